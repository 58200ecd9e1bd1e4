"""python3 -m fvr.dataset on a Dask LocalCluster against the single-process result (the built
fvr-render run on each study): the same stacks bit for bit, the same sidecar facts; resumed
after one output is deleted (only that study rendered again); a broken study reported without
losing the others; Zarr output; manifest errors."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from fvr import dataset
from conftest import BODY_CT_MHD, DATA, HEAD_DICOM, need, run_fvr_render

HEADSQ = DATA / "volumes/headsq/headsq.mhd"
# id, path, settings (fvr-render options by name; empty: the default)
STUDIES = [
    ("body", BODY_CT_MHD, {"kernel": "kaiser-bessel", "values": "mu", "oversampling": "1.25"}),
    ("head", HEAD_DICOM, {"kernel": "", "values": "", "oversampling": ""}),
    ("headsq", HEADSQ, {"kernel": "bspline", "values": "", "oversampling": ""}),
]
VIEWS, SIZE = 12, 128
pytestmark = pytest.mark.filterwarnings("ignore:make_current is deprecated")  # Debian's tornado


def write_manifest(path, rows):
    columns = ["id", "path", "sweep", "size", "kernel", "values", "oversampling"]
    lines = [",".join(columns)]
    for job_id, study, settings in rows:
        cells = [job_id, str(study), str(VIEWS), str(SIZE)] + [settings[c] for c in columns[4:]]
        lines.append(",".join(cells))
    path.write_text("\n".join(lines) + "\n")
    return path


def cli_args(settings):
    return [a for k, v in settings.items() if v for a in (f"--{k}", v)]


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """The manifest (three studies and a broken one) rendered on a LocalCluster of 2 workers."""
    for _, study, _ in STUDIES:
        need(study)
    tmp = tmp_path_factory.mktemp("dataset")
    rows = STUDIES + [("broken", tmp / "missing.mhd", STUDIES[1][2]),
                      ("bad-kernel", BODY_CT_MHD, {"kernel": "bogus", "values": "", "oversampling": ""})]
    manifest = write_manifest(tmp / "manifest.csv", rows)
    out = tmp / "out"
    results = dataset.run(manifest, out, workers=2, processes=False)
    return manifest, out, {r["id"]: r for r in results}


def test_the_cluster_renders_what_fvr_render_renders(rendered, fvr_render, tmp_path):
    manifest, out, results = rendered
    for job_id, study, settings in STUDIES:
        assert results[job_id]["ok"] and results[job_id]["views"] == VIEWS, results[job_id]
        stack = np.load(out / f"{job_id}.npy")
        assert stack.shape == (VIEWS, SIZE, SIZE) and stack.dtype == np.float32
        single = run_fvr_render(fvr_render, [study, "--sweep", VIEWS, "--size", SIZE,
                                             *cli_args(settings)], tmp_path / f"{job_id}.npy")
        assert stack.tobytes() == single.tobytes(), job_id
        mine = json.loads((out / f"{job_id}.json").read_text())
        theirs = json.loads((tmp_path / f"{job_id}.npy.json").read_text())
        assert mine["views"] == theirs["views"] and mine["volume"] == theirs["volume"]
        for key in ("kernel", "values", "oversampling", "pixel_size_mm", "voxel_model"):
            assert mine["settings"][key] == theirs["settings"][key], key
        assert mine["dataset"]["id"] == job_id and len(mine["dataset"]["settings_hash"]) == 64


def test_a_broken_study_is_reported_and_the_others_done(rendered):
    manifest, out, results = rendered
    assert not results["broken"]["ok"] and "missing.mhd" in results["broken"]["error"]
    assert not results["bad-kernel"]["ok"]
    assert results["bad-kernel"]["error"].startswith("ValueError: --kernel")
    assert not (out / "broken.npy").exists() and not (out / "bad-kernel.json").exists()


def test_resumes_rendering_only_the_deleted_output(rendered):
    manifest, out, _ = rendered
    (out / "head.npy").unlink()
    before = {s[0]: os.stat(out / f"{s[0]}.npy").st_mtime_ns for s in STUDIES if s[0] != "head"}
    results = {r["id"]: r for r in dataset.run(manifest, out, workers=2, processes=False)}
    assert results["head"]["ok"] and not results["head"].get("skipped")
    assert results["body"].get("skipped") and results["headsq"].get("skipped")
    assert not results["broken"]["ok"]  # tried again, failing again
    for job_id, mtime in before.items():
        assert os.stat(out / f"{job_id}.npy").st_mtime_ns == mtime, job_id
    assert np.load(out / "head.npy").shape == (VIEWS, SIZE, SIZE)


def test_changed_settings_render_again(rendered, tmp_path):
    manifest, out, _ = rendered
    text = manifest.read_text().replace(f"headsq,{HEADSQ},{VIEWS},{SIZE},bspline",
                                        f"headsq,{HEADSQ},{VIEWS},{SIZE},linear")
    changed = tmp_path / "changed.csv"
    changed.write_text(text)
    jobs = {j["id"]: j for j in dataset.read_manifest(changed)}
    assert not dataset.is_done(jobs["headsq"], out, "npy") and dataset.is_done(jobs["body"], out, "npy")


def test_zarr_output_holds_the_same_stack(rendered, tmp_path):
    zarr = pytest.importorskip("zarr")
    manifest, out, _ = rendered
    one = tmp_path / "one.csv"
    one.write_text("\n".join(manifest.read_text().splitlines()[:2]) + "\n")  # the body study
    results = dataset.run(one, tmp_path / "z", workers=0, fmt="zarr")
    assert results[0]["ok"], results
    z = zarr.open(str(tmp_path / "z" / "body.zarr"), mode="r")
    np.testing.assert_array_equal(z[:], np.load(out / "body.npy"))
    sidecar = json.loads((tmp_path / "z" / "body.json").read_text())
    assert sidecar["output"]["files"] == [str(tmp_path / "z" / "body.zarr")]
    assert not list((tmp_path / "z").glob("*.npy"))


@pytest.mark.parametrize("text, message", [
    ("id,sweep\na,3\n", "no 'path' column"),
    ("id,path,out\na,phantom:chest,x.npy\n", "column 'out'"),
    ("id,path\na,phantom:chest\na,phantom:chest\n", ":3: id 'a' repeated"),
    # A cell beyond the header was dropped without a word (a shifted row renders wrongly).
    ("id,path\na,phantom:chest\nb,phantom:chest,256\n", ":3: 3 cells, the header names 2"),
])
def test_manifest_errors_name_the_file_and_line(tmp_path, text, message):
    (tmp_path / "m.csv").write_text(text)
    with pytest.raises(dataset.ManifestError, match=message):
        dataset.read_manifest(tmp_path / "m.csv")


def test_the_command_line_reports_a_failure_in_its_exit_status(tmp_path):
    """The command as documented: a LocalCluster of 2 worker processes (on the loopback)."""
    (tmp_path / "m.csv").write_text(f"id,path,size\nphantom,phantom:shepp-logan:64,128\n"
                                    f"missing,{tmp_path}/nothing.nii.gz,128\n")
    done = subprocess.run([sys.executable, "-m", "fvr.dataset", str(tmp_path / "m.csv"), "--out",
                           str(tmp_path / "out"), "--workers", "2"], capture_output=True, text=True)
    assert done.returncode == 1, done.stderr
    assert "missing: RuntimeError" in done.stderr and "1 studies done, 1 failed" in done.stderr
    assert np.load(tmp_path / "out" / "phantom.npy").shape == (128, 128)
