"""python3 -m fvr.dataset on a Dask LocalCluster against the single-process result (the built
fvr-render run on each study): the same stacks bit for bit, the same sidecar facts; resumed
after one output is deleted (only that study rendered again); a broken study reported without
losing the others; Zarr output; manifest errors."""
import hashlib
import json
import os
import re
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


# Ids name a study's files in --out: `a` writes a.npy, a.json and, for a moment, fvr-render's
# a.npy.json, which is row `a.npy`'s final sidecar. Each reason names the file and the line.
@pytest.mark.parametrize("job_id, reason", [
    ("a.npy", "ends with .npy"), ("A.NPY", "ends with .npy"), ("b.json", "ends with .json"),
    ("c.zarr", "ends with .zarr"), ("d.part", "ends with .part"),
    ("x/y", "path separator"), ("x\\y", "path separator"), ("..", "starts with '.'"),
    (".", "starts with '.'"), (".hidden", "starts with '.'"),
    ("tab\there", "control character U+0009"), ("nul\x00", "control character U+0000"),
    ("del\x7f", "control character U+007F"), ("x" * 201, "201 bytes"),
])
def test_ids_that_would_name_other_files_are_refused(tmp_path, job_id, reason):
    (tmp_path / "m.csv").write_text(f'id,path\nok,phantom:chest\n"{job_id}",phantom:chest\n')
    with pytest.raises(dataset.ManifestError) as e:
        dataset.read_manifest(tmp_path / "m.csv")
    assert str(e.value).startswith(f"{tmp_path / 'm.csv'}:3: ") and reason in str(e.value)


@pytest.mark.parametrize("first, second", [
    ("a", "a"), ("Study", "study"),  # a case-folding disk holds one file for both
    ("caf\u00e9", "cafe\u0301"),  # NFC: the same name, composed and decomposed
    ("STRASSE", "stra\u00dfe"),  # case-folded, German sharp s
])
def test_ids_equal_after_normalisation_clash(tmp_path, first, second):
    (tmp_path / "m.csv").write_text(f"id,path\n{first},phantom:chest\n{second},phantom:chest\n",
                                    encoding="utf-8")
    with pytest.raises(dataset.ManifestError, match=":3: id .* repeated \\(line 2"):
        dataset.read_manifest(tmp_path / "m.csv")


def test_ids_a_and_a_npy_are_refused_before_anything_is_written(tmp_path):
    """The clash itself: rendering `a` leaves a.npy.json, row `a.npy`'s sidecar
    name, in --out; the id check refuses `a.npy` before anything is written."""
    (tmp_path / "m.csv").write_text("id,path,size\na,phantom:shepp-logan:32,128\n"
                                    "a.npy,phantom:shepp-logan:32,128\n")
    with pytest.raises(dataset.ManifestError, match="m.csv:3: id 'a.npy' ends with .npy"):
        dataset.run(tmp_path / "m.csv", tmp_path / "out", workers=0)
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").iterdir())


@pytest.mark.parametrize("column, reason", [
    ("material_out", "writes a file outside"), ("material-out", "writes a file outside"),
    ("send", "sends data to a PACS"), ("store", "study store"), ("retrieve", "PACS"),
    ("ae_title", "PACS"), ("listen_port", "PACS"), ("numbered", "output files"),
    ("bench", "does not render"), ("query", "does not render"), ("bit_depth", "output files"),
])
def test_columns_that_write_or_send_are_refused(tmp_path, column, reason):
    (tmp_path / "m.csv").write_text(f"id,path,{column}\na,phantom:chest,/tmp/elsewhere.npy\n")
    with pytest.raises(dataset.ManifestError,
                       match=f"m.csv:1: column '{column}': not a setting .*{reason}"):
        dataset.read_manifest(tmp_path / "m.csv")


@pytest.mark.parametrize("header, message", [
    ("id,path,sizee", "column 'sizee': unknown"), ("id,path,Size", "column 'Size': unknown"),
    ("id,path,size,size", "column 'size' given twice"),
    ("id,path,pixel_size,pixel-size", "column 'pixel-size' given twice"),
    ("id,path,", "column 3 has no name"), ("path", "no 'id' column"),
])
def test_unknown_and_repeated_columns_are_refused(tmp_path, header, message):
    (tmp_path / "m.csv").write_text(header + "\n")
    with pytest.raises(dataset.ManifestError, match=message):
        dataset.read_manifest(tmp_path / "m.csv")


def test_a_value_that_looks_like_an_option_stays_the_options_value(tmp_path):
    """`--size --material-out=/x.npy` could have been read as two options; one argument
    `--size=...` is one option's (bad) value. A path starting with '-' is refused."""
    (tmp_path / "m.csv").write_text("id,path,view\na,phantom:chest,--material-out=/tmp/x.npy\n")
    (job,) = dataset.read_manifest(tmp_path / "m.csv")
    assert job["args"] == ["--view=--material-out=/tmp/x.npy"]
    result = dataset.render_study(job, str(tmp_path / "out"))
    assert not result["ok"] and "--view" in result["error"]
    (tmp_path / "m.csv").write_text("id,path\na,--send=dicom://X@h:1\n")
    with pytest.raises(dataset.ManifestError, match="m.csv:2: path '--send=.*' starts with '-'"):
        dataset.read_manifest(tmp_path / "m.csv")


