"""The Python module fvr against independent oracles: the shared data's documented sizes, the
built fvr-render's own .npy outputs (bit for bit), a loop of single renders, the CLI's messages,
and two threads rendering at once."""
import os
import resource
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import fvr
from conftest import BODY_CT_MHD, BODY_CT_NII, HEAD_DICOM, need, run_fvr_render

SETTINGS = dict(kernel="kaiser-bessel", oversampling=1.25, values="mu", voxel_model="bspline")
CLI_SETTINGS = ["--kernel", "kaiser-bessel", "--oversampling", "1.25", "--values", "mu",
                "--voxel-model", "bspline", "--backend", "cpu"]


@pytest.fixture(scope="module")
def body():
    return fvr.load(need(BODY_CT_MHD))


@pytest.fixture(scope="module")
def renderer(body):
    return fvr.Renderer(body, **SETTINGS)


# The sizes of data/README.md, as (z, y, x).
@pytest.mark.parametrize("path, shape, units", [
    (HEAD_DICOM, (93, 64, 64), "intensity"),      # DICOM folder (RescaleType US: not HU)
    (BODY_CT_MHD, (112, 101, 122), "HU"),         # MetaImage (no units stated: HU by the guess)
    (BODY_CT_NII, (112, 101, 122), "HU"),         # NIfTI gz, the same study
])
def test_load_shared_volume_kinds(path, shape, units):
    vol = fvr.load(need(path))
    assert vol.shape == shape
    assert vol.units == units
    assert vol.array.shape == shape and vol.array.dtype == np.float32
    assert not vol.array.flags.writeable
    assert vol.info["dims"] == list(shape[::-1])
    assert all(s > 0 for s in vol.spacing)


def test_nifti_and_metaimage_of_one_study_hold_the_same_voxels():
    mhd, nii = fvr.load(need(BODY_CT_MHD)), fvr.load(need(BODY_CT_NII))
    np.testing.assert_array_equal(mhd.array, nii.array)
    assert mhd.spacing == nii.spacing == (3.0, 3.0, 3.0)


def test_load_phantom_and_its_warnings():
    vol = fvr.load("phantom:shepp-logan:64")
    assert vol.shape == (64, 64, 64)
    assert vol.units == "HU"
    body = fvr.load(need(BODY_CT_MHD))
    assert any("no orientation" in w for w in body.warnings)
    dicom = fvr.load(need(HEAD_DICOM))
    assert any("RescaleType" in w for w in dicom.warnings)


def test_render_is_bit_identical_to_fvr_render(body, renderer, fvr_render, tmp_path):
    for view, size in [("AP", 128), ("LEFT", 256)]:
        cli = run_fvr_render(fvr_render, [BODY_CT_MHD, *CLI_SETTINGS, "--view", view,
                                          "--size", size], tmp_path / f"{view}.npy")
        img = renderer.render(view=view, size=size)
        assert img.dtype == np.float32 and img.shape == (size, size)
        assert cli.tobytes() == img.tobytes(), view
        assert img.max() > 1.0  # a real projection, not an empty image


def test_any_width_and_height_renders_as_fvr_render_does(body, renderer, fvr_render, tmp_path):
    # Training sets' sizes (64, 200, 224) and a real detector's aspect: (H, W) arrays, the same
    # bytes as fvr-render --size WxH, the volume's centre at pixel (W // 2, H // 2).
    for size, shape, text in [(64, (64, 64), "64"), (200, (200, 200), "200"),
                              ((224, 160), (160, 224), "224x160")]:
        cli = run_fvr_render(fvr_render, [BODY_CT_MHD, *CLI_SETTINGS, "--view", "AP",
                                          "--size", text], tmp_path / f"s{text}.npy")
        img = renderer.render(view="AP", size=size)
        assert img.dtype == np.float32 and img.shape == shape
        assert cli.tobytes() == img.tobytes(), text
    # A pixel size whose 128 pixels hold the volume's diagonal: 90 x 120 is transformed on the
    # 128^2 square too, and is its crop about pixel (64, 64) to the bit.
    extent = np.array(body.shape[::-1]) * np.array(body.spacing)
    d = float(np.linalg.norm(extent)) / 128 * 1.001
    stack = renderer.render_many(["AP", "LEFT"], size=(90, 120), pixel_size=d)
    assert stack.shape == (2, 120, 90)
    square = renderer.render(view="AP", size=128, pixel_size=d)
    np.testing.assert_array_equal(stack[0], square[64 - 60:64 + 60, 64 - 45:64 + 45])


