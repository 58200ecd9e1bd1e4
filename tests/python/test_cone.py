"""fvr.Camera and the cone-beam renders against hand-worked geometry: where a ball left of the
isocentre lands (the C-arm's formulas worked by hand), the magnification SID/SOD of a slab's
width, chord lengths of a water cube in mm, P mapping the isocentre to the principal point,
render_many against single renders, Beer-Lambert by numpy, the checks' messages, and
fvr-render --geometry cone's .npy (where the built fvr-render has cone beam)."""
import math
import pickle
import shutil
import subprocess

import numpy as np
import pytest

import fvr
from conftest import run_fvr_render
from test_fvr import released_gil_during

SPACING = 2.0  # mm


def volume(array, units="unknown"):
    """A volume whose centre lies at the LPS origin (array (z, y, x), 2 mm voxels)."""
    nz, ny, nx = array.shape
    origin = tuple(-(n - 1) / 2 * SPACING for n in (nx, ny, nz))
    return fvr.Volume(array, spacing=(SPACING,) * 3, origin=origin, units=units)


def lps_grid(shape):
    """The LPS coordinates (x, y, z) of the voxel centres of volume(np.zeros(shape))."""
    nz, ny, nx = shape
    z, y, x = np.meshgrid(*[(np.arange(n) - (n - 1) / 2) * SPACING for n in (nz, ny, nx)],
                          indexing="ij")
    return x, y, z


@pytest.fixture(scope="module")
def ball():
    """A ball of radius 8 mm, value 1, centred at x = +30 mm (the patient's left)."""
    shape = (48, 48, 64)
    x, y, z = lps_grid(shape)
    a = ((x - 30.0) ** 2 + y ** 2 + z ** 2 <= 8.0 ** 2).astype(np.float32)
    return fvr.Renderer(volume(a), threads=2)


def test_a_ball_left_of_the_isocentre_lands_right_of_centre_where_project_says(ball):
    cam = fvr.Camera.carm(sid=1000, sod=750, isocenter=(0, 0, 0), detector=(128, 64), pitch=1.0)
    # By hand: at 0/0 the source is posterior (0, 750, 0), the columns run to the patient's
    # left; the ball's centre lies at the isocentre's depth, magnified SID/SOD.
    expected = (127 / 2 + 30.0 * 1000 / 750 / 1.0, 63 / 2)
    np.testing.assert_allclose(cam.project((30, 0, 0)), expected, atol=1e-9)
    img = ball.render(camera=cam)
    assert img.shape == (64, 128) and img.dtype == np.float32
    rows, cols = np.indices(img.shape)
    centroid = ((cols * img).sum() / img.sum(), (rows * img).sum() / img.sum())
    assert centroid[0] > 127 / 2 + 30  # right of centre
    np.testing.assert_allclose(centroid, expected, atol=0.25)


def test_matrix_maps_the_isocentre_to_the_principal_point():
    iso = (12.0, -30.0, 45.0)
    cam = fvr.Camera.carm(primary=-35, secondary=20, sid=1200, sod=800, isocenter=iso,
                          detector=(120, 90), pitch=(0.4, 0.5), principal_point=(3.5, -2.0))
    P = cam.matrix
    assert P.shape == (3, 4) and P.dtype == np.float64
    w = P @ np.array([*iso, 1.0])
    # The contract puts pixel (i, j) at detector centre + (i - (W-1)/2 + du) pu u + ...: the
    # principal ray (through the isocentre, onto the detector centre) lands at the pixel
    # i = (W-1)/2 - du, j = (H-1)/2 - dv.
    np.testing.assert_allclose(w[:2] / w[2], (119 / 2 - 3.5, 89 / 2 + 2.0), atol=1e-9)
    assert w[2] == pytest.approx(800.0)  # its depth from the source: SOD
    # The C-arm formulas by hand: d points from the isocentre to the detector.
    a, b = math.radians(-35), math.radians(20)
    d = np.array([math.sin(a) * math.cos(b), -math.cos(a) * math.cos(b), math.sin(b)])
    np.testing.assert_allclose(cam.source, np.array(iso) - 800 * d, atol=1e-9)
    np.testing.assert_allclose(cam.detector_centre, np.array(iso) + 400 * d, atol=1e-9)
    np.testing.assert_allclose(cam.u, (math.cos(a), math.sin(a), 0.0), atol=1e-12)
    np.testing.assert_allclose(cam.v, np.cross(cam.u, d), atol=1e-12)
    assert (cam.width, cam.height, cam.pitch, cam.principal_point) == (120, 90, (0.4, 0.5),
                                                                        (3.5, -2.0))
    assert cam.sid == pytest.approx(1200.0)
    # Every pixel centre projects to its own indices.
    for col, row in [(0, 0), (119, 0), (17, 66), (119, 89)]:
        np.testing.assert_allclose(cam.project(cam.pixel_centre(col, row)), (col, row), atol=1e-9)