def test_bad_text_is_a_manifest_error_naming_the_line(tmp_path):
    (tmp_path / "m.csv").write_bytes(b"id,path\na,phantom:chest\nb\xff,phantom:chest\n")
    with pytest.raises(dataset.ManifestError, match="m.csv:3: not UTF-8"):
        dataset.read_manifest(tmp_path / "m.csv")


def test_hashes_of_settings_follow_the_words_and_the_defaults():
    """The arguments are `--name=value`; the hash takes them as separate words (`--name value`,
    as earlier versions did), and the version of the defaults that fill in what a row leaves
    out: a row rendered under the earlier defaults (linear, raw, axial) is rendered again."""
    job = {"path": "p", "args": ["--size=128", "--keep-negative", "--threads=4"]}
    words = {"path": "p", "args": ["--size", "128", "--keep-negative"], "format": "npy"}
    current = dict(words, defaults=dataset.DEFAULTS_VERSION)
    assert dataset.settings_hash(job, "npy") == hashlib.sha256(
        json.dumps(current, sort_keys=True).encode()).hexdigest()
    assert dataset.settings_hash(job, "npy") != hashlib.sha256(
        json.dumps(words, sort_keys=True).encode()).hexdigest()


def _help_options(fvr_render) -> dict:
    """fvr-render --help's options, each with its group's title."""
    text = subprocess.run([fvr_render, "--help"], capture_output=True, text=True, check=True).stdout
    options, group = {}, ""
    for line in text.splitlines():
        if line and not line.startswith(" ") and line.rstrip().endswith(":"):
            group = line.rstrip()[:-1]
        for name in re.findall(r"^\s+(?:-\w,\s*)?--([a-z0-9][a-z0-9-]*)", line):
            options[name] = group
    return options


def test_the_allowed_columns_are_fvr_renders_render_options(fvr_render):
    """The allow-list and fvr-render's options cannot drift apart: every allowed column is an
    option of fvr-render, and every option of fvr-render is allowed or refused by name (an
    option added to fvr-render fails here until it is put in one list), but for the PACS
    options, which a manifest never sets (refused whatever they are)."""
    options = _help_options(fvr_render)
    assert len(options) > 40, options
    assert not dataset.ALLOWED_COLUMNS - set(options), "allowed but not fvr-render's"
    assert not dataset.ALLOWED_COLUMNS & set(dataset.REFUSED_COLUMNS)
    unsorted = {o for o, g in options.items() if g != "PACS"} - dataset.ALLOWED_COLUMNS - set(
        dataset.REFUSED_COLUMNS)
    assert not unsorted, f"fvr-render options neither allowed nor refused: {sorted(unsorted)}"
    pacs = {o for o, g in options.items() if g == "PACS"}
    assert {"send", "store", "retrieve"} <= pacs and not pacs & dataset.ALLOWED_COLUMNS


def test_every_allowed_column_is_accepted_by_fvr_render(tmp_path):
    """Each allowed column reaches fvr-render as an option it knows (its value may be bad; the
    input is missing, so that nothing renders: the options are read before the input)."""
    unknown = "The following argument was not expected"
    for column in sorted(dataset.ALLOWED_COLUMNS) + ["sizee"]:
        job = {"id": "a", "path": str(tmp_path / "missing.mhd"), "args": [f"--{column}=1"]}
        result = dataset.render_study(job, str(tmp_path / "out"))
        assert not result["ok"]
        assert (unknown in result["error"]) == (column == "sizee"), (column, result["error"])


def test_temporaries_name_their_host_as_fvr_render_reads_it(fvr_render, tmp_path):
    """Workers on other machines write into one shared --out: the tool's temporaries name their
    pid space as fvr-render's writers do, so fvr-render on this host removes one whose writer
    died here and keeps another host's (whose pid means nothing here)."""
    child = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                           capture_output=True, text=True, check=True)
    dead = int(child.stdout)  # exited: its pid names no process (or a reused one: kept)
    ours = dataset._part(tmp_path / "a.npy").name
    assert re.fullmatch(r"\.a\.npy\.%d-[0-9a-f]{8}\.\d+\.part" % os.getpid(), ours), ours
    identity = ours.split(".")[3].split("-")[1]
    other = "00000000" if identity != "00000000" else "00000001"
    mine = tmp_path / f".a.npy.{dead}-{identity}.1.part"
    foreign = tmp_path / f".a.npy.{dead}-{other}.1.part"
    for p in (mine, foreign):
        p.write_text("x")
    run_fvr_render(fvr_render, ["phantom:shepp-logan:16", "--backend", "cpu", "--size", "128"],
                   tmp_path / "b.npy")
    assert not mine.exists()
    assert foreign.exists()