def test_default_settings_render_what_fvr_render_renders(fvr_render, tmp_path):
    # Nothing chosen on either side: one set of defaults (core's RenderSettings: the AP view,
    # mu, kaiser-bessel4 deapodized at 1.25x, trilinear), so the same bytes.
    cli = run_fvr_render(fvr_render, ["phantom:shepp-logan:64", "--size", 128, "--backend", "cpu"],
                         tmp_path / "default.npy")
    r = fvr.Renderer(fvr.load("phantom:shepp-logan:64"))
    img = r.render(size=128)
    assert cli.tobytes() == img.tobytes()
    assert r.settings["kernel"] == "kaiser-bessel4" and r.settings["values"] == "mu"
    paper = fvr.Renderer(fvr.load("phantom:shepp-logan:64"), preset="paper")
    assert paper.settings["kernel"] == "linear" and paper.settings["values"] == "raw"


def test_sweep_is_bit_identical_to_fvr_render(body, fvr_render, tmp_path):
    cli = run_fvr_render(fvr_render, [BODY_CT_MHD, *CLI_SETTINGS, "--sweep", 5, "--size", 128,
                                      "--pixel-size", 3.5], tmp_path / "sweep.npy")
    r = fvr.Renderer(body, sweep=5, **SETTINGS)
    stack = r.render_many(size=128, pixel_size=3.5)
    assert stack.shape == (5, 128, 128)
    assert cli.tobytes() == stack.tobytes()
    assert r.views().shape == (5, 2, 3)


def test_render_many_equals_a_loop_of_render(renderer):
    names = ["AP", "LEFT", "PA", "RIGHT", "HEAD"]
    stack = renderer.render_many(names, size=128)
    for i, name in enumerate(names):
        np.testing.assert_array_equal(stack[i], renderer.render(view=name, size=128))
    views = np.array([[[0.6, 0.8, 0.0], [0, 0, 1]], [[0, 1, 0], [0, 0, -1]], [[1, 0, 0], [0, 1, 0]]])
    stack = renderer.render_many(views, size=128, pixel_size=3.0)
    for i, (d, u) in enumerate(views):
        np.testing.assert_array_equal(stack[i], renderer.render(dir=d, up=u, size=128, pixel_size=3.0))


def test_a_view_of_the_call_replaces_the_renderers_own(body, renderer):
    left = fvr.Renderer(body, view="LEFT", **SETTINGS)
    d, u = (0.6, 0.8, 0.0), (0.0, 0.0, 1.0)
    np.testing.assert_array_equal(left.render(dir=d, up=u, size=128),
                                  renderer.render(dir=d, up=u, size=128))
    np.testing.assert_array_equal(left.render(size=128), renderer.render(view="LEFT", size=128))


def test_volume_from_numpy_renders_as_the_loaded_volume(body, renderer):
    copy = fvr.Volume(np.array(body.array), spacing=body.spacing, origin=body.origin,
                      direction=body.direction, units=body.units)
    assert copy.shape == body.shape and copy.spacing == body.spacing
    r = fvr.Renderer(copy, **SETTINGS)
    assert r.render(view="AP", size=128).tobytes() == renderer.render(view="AP", size=128).tobytes()
    # Another dtype converts; float64 doubles round to the same float32 voxels.
    as64 = fvr.Volume(body.array.astype(np.float64), spacing=body.spacing, units="HU")
    np.testing.assert_array_equal(as64.array, body.array)


def test_volume_geometry_round_trips_as_given():
    # direction[a] is index axis a, as given (a permutation that is not symmetric: a transpose
    # would show); spacing, origin and direction come back as given, in Python and in info().
    axes = ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0))
    v = fvr.Volume(np.zeros((4, 5, 6), np.float32), spacing=(0.5, 1.25, 3.0),
                   origin=np.array([-10.5, 2.0, 7.25]), direction=np.array(axes), units="HU")
    assert v.spacing == (0.5, 1.25, 3.0) and v.origin == (-10.5, 2.0, 7.25)
    assert v.direction == axes
    info = v.info
    assert info["direction"] == [list(a) for a in axes]
    assert info["spacing_mm"] == [0.5, 1.25, 3.0] and info["origin_mm"] == [-10.5, 2.0, 7.25]
    with pytest.raises((TypeError, ValueError)):
        fvr.Volume(np.zeros((4, 4, 4), np.float32), spacing=(1.0, 1.0))


