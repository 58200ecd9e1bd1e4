"""fvr.register: the chest phantom's pose found again from an offset, against an X-ray rendered
with another ray model (box: exact path lengths) than the registration's (trilinear)."""
import math

import numpy as np
import pytest

import fvr


@pytest.fixture(scope="module")
def chest():
    vol = fvr.load("phantom:chest")
    r = fvr.Renderer(vol, values="mu")
    cam = r.camera(primary=0, detector=128)
    lat = r.camera(primary=90, detector=128)
    return vol, [cam, lat], r.render_many([cam, lat], model="box")


def rotation(deg):
    """R = Rz Ry Rx, degrees, worked out here."""
    x, y, z = (math.radians(a) for a in deg)
    rx = np.array([[1, 0, 0], [0, math.cos(x), -math.sin(x)], [0, math.sin(x), math.cos(x)]])
    ry = np.array([[math.cos(y), 0, math.sin(y)], [0, 1, 0], [-math.sin(y), 0, math.cos(y)]])
    rz = np.array([[math.cos(z), -math.sin(z), 0], [math.sin(z), math.cos(z), 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_register_finds_the_recorded_pose_from_an_offset(chest):
    vol, cams, images = chest
    calls = []
    res = fvr.register(vol, images, cams,
                       init={"rotation_deg": (3, -2, 4), "translation_mm": (5, -6, 4)},
                       threads=2, progress=lambda stage, n, s: calls.append((stage, n, s)))
    pose = res["pose"]
    assert pose.shape == (4, 4)
    np.testing.assert_array_equal(pose[3], [0, 0, 0, 1])
    # The matrix is the documented parameterisation of its angles, translation and centre.
    c = np.array(res["centre"])
    np.testing.assert_allclose(c, fvr._fvr.volume_centre(vol._v))  # the default centre
    R = rotation(res["rotation_deg"])
    np.testing.assert_allclose(pose[:3, :3], R, atol=1e-12)
    np.testing.assert_allclose(pose[:3, 3], c - R @ c + np.array(res["translation_mm"]),
                               atol=1e-9)
    # Close to the identity (the geometry's own pose): mTRE over a 100 mm cube's corners.
    corners = np.array([[sx, sy, sz] for sx in (-50, 50) for sy in (-50, 50)
                        for sz in (-50, 50)]) + c
    moved = corners @ pose[:3, :3].T + pose[:3, 3]
    mtre = np.linalg.norm(moved - corners, axis=1).mean()
    assert mtre < 2.0, res
    assert res["similarity_after"] > res["similarity_before"]
    assert len(res["history"]) == res["evaluations"] > 0
    assert sum(s["evaluations"] for s in res["stages"]) == res["evaluations"]
    assert all(s["drrs"] == 2 * s["evaluations"] for s in res["stages"])
    assert res["seconds"] > 0 and calls and calls[0][0]
    print(f"fvr.register biplane: mTRE {mtre:.3f} mm, {res['evaluations']} evaluations, "
          f"{res['seconds']:.2f} s")


def test_register_refuses_an_image_of_another_size_than_its_camera(chest):
    vol, cams, images = chest
    with pytest.raises(ValueError, match=r"images\[0\]: expected \(128, 128\)"):
        fvr.register(vol, images[0][:64], cams[0])
    with pytest.raises(ValueError, match="one image per camera"):
        fvr.register(vol, images, cams[0])
    with pytest.raises(ValueError, match="not a rotation|rigid"):
        fvr.register(vol, images[0], cams[0], init=np.diag([2.0, 1, 1, 1]))