# --- The geometry column: parallel (the default) or cone.

def test_the_geometry_column_is_parallel_by_default_and_keeps_the_hash(tmp_path):
    """A geometry cell "parallel", or empty, or no column at all: the same fvr-render
    arguments, so the same settings hash as before the column existed (no study renders
    again); the job and the sidecar's dataset record say "parallel"."""
    manifest = tmp_path / "m.csv"
    manifest.write_text("id,path,geometry,size\na,phantom:chest:64,parallel,128\n"
                        "b,phantom:chest:64,,128\nc,phantom:chest:64,PARALLEL,128\n")
    plain = tmp_path / "plain.csv"
    plain.write_text("id,path,size\na,phantom:chest:64,128\n")
    (before,) = dataset.read_manifest(plain)
    jobs = dataset.read_manifest(manifest)
    assert [j["geometry"] for j in jobs] == ["parallel"] * 3
    assert [j["args"] for j in jobs] == [["--size=128"]] * 3
    assert {dataset.settings_hash(j, "npy") for j in jobs} == {
        dataset.settings_hash(before, "npy")}
    assert before["geometry"] == "parallel"
    (tmp_path / "out").mkdir()
    result = dataset.render_study(jobs[0], str(tmp_path / "out"))
    assert result["ok"], result
    record = json.loads((tmp_path / "out" / "a.json").read_text())["dataset"]
    assert record["geometry"] == "parallel"
    assert record["settings_hash"] == dataset.settings_hash(before, "npy")


def test_a_bad_geometry_is_a_manifest_error_naming_the_line(tmp_path):
    manifest = tmp_path / "m.csv"
    manifest.write_text("id,path,geometry\na,phantom:chest:64,\nb,phantom:chest:64,fan\n")
    with pytest.raises(dataset.ManifestError) as e:
        dataset.read_manifest(manifest)
    assert str(e.value) == f"{manifest}:3: geometry 'fan': expected parallel or cone"


def test_cone_rows_render_fvr_renders_cone_beam_or_are_refused_where_it_has_none(
        tmp_path, fvr_render):
    """geometry=cone passes --geometry=cone and the cone-beam columns to fvr-render: its stack
    and the camera in its sidecar, as fvr-render writes them. An fvr-render without cone beam
    (the dataset asks the package's own) refuses the row naming the line."""
    manifest = tmp_path / "m.csv"
    if not dataset.RENDERS_CONE:
        manifest.write_text("id,path,geometry\na,phantom:chest:64,parallel\n"
                            "b,phantom:chest:64,cone\n")
        with pytest.raises(dataset.ManifestError) as e:
            dataset.read_manifest(manifest)
        assert str(e.value) == (f"{manifest}:3: geometry 'cone': this fvr-render renders "
                                f"parallel projections only (it has no --geometry cone)")
        assert "--geometry" not in subprocess.run([fvr_render, "--help"], capture_output=True,
                                                  text=True).stdout
        return
    assert dataset.CONE_COLUMNS <= dataset.ALLOWED_COLUMNS
    manifest.write_text("id,path,geometry,primary_angle,sid,sod,detector_size,ray_model\n"
                        "c,phantom:chest:64,cone,30,1000,750,64x48,box\n")
    (job,) = dataset.read_manifest(manifest)
    assert job["geometry"] == "cone"
    assert job["args"][0] == "--geometry=cone"
    (tmp_path / "out").mkdir()
    result = dataset.render_study(job, str(tmp_path / "out"))
    assert result["ok"], result
    stack = np.load(tmp_path / "out" / "c.npy")
    expected = run_fvr_render(fvr_render, ["phantom:chest:64", "--geometry", "cone",
                                           "--primary-angle", "30", "--sid", "1000", "--sod",
                                           "750", "--detector-size", "64x48", "--ray-model",
                                           "box"], tmp_path / "cli.npy")
    assert stack.shape[-2:] == (48, 64)  # W x H: 64 columns, 48 rows
    np.testing.assert_array_equal(stack, expected)
    record = json.loads((tmp_path / "out" / "c.json").read_text())["dataset"]
    assert record["geometry"] == "cone"


def test_a_size_column_takes_any_width_and_height(tmp_path):
    """Training sets use 64^2, 200^2, 224^2 and detectors' own shapes: W x H stacks (N, H, W)."""
    (tmp_path / "m.csv").write_text("id,path,sweep,size\nwide,phantom:shepp-logan:32,3,96x64\n"
                                    "small,phantom:shepp-logan:32,2,64\n")
    done = subprocess.run([sys.executable, "-m", "fvr.dataset", str(tmp_path / "m.csv"), "--out",
                           str(tmp_path / "out"), "--workers", "0"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert np.load(tmp_path / "out" / "wide.npy").shape == (3, 64, 96)
    assert np.load(tmp_path / "out" / "small.npy").shape == (2, 64, 64)