def test_a_slabs_width_is_magnified_sid_over_sod():
    """A slab 40 mm wide (x), 2 mm deep at the isocentre: its shadow on a 0.5 mm detector spans
    the columns within 20 x SID/SOD / 0.5 = 53.3 pixels of the centre, 106 of them (a parallel
    projection would give 80)."""
    shape = (40, 40, 40)
    x, y, z = lps_grid(shape)
    a = ((np.abs(x) < 20) & (np.abs(y) < 1.5) & (np.abs(z) < 20)).astype(np.float32)
    r = fvr.Renderer(volume(a), threads=2)
    cam = fvr.Camera.carm(isocenter=(0, 0, 0), detector=(160, 16), pitch=0.5)
    for model in ("box", "trilinear"):
        img = r.render(camera=cam, model=model)
        row = img[7]
        assert (row > row.max() / 2).sum() == 106, model


def test_water_line_integrals_are_chords_in_mm():
    """Hounsfield data renders mu (as the parallel views): a water cube (0 HU) of 13 voxels, 26 mm
    deep, in air gives the central ray's chord, 26 mm, and Beer-Lambert exp(-mu_water 26) on
    it."""
    shape = (31, 31, 31)
    x, y, z = lps_grid(shape)
    a = np.where((np.abs(x) <= 12) & (np.abs(y) <= 12) & (np.abs(z) <= 12), 0.0, -1000.0)
    r = fvr.Renderer(volume(a.astype(np.float32), units="HU"), threads=2)
    cam = fvr.Camera.carm(primary=0, isocenter=(0, 0, 0), detector=(33, 33), pitch=0.25)
    img = r.render(camera=cam, model="box")
    assert img[16, 16] == pytest.approx(26.0, abs=1e-4)
    t = r.transmission(img, energy_kev=70)
    np.testing.assert_allclose(t, np.exp(-0.01937 * img.astype(np.float64)), rtol=1e-3)
    # The sampled models agree inside the cube (the interpolants are 1 there).
    for model, step in (("trilinear", 0.0), ("trilinear", 0.5), ("bspline", 0.25)):
        assert r.render(camera=cam, model=model, step=step)[16, 16] == pytest.approx(26.0, abs=0.3)


def test_render_many_equals_separate_renders(ball):
    cams = [ball.camera(primary=p, secondary=s, detector=(48, 40))
            for p, s in [(0, 0), (30, 15), (-60, -10), (180, 0)]]
    for model in ("trilinear", "box"):
        stack = ball.render_many(cams, model=model)
        assert stack.shape == (4, 40, 48)
        for k, cam in enumerate(cams):
            np.testing.assert_array_equal(stack[k], ball.render(camera=cam, model=model))
    assert ball.render_many(tuple(cams[:1])).shape == (1, 40, 48)


def test_renderer_camera_defaults_to_the_volume_centre_and_its_framing_pitch(ball):
    cam = ball.camera(sid=1200, sod=800, detector=(64, 32))
    vol = ball.volume
    centre = np.array(vol.origin) + (np.array(vol.shape[::-1]) - 1) / 2 * SPACING
    np.testing.assert_allclose(cam.project(centre), (63 / 2, 31 / 2), atol=1e-9)
    # The framing pitch: the diagonal magnified at the isocentre on the smaller side (32).
    diagonal = np.linalg.norm(np.array(vol.shape) * SPACING)
    assert cam.pitch[0] == cam.pitch[1]
    assert cam.pitch[0] * 32 == pytest.approx(diagonal * 1200 / 800, rel=0.05)