def test_non_finite_voxels_are_said_and_replaced():
    a = np.full((8, 8, 8), 100.0, np.float32)
    a[0, 0, 1] = -50.0
    a[2, 3, 4] = np.nan
    a[5, 5, 5] = np.inf
    v = fvr.Volume(a, spacing=(1.0, 1.0, 1.0))
    assert any(w.startswith("2 of 512 voxels are not finite") for w in v.warnings), v.warnings
    assert v.array[2, 3, 4] == -50.0 and v.array[5, 5, 5] == -50.0
    img = fvr.Renderer(v).render(view="AP", size=128)
    assert np.isfinite(img).all()  # one NaN voxel used to spread into about a third of it


@pytest.mark.parametrize("call, message", [
    (lambda v, r: fvr.Renderer(v, kernel="bogus"), "--kernel"),
    (lambda v, r: fvr.Renderer(v, oversampling=3), "expected a factor in [1, 2], found 3"),
    # was CLI11's "Value -1 not in range 0.000000 to 1797693134862315708145...":
    (lambda v, r: fvr.Renderer(v, threads=-1), "--threads: expected a whole number of threads"),
    (lambda v, r: r.render(size=15), "--size: expected 16..4096 pixels, found 15"),
    # It rendered line integrals, as if kvp had not been given:
    (lambda v, r: fvr.Renderer(v, kvp=80), "kvp: fvr.Renderer renders line integrals"),
    (lambda v, r: r.render(size=(64, 5000)), "expected 16..4096 pixels, found 5000"),
    (lambda v, r: r.render(size=(64, 48, 2)), "size: expected N or (W, H)"),
    (lambda v, r: r.render(view="SIDEWAYS"), "SIDEWAYS"),
    (lambda v, r: r.render(dir=(0, 0, 0)), "view direction: expected a non-zero finite vector"),
    (lambda v, r: r.render(pixel_size=-1), "--pixel-size: expected a positive number of mm"),
    (lambda v, r: r.render_many(np.zeros((2, 3)), size=128), "(N, 2, 3)"),
    (lambda v, r: r.render_many(["AP", 3], size=128), "views: expected view names only, found 3"),
    (lambda v, r: fvr.Renderer(v, values="raw").transmission(np.zeros((4, 4)), energy_kev=70),
     "--beer-lambert: needs --values mu or mu-bone"),
    (lambda v, r: r.transmission(np.zeros((4, 4)), energy_kev=500), "--energy"),
    (lambda v, r: fvr.Renderer(fvr.Volume(np.ones((8, 8, 8), np.float32))).transmission(
        np.zeros((4, 4))), "not Hounsfield units"),
    (lambda v, r: fvr.Volume(np.zeros((4, 4), np.float32)), "expected 3 dimensions"),
    (lambda v, r: fvr.Volume(np.zeros((4, 4, 4), np.float32), spacing=(1, 0, 1)), "spacing"),
])
def test_bad_arguments_raise_value_error_with_the_message(body, renderer, call, message):
    with pytest.raises(ValueError) as e:
        call(body, renderer)
    assert message in str(e.value)


def test_unreadable_input_raises_runtime_error(tmp_path):
    with pytest.raises(RuntimeError, match="nothing.mhd"):
        fvr.load(str(tmp_path / "nothing.mhd"))


def test_transmission_is_beer_lambert(renderer):
    img = renderer.render(view="AP", size=128)
    mu = 0.0193  # per mm
    expected = 2.0 * np.exp(-mu * img.astype(np.float64))
    got = renderer.transmission(img, mu_water=mu, exposure=2.0)
    np.testing.assert_allclose(got, expected, rtol=1e-6)
    # The default beam is water's attenuation at 70 keV (NIST XCOM, 0.01937 per mm).
    default = renderer.transmission(img, exposure=2.0)
    np.testing.assert_array_equal(default, renderer.transmission(img, energy_kev=70, exposure=2.0))
    assert not np.array_equal(default, got)
    film = fvr.film(img, energy_kev=70)
    assert film.shape == img.shape and 0.0 <= film.min() and film.max() <= 1.0
    # Film look (inverted): more attenuation is brighter.
    assert film.flat[np.argmax(img)] >= film.flat[np.argmin(img)]


def test_progress_is_reported_and_its_exception_stops_preprocessing(body):
    seen = []
    fvr.Renderer(body, progress=lambda f, stage: seen.append(f))
    assert seen and seen == sorted(seen) and seen[-1] <= 1.0

    def stop(f, stage):
        raise KeyError("enough")
    with pytest.raises(RuntimeError, match="enough"):
        fvr.Renderer(body, progress=stop)


