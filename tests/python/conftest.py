"""Shared fixtures of the Python tests: the shared data and the built fvr-render (CTest passes
their paths in FVR_SHARED_DATA_DIR and FVR_RENDER_EXE; PYTHONPATH holds build/python)."""
import atexit
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

# Bit-for-bit comparisons need the same FFTW plans in this process and in fvr-render: ESTIMATE
# plans, no wisdom from earlier runs (a measured plan gives other roundings), set before fvr loads.
os.environ["FVR_FFTW_PLANNING"] = "estimate"
_WISDOM = tempfile.mkdtemp(prefix="fvr-wisdom-")
atexit.register(shutil.rmtree, _WISDOM, ignore_errors=True)
os.environ["FVR_FFTW_WISDOM"] = os.path.join(_WISDOM, "none")

DATA = Path(os.environ.get("FVR_SHARED_DATA_DIR", Path(__file__).parents[3] / "shared" / "data"))
BODY_CT_MHD = DATA / "volumes/body_ct_hu_3mm/example_ct.mhd"
BODY_CT_NII = DATA / "volumes/body_ct_hu_3mm/example_ct.nii.gz"
HEAD_DICOM = DATA / "dicom/ct_head_slicer_64x64x93"
HEADSQ_MHD = DATA / "volumes/headsq"


def need(path: Path) -> str:
    """The path as text, or the test skips saying what is missing."""
    if not path.exists():
        pytest.skip(f"{path} missing (the shared data lies in ../shared/data beside the checkout)")
    return str(path)


@pytest.fixture(scope="session")
def fvr_render() -> str:
    exe = os.environ.get("FVR_RENDER_EXE")
    if not exe or not Path(exe).exists():
        pytest.skip("FVR_RENDER_EXE is not set to the built fvr-render (CTest sets it)")
    return exe


def run_fvr_render(exe: str, args: list, out: Path) -> np.ndarray:
    """fvr-render ARGS --out OUT (.npy), checked; the array it wrote."""
    done = subprocess.run([exe, *map(str, args), "--out", str(out)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return np.load(out)