def test_the_flat_field_is_inverse_square_times_obliquity():
    cam = fvr.Camera.carm(primary=20, isocenter=(0, 0, 0), detector=(40, 30), pitch=2.0,
                          sid=1000, sod=600)
    f = cam.flat_field()
    assert f.shape == (30, 40) and f.dtype == np.float32
    for col, row in [(0, 0), (39, 29), (7, 22), (20, 15)]:
        r = np.linalg.norm(np.array(cam.pixel_centre(col, row)) - cam.source)
        assert f[row, col] == pytest.approx((1000 / r) ** 3, rel=1e-6)
    # The pixel centres nearest the principal point ((W-1)/2, (H-1)/2) respond most.
    assert f.max() == f[14:16, 19:21].max() and f.max() < 1 < f.max() + 1e-5


def test_a_camera_from_its_parts_and_through_pickle_is_the_same_camera():
    cam = fvr.Camera.carm(primary=25, secondary=-10, isocenter=(5, 6, 7), detector=64, pitch=0.8,
                          principal_point=(1.5, 0.5))
    parts = fvr.Camera(cam.source, cam.detector_centre, cam.u, cam.v,
                       (cam.width, cam.height), cam.pitch, cam.principal_point)
    np.testing.assert_array_equal(parts.matrix, cam.matrix)
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(cam)).matrix, cam.matrix)