def released_gil_during(call, then=None) -> bool:
    """Whether another Python thread ran while `call` was in C++. The switch interval is set far
    above the call's length, so that the interpreter never takes the GIL from a thread that
    holds it: the observer thread, woken just before the call, gets the GIL during the call only
    if the call releases it, and otherwise only after the call has returned."""
    state = {"in_call": False}
    seen = []
    go = threading.Event()

    def observe():
        go.wait()
        seen.append(state["in_call"])
        if then is not None:
            then()

    observer = threading.Thread(target=observe)
    observer.start()
    interval = sys.getswitchinterval()
    sys.setswitchinterval(60.0)
    try:
        state["in_call"] = True
        go.set()
        # The observer wakes and queues for the GIL while this thread holds it (a busy wait
        # gives the GIL away no more than the C++ call would).
        until = time.perf_counter() + 0.05
        while time.perf_counter() < until:
            pass
        call()
        state["in_call"] = False
    finally:
        sys.setswitchinterval(interval)
    observer.join()
    return seen[0]


def test_the_gil_is_released_while_cpp_works(body):
    # One thread in C++: the other core stays free for the observer.
    r = fvr.Renderer(body, threads=1, **SETTINGS)
    assert released_gil_during(lambda: fvr.Renderer(body, threads=1, **SETTINGS))
    assert released_gil_during(lambda: r.render(view="AP", size=512))
    assert released_gil_during(lambda: r.render_many(["AP", "LEFT"] * 2, size=512))
    assert released_gil_during(lambda: fvr.load("phantom:chest"))


def test_two_threads_render_at_once(body):
    """The second thread's render starts while the first's is in C++: both render at once."""
    renderers = [fvr.Renderer(body, threads=1, **SETTINGS) for _ in range(2)]
    stacks = []
    views = ["AP", "LEFT", "PA", "RIGHT"] * 2
    assert released_gil_during(lambda: stacks.append(renderers[0].render_many(views, size=256)),
                               then=lambda: stacks.append(renderers[1].render_many(views, size=256)))
    assert len(stacks) == 2
    np.testing.assert_array_equal(stacks[0], stacks[1])


# --- Resource limits: bad values end in ValueError with the numbers, never in gigabytes or NaN.

def run_bounded(code: str) -> subprocess.CompletedProcess:
    """Runs Python `code` in a child limited to 4 GiB of address space and 120 s: a regression
    (a render that grows without bound) fails there instead of taking the machine."""
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, preexec_fn=limit, env=env)


def test_tiny_pixel_sizes_raise_value_error_with_the_numbers():
    # A pixel of 1e-6 mm once grew the process to 9 GB in the voxel model's table.
    r = run_bounded(
        "import fvr\n"
        "r = fvr.Renderer(fvr.load('phantom:shepp-logan:32'), voxel_model='trilinear')\n"
        "for d in (1e-6, 1e-300, 1e300):\n"
        "    try:\n"
        "        r.render(size=128, pixel_size=d)\n"
        "        print('rendered', d)\n"
        "    except ValueError as e:\n"
        "        print('ValueError:', e)\n")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert len(lines) == 3, r.stdout + r.stderr
    assert all(line.startswith("ValueError: pixel size ") for line in lines), r.stdout
    assert "pixel size 1e-06 mm: the 128-pixel image would span 0.000128 mm" in lines[0]
    assert "expected a pixel size from" in lines[1]


def test_values_that_overflow_float_raise_instead_of_rendering_nan():
    # Float voxels of 3e38 once gave NaN pixels (6,561 of 16,384) and no error.
    vol = fvr.Volume(np.full((16, 16, 16), 3e38, np.float32), name="huge")
    with pytest.raises(ValueError) as e:
        fvr.Renderer(vol).render(size=128)
    assert "huge: values too large for float: |value| up to 3e+38" in str(e.value)
    # Large values that fit still render, finite.
    img = fvr.Renderer(fvr.Volume(np.full((16, 16, 16), 1e25, np.float32))).render(size=128)
    assert np.isfinite(img).all() and img.max() > 0


def test_paths_and_arguments_holding_nul_raise_value_error(tmp_path):
    with pytest.raises(ValueError) as e:
        fvr.load(str(tmp_path / "a\0b.nii"))
    assert "path holds a NUL character" in str(e.value)
    assert str(tmp_path / "a") + "\\0b.nii'" in str(e.value)  # the whole path, NUL escaped
    with pytest.raises(ValueError) as e:
        fvr.run_cli(["phantom:shepp-logan:32", "--size", "128", "--out",
                     str(tmp_path / "x\0.npy")])
    assert "argument 5 holds a NUL character" in str(e.value)
    assert not (tmp_path / "x").exists()