def test_a_camera_from_its_matrix_or_a_matrix_file_is_the_same_camera(tmp_path):
    cam = fvr.Camera.carm(primary=-35, secondary=20, isocenter=(10, -5, 30), detector=(96, 64),
                          pitch=(0.7, 0.9), principal_point=(2.5, -1.0))
    back = fvr.Camera.from_matrix(cam.matrix * 3.0, (96, 64), (0.7, None))  # any scale of P
    np.testing.assert_allclose(back.matrix, cam.matrix, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(back.source, cam.source, atol=1e-9)
    assert back.pitch == pytest.approx((0.7, 0.9))
    rows = "\n".join(" ".join(repr(x) for x in row) for row in cam.matrix)
    path = tmp_path / "p.txt"
    path.write_text(f"# a C-arm\ndetector 96 64\npitch 0.7 0.9\n{rows}\n")
    (read,) = fvr.Camera.read_matrix_file(path)
    np.testing.assert_allclose(read.matrix, cam.matrix, rtol=1e-9, atol=1e-9)
    with pytest.raises(ValueError, match="expected a .3, 4. array"):
        fvr.Camera.from_matrix(np.eye(3), 96, 1.0)


@pytest.mark.parametrize("call, message", [
    (lambda r: fvr.Camera.carm(sid=1000, sod=1000, isocenter=(0, 0, 0), pitch=1),
     "expected 0 < SOD < SID, found SOD 1000 mm, SID 1000 mm"),
    (lambda r: fvr.Camera.carm(sid=900, sod=1000, isocenter=(0, 0, 0), pitch=1),
     "expected 0 < SOD < SID"),
    (lambda r: fvr.Camera.carm(isocenter=(0, 0, 0), pitch=0),
     "column pitch: expected a positive number of mm, found 0"),
    (lambda r: fvr.Camera.carm(isocenter=(0, 0, 0), pitch=(1, -1)), "row pitch"),
    (lambda r: fvr.Camera.carm(isocenter=(0, 0, 0), pitch=1, detector=8),
     "detector width: expected 16..4096 pixels, found 8"),
    (lambda r: fvr.Camera.carm(pitch=1), "isocenter: give the isocentre"),
    (lambda r: fvr.Camera.carm(isocenter=(0, 0, 0)), "pitch: give the detector's pitch"),
    (lambda r: fvr.Camera((0, 0, 100), (0, 0, -100), (1, 0, 0), (1, 0, 0), 32, 1),
     "column and row directions must be orthonormal"),
    (lambda r: r.render(camera=r.camera(detector=32), size=256),
     "size: not with a cone-beam camera"),
    (lambda r: r.render(camera=r.camera(detector=32), view="AP"), "view: not with a cone-beam"),
    (lambda r: r.render(camera=r.camera(detector=32), model="box", step=0.5),
     "step: not with model box"),
    (lambda r: r.render(camera=r.camera(detector=32), model="spline"),
     "ray model: expected box, trilinear or bspline, found 'spline'"),
    (lambda r: r.render(camera=r.camera(detector=32), step=9), "step"),
    (lambda r: r.render(view="AP", model="box"), "model, step: only with camera="),
    (lambda r: r.render_many([r.camera(detector=32), r.camera(detector=48)]),
     "one stack needs one detector size: camera 0 has 32x32, camera 1 48x48"),
    (lambda r: r.render_many([r.camera(detector=32), "AP"]), "found a mix"),
    (lambda r: r.render(camera=fvr.Camera.carm(sid=300, sod=10, isocenter=(0, 0, 0), pitch=1,
                                               detector=32)), "the source lies inside the volume"),
    (lambda r: r.render_many([r.camera(detector=32),
                              fvr.Camera.carm(sid=300, sod=10, isocenter=(0, 0, 0), pitch=1,
                                              detector=32)]), "camera 1: "),
    (lambda r: r.camera(detector=32).project([[1, 2]]), "points: expected an (N, 3) array"),
])
def test_bad_geometry_raises_value_error_with_the_message(ball, call, message):
    with pytest.raises(ValueError) as e:
        call(ball)
    assert message in str(e.value)


@pytest.mark.parametrize("setting, message", [
    (dict(depth_cue=0.3), "depth_cue: not with a cone-beam camera"),
    (dict(sharpen=0.5), "sharpen: not with a cone-beam camera"),
    (dict(band_limit=0.2), "band_limit: not with a cone-beam camera"),
])
def test_parallel_only_settings_are_refused_for_cone_beam(setting, message):
    r = fvr.Renderer(volume(np.ones((20, 20, 20), np.float32)), threads=1, **setting)
    with pytest.raises(ValueError) as e:
        r.render(camera=r.camera(detector=32))
    assert message in str(e.value)


def test_kvp_is_refused_where_the_renderer_is_made():
    """The renderer renders line integrals: a kvp it took was silently not applied (parallel
    images equal to those without it); fvr.run_cli runs fvr-render --kvp."""
    with pytest.raises(ValueError, match="kvp: fvr.Renderer renders line integrals"):
        fvr.Renderer(volume(np.ones((20, 20, 20), np.float32)), threads=1, kvp=80)


def test_pixel_aperture_averages_the_pixels_area_as_a_finer_detector_binned_down(ball):
    """pixel_aperture=True casts 4 x 4 rays per pixel and averages them: the rays of a 4x finer
    point-sampled detector, binned 4 x 4 here. The ball's edge is softer than point sampling's,
    and nearer the box filter of the pixel (a 16x finer detector binned 16 x 16)."""
    shape = (48, 48, 64)
    x, y, z = lps_grid(shape)
    a = ((x - 30.0) ** 2 + y ** 2 + z ** 2 <= 8.0 ** 2).astype(np.float32)
    aperture = fvr.Renderer(volume(a), threads=2, pixel_aperture=True)

    def cam(n, pitch):
        return fvr.Camera.carm(primary=10, sid=1000, sod=750, isocenter=(30, 0, 0),
                               detector=n, pitch=pitch)

    def binned(img, f):
        h, w = img.shape
        return img.reshape(h // f, f, w // f, f).astype(np.float64).mean(axis=(1, 3))

    area = aperture.render(camera=cam(24, 1.5), model="box")
    point = ball.render(camera=cam(24, 1.5), model="box")
    fine4 = binned(ball.render(camera=cam(96, 0.375), model="box"), 4)
    fine16 = binned(ball.render(camera=cam(384, 1.5 / 16), model="box"), 16)
    np.testing.assert_allclose(area, fine4, atol=1e-4)
    to_box, point_to_box = np.abs(area - fine16).mean(), np.abs(point - fine16).mean()
    print(f"[aperture] mean |area - box| {to_box:.4f} mm, point sampling {point_to_box:.4f} mm")
    assert point_to_box > 0.05  # mm of chord, mostly at the ball's edge
    assert to_box < 0.25 * point_to_box


def test_the_gil_is_released_while_cone_beam_renders(ball):
    cams = [ball.camera(primary=p, detector=256) for p in range(0, 360, 45)]
    ball.render(camera=cams[0])  # the ray caster made before the observed call
    assert released_gil_during(lambda: ball.render_many(cams))


def test_render_equals_fvr_renders_cone_beam(fvr_render, tmp_path):
    """The same C-arm through Python and through fvr-render --geometry cone (its defaults: the
    volume's centre, the framing pitch, mu for Hounsfield data): the same image, bit for bit."""
    if "--geometry" not in subprocess.run([fvr_render, "--help"], capture_output=True,
                                          text=True).stdout:
        pytest.skip("this fvr-render has no --geometry cone")
    r = fvr.Renderer(fvr.load("phantom:chest:64"))
    for model in ("trilinear", "box"):
        cam = r.camera(primary=-40, secondary=25, sid=1100, sod=700, detector=(80, 56))
        cli = run_fvr_render(fvr_render, ["phantom:chest:64", "--geometry", "cone",
                                          "--primary-angle", "-40", "--secondary-angle", "25",
                                          "--sid", "1100", "--sod", "700", "--detector-size",
                                          "80x56", "--ray-model", model], tmp_path / "c.npy")
        np.testing.assert_array_equal(r.render(camera=cam, model=model), cli.reshape(56, 80))
    # The pixel aperture: the same 4 x 4 rays per pixel.
    a = fvr.Renderer(fvr.load("phantom:chest:64"), pixel_aperture=True)
    cam = a.camera(primary=-40, secondary=25, sid=1100, sod=700, detector=(80, 56))
    cli = run_fvr_render(fvr_render, ["phantom:chest:64", "--geometry", "cone", "--primary-angle",
                                      "-40", "--secondary-angle", "25", "--sid", "1100", "--sod",
                                      "700", "--detector-size", "80x56", "--pixel-aperture"],
                         tmp_path / "a.npy")
    np.testing.assert_array_equal(a.render(camera=cam), cli.reshape(56, 80))
    assert np.abs(a.render(camera=cam) - r.render(camera=cam)).max() > 0.1


# A DRR written as DICOM by fvr-render (in this process, fvr.run_cli) read back: an oblique C-arm
# off the volume's centre, with unequal pitches and a principal-point offset.
OBLIQUE = dict(primary=35, secondary=-20, sid=1100, sod=720, isocenter=(5, -3, 8),
               detector=(48, 40), pitch=(2.5, 3.0), principal_point=(1.5, -2.0))


def write_oblique_dicom(path, *extra):
    o = OBLIQUE
    fvr.run_cli(["phantom:chest:32", "--geometry", "cone", "--primary-angle", o["primary"],
                 "--secondary-angle", o["secondary"], "--sid", o["sid"], "--sod", o["sod"],
                 "--isocenter", "5,-3,8", "--detector-size", "48x40", "--pitch", "2.5,3",
                 "--principal-point", "1.5,-2", *extra, "--out", path])


def test_from_dicom_is_the_camera_that_wrote_the_file_and_read_xray_its_pixels(tmp_path):
    dcm = tmp_path / "oblique.dcm"
    write_oblique_dicom(dcm)
    cam = fvr.Camera.from_dicom(dcm)
    assert cam.warnings == [] and cam.isocenter_from == "file"
    expected = fvr.Camera.carm(**OBLIQUE)
    assert (cam.width, cam.height) == (48, 40) and cam.principal_point == (1.5, -2.0)
    np.testing.assert_allclose(cam.matrix, expected.matrix,
                               atol=1e-9 * np.abs(expected.matrix).max())
    # The file's pixels are the line integrals of that camera within the 16-bit quantisation
    # (half a step of the range over 65535).
    r = fvr.Renderer(fvr.load("phantom:chest:32"))
    ref = r.render(camera=expected)
    pixels = fvr.read_xray(dcm)
    assert pixels.shape == (40, 48) and pixels.dtype == np.float32
    step = (ref.max() - ref.min()) / 65535
    assert np.abs(pixels - ref).max() <= 0.5 * step * 1.001 + 1e-5 * ref.max()
    psnr = 10 * np.log10(ref.max() ** 2 / np.mean((pixels.astype(np.float64) - ref) ** 2))
    assert psnr >= 80
    # An isocentre given for a file that states its own: the file's wins.
    same = fvr.Camera.from_dicom(dcm, isocenter=(100, 100, 100))
    np.testing.assert_array_equal(same.matrix, cam.matrix)


def test_from_dicom_takes_each_frame_of_a_run(tmp_path):
    dcm = tmp_path / "orbit.dcm"
    fvr.run_cli(["phantom:chest:32", "--geometry", "cone", "--secondary-angle", "10",
                 "--detector-size", "40x32", "--pitch", "3", "--orbit", "-30:60:4", "--out", dcm])
    stack = fvr.read_xray(dcm)
    assert stack.shape == (4, 32, 40)
    r = fvr.Renderer(fvr.load("phantom:chest:32"))
    for k in range(4):
        cam = fvr.Camera.from_dicom(dcm, frame=k)
        expected = r.camera(primary=-30 + 30 * k, secondary=10, detector=(40, 32), pitch=3)
        np.testing.assert_allclose(cam.matrix, expected.matrix,
                                   atol=1e-9 * np.abs(expected.matrix).max())
        ref = r.render(camera=expected)
        assert np.abs(stack[k] - ref).max() <= 1e-4 * ref.max()
    with pytest.raises(ValueError, match=r"frame: 4 asked for, .*orbit.dcm has 4 frames \(0..3\)"):
        fvr.Camera.from_dicom(dcm, frame=4)


def test_from_dicom_without_an_isocentre_takes_the_given_or_the_volumes(tmp_path):
    dcmodify = shutil.which("dcmodify")
    if not dcmodify:
        pytest.skip("dcmodify (Debian package dcmtk) is not installed")
    dcm = tmp_path / "plain.dcm"
    write_oblique_dicom(dcm)
    # As an X-ray from a real C-arm: no isocentre (our private tags gone), and no SID.
    subprocess.run([dcmodify, "-nb", "-ea", "(0018,1110)", "-ea", "(0009,1001)", "-ea",
                    "(0009,1002)", "-ea", "(0009,0010)", str(dcm)], check=True)
    with pytest.raises(ValueError, match="plain.dcm states no isocentre"):
        fvr.Camera.from_dicom(dcm)
    cam = fvr.Camera.from_dicom(dcm, isocenter=(5, -3, 8))
    assert cam.isocenter_from == "isocenter"
    assert any("DistanceSourceToDetector (0018,1110) missing" in w for w in cam.warnings)
    # SID from SOD x EstimatedRadiographicMagnificationFactor; no principal-point offset.
    expected = fvr.Camera.carm(**{**OBLIQUE, "principal_point": (0.0, 0.0)})
    np.testing.assert_allclose(cam.matrix, expected.matrix,
                               atol=1e-9 * np.abs(expected.matrix).max())
    vol = fvr.load("phantom:chest:32")
    centred = fvr.Camera.from_dicom(dcm, volume=vol)
    assert centred.isocenter_from == "volume"
    np.testing.assert_allclose(centred.project(fvr._fvr.volume_centre(vol._v)),
                               (47 / 2, 39 / 2), atol=1e-9)


def test_from_dicom_and_read_xray_name_a_file_they_cannot_read(tmp_path):
    bad = tmp_path / "bad.dcm"
    bad.write_text("not DICOM")
    for call in (fvr.Camera.from_dicom, fvr.read_xray):
        with pytest.raises(RuntimeError, match="bad.dcm"):
            call(bad)


def test_a_renderer_asked_for_a_cone_beam_says_to_give_a_camera(ball):
    with pytest.raises(ValueError, match="rendered with a camera"):
        fvr.Renderer(ball.volume, geometry="cone")


def test_from_dicom_reads_a_treatment_beams_rt_image(tmp_path):
    # A beam with couch and collimator turned, written by fvr-render as an RT Image: the camera
    # read back is the sidecar's (the same P), and read_xray gives its pixels.
    dcm = tmp_path / "beam.dcm"
    fvr.run_cli(["phantom:chest:32", "--geometry", "cone", "--beam", "60,15,20",
                 "--detector-size", "40x32", "--pitch", "2", "--out", dcm])
    cam = fvr.Camera.from_dicom(dcm)
    assert cam.warnings == [] and cam.isocenter_from == "file"
    import json
    view = json.loads((tmp_path / "beam.dcm.json").read_text())["views"][0]
    expected = np.array(view["projection_matrix"])
    np.testing.assert_allclose(cam.matrix, expected, atol=1e-6 * np.abs(expected).max())
    assert fvr.read_xray(dcm).shape == (32, 40)
