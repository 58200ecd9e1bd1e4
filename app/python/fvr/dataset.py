"""Datasets of DRRs on a Dask cluster: ``python3 -m fvr.dataset MANIFEST.csv --out DIR``.

The manifest is a CSV with a header: ``id`` and ``path`` (what fvr-render takes as INPUT) are
required; any other column is one of fvr-render's render options by its name (``sweep``,
``views``, ``size``, ``pixel_size`` or ``pixel-size``, ``kernel``, ``oversampling``, ``values``,
``voxel_model``, ``view``, ``axis``, ``deapodize``, ``beer_lambert``...: ALLOWED_COLUMNS); an
empty cell or an absent column is fvr-render's default, ``true``/``yes`` gives a flag,
``false``/``no`` leaves it out. Any other column is refused: the options that write files, send
data or talk to a PACS (``out``, ``material_out``, ``send``, ``store``...), and unknown ones. An
id names the study's files in DIR: no path separator, control character or leading dot, no
ending .npy/.json/.zarr/.part, at most 200 bytes, and unique compared in NFC, case-folded
(``A`` and ``a`` would be one file on a macOS or Windows disk). A bad manifest stops the run
with an error naming the file, the line and the reason. A ``geometry`` column gives each row's
projection: ``parallel`` (an empty cell, and the default: Fourier volume rendering) or ``cone``
(fvr-render --geometry cone: a C-arm's point source, ray cast; the cone-beam options
``primary_angle``, ``sid``, ``sod``, ``detector_size``, ``pitch``, ``ray_model``... are columns
then: CONE_COLUMNS).

Each row is one Dask task (load, preprocess once, all views) that runs fvr-render itself in
the worker's process (fvr.run_cli): ``DIR/<id>.npy`` is the (N, H, W) float32 stack that
``fvr-render PATH ... --out X.npy`` writes, ``DIR/<id>.json`` its sidecar, with a "dataset"
record added at its end (the row's id, its geometry, its settings and their hash). With ``--format zarr``
the stack becomes ``DIR/<id>.zarr`` (one chunk per view). A row whose sidecar holds the hash of
its settings and whose output exists is skipped (resumable); a failing row is reported and the
others go on (exit status 1 when any failed). A LocalCluster by default (``--workers N``
processes, one study at a time each, ``cores / N`` threads per study), or an existing cluster
(``--scheduler ADDRESS``; start its workers with ``--nthreads 1`` so that each holds one
study's spectrum at a time). ``--workers 0`` renders in this process, without Dask.
"""
from __future__ import annotations

import argparse
import csv
import hashlib
import io
import itertools
import json
import os
import sys
import time
import unicodedata
from pathlib import Path
from typing import Optional

import numpy as np

import fvr

# The manifest's columns besides id and path: fvr-render's render options (the settings of the
# pixels), and no other. tests/python/test_dataset.py checks this list against `fvr-render --help`
# so that the two cannot drift apart: every option there is either allowed here or refused.
ALLOWED_COLUMNS = frozenset({
    # Input
    "series", "raw-dims", "raw-type", "raw-spacing", "raw-big-endian", "raw-header",
    # View and image
    "dir", "up", "view", "size", "pixel-size",
    # Rendering
    "preset", "kernel", "kernel-width", "deapodize", "transform", "oversampling", "values",
    "voxel-model", "pixel-aperture", "no-clip", "clip", "keep-negative", "non-negative",
    "depth-cue", "sharpen", "sharpen-radius", "band-limit", "backend", "fp16", "threads",
    # Many views (a views file is read, as INPUT is)
    "sweep", "axis", "views",
    # X-ray and polychromatic X-ray
    "beer-lambert", "mu-water", "energy", "exposure", "kvp", "filtration-al", "filtration-cu",
    "detector", "csi-um", "materials", "noise-mas", "electronic-noise", "seed",
})
# fvr-render --geometry cone's options (the C-arm, the detector, the ray caster), columns where the
# fvr-render of this package has them: the list above is fvr-render's options and no other.
CONE_COLUMNS = frozenset({
    "geometry", "primary-angle", "secondary-angle", "sid", "sod", "isocenter", "detector-size",
    "pitch", "principal-point", "ray-model", "step", "flat-field", "orbit", "pixel-subsamples",
    # Treatment beams (IEC 61217)
    "beam", "sad", "patient-position", "beam-number",
    # A camera file is read, as INPUT is: 3x4 matrices, an X-ray's geometry, an RT Plan's beams
    "projection-matrix", "geometry-from", "frame", "rtplan",
})


def _renders_cone() -> bool:
    """Whether this package's fvr-render takes --geometry cone."""
    try:
        fvr._fvr.check_settings(["--geometry=parallel"])
        return True
    except ValueError:
        return False


RENDERS_CONE = _renders_cone()
if RENDERS_CONE:
    ALLOWED_COLUMNS = ALLOWED_COLUMNS | CONE_COLUMNS
# The geometry column's values: fvr-render's --geometry (parallel, the default, or cone).
GEOMETRIES = ("parallel", "cone")

# fvr-render options a manifest may not set, and why: the dataset decides the outputs, and a row
# never writes a file outside --out, sends data or talks to a PACS. Any option not allowed above
# is refused too (these only get a more precise message).
REFUSED_COLUMNS = {
    "out": "the dataset decides the output files",
    "numbered": "the dataset decides the output files",
    "bit-depth": "the dataset decides the output files (.npy or Zarr)",
    "material-out": "it writes a file outside the dataset's outputs",
    "info": "it does not render", "bench": "it does not render", "gpu-info": "it does not render",
    "help": "it does not render", "query": "it does not render",
    "query-series": "it does not render",
    "send": "it sends data to a PACS", "store": "it writes into a study store",
    "retrieve": "it talks to a PACS", "ae-title": "it talks to a PACS",
    "listen-port": "it talks to a PACS", "pacs-timeout": "it talks to a PACS",
    "tls": "it talks to a PACS", "tls-cert": "it talks to a PACS",
    "tls-key": "it talks to a PACS", "tls-ca": "it talks to a PACS",
    "tls-no-verify": "it talks to a PACS",
}
# What the dataset writes for a study <id> in --out (and fvr-render's own FILE.json and
# temporaries): an id ending so would name another study's files.
RESERVED_SUFFIXES = (".npy", ".json", ".zarr", ".part")
MAX_ID_BYTES = 200  # the longest name made from an id (temporaries) stays within 255 bytes
_TRUE, _FALSE = {"true", "yes"}, {"false", "no"}


class ManifestError(ValueError):
    """A manifest that cannot be read: names the file, the line and the problem."""


def _column_name(column: str) -> str:
    """A column's fvr-render option name: ``pixel_size`` and ``pixel-size`` are --pixel-size."""
    return column.replace("_", "-")


def _check_columns(path, columns: list) -> None:
    for need in ("id", "path"):
        if need not in columns:
            raise ManifestError(f"{path}:1: no '{need}' column (columns: {', '.join(columns)})")
    seen = {}
    for k, c in enumerate(columns, start=1):
        name = _column_name(c)
        if not c:
            raise ManifestError(f"{path}:1: column {k} has no name")
        if name in seen:
            raise ManifestError(f"{path}:1: column '{c}' given twice (as '{seen[name]}' before)")
        seen[name] = c
        if c in ("id", "path", "geometry"):
            continue
        if name in REFUSED_COLUMNS:
            raise ManifestError(f"{path}:1: column '{c}': not a setting a manifest may give "
                                f"({REFUSED_COLUMNS[name]})")
        if name not in ALLOWED_COLUMNS:
            allowed = ", ".join(sorted(ALLOWED_COLUMNS))
            raise ManifestError(f"{path}:1: column '{c}': unknown (a column is id, path or one "
                                f"of fvr-render's render options: {allowed})")


def check_id(job_id: str) -> None:
    """Raises ValueError saying why `job_id` cannot name a study's files in --out: empty, a
    path (/ \\ . ..), hidden (a leading dot: the temporaries' names), a control character, a
    reserved suffix (another study's file names) or too long."""
    if not job_id:
        raise ValueError("an empty id")
    bad = next((c for c in job_id if unicodedata.category(c) in ("Cc", "Zl", "Zp")), None)
    if bad is not None:
        raise ValueError(f"id {job_id!r} holds the control character U+{ord(bad):04X}")
    if "/" in job_id or "\\" in job_id:
        raise ValueError(f"id {job_id!r} holds a path separator (/ or \\)")
    if job_id.startswith("."):
        raise ValueError(f"id {job_id!r} starts with '.' (., .. and hidden names are the "
                         f"dataset's temporaries)")
    for suffix in RESERVED_SUFFIXES:
        if job_id.casefold().endswith(suffix):
            raise ValueError(f"id {job_id!r} ends with {suffix} (the dataset's own file names "
                             f"end so: {', '.join(RESERVED_SUFFIXES)})")
    if len(job_id.encode("utf-8")) > MAX_ID_BYTES:
        raise ValueError(f"id of {len(job_id.encode('utf-8'))} bytes (at most {MAX_ID_BYTES})")


def id_key(job_id: str) -> str:
    """What two ids must not share: NFC and case-folded (a macOS or Windows disk, or a copy of
    the dataset there, holds one file for both)."""
    return unicodedata.normalize("NFC", unicodedata.normalize("NFC", job_id).casefold())


def _manifest_text(path) -> str:
    data = Path(path).read_bytes()
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise ManifestError(f"{path}:{line}: not UTF-8 text (byte {e.start}: {e.reason})") from None


def read_manifest(path) -> list:
    """The manifest's rows as jobs: {"id", "path", "args" (fvr-render options), "line"}.
    Raises ManifestError naming the file, the line and the reason (OSError where it cannot be
    read)."""
    reader = csv.reader(io.StringIO(_manifest_text(path), newline=""))
    jobs, ids = [], {}
    try:
        header = next(reader, None)
        columns = [c.strip() for c in header or []]
        _check_columns(path, columns)
        for cells in reader:
            line = reader.line_num
            if not any(c.strip() for c in cells):
                continue  # a blank line
            if len(cells) > len(columns):
                raise ManifestError(f"{path}:{line}: {len(cells)} cells, the header names "
                                    f"{len(columns)} columns")
            row = {c: v.strip() for c, v in zip(columns, cells)}
            row.update({c: "" for c in columns[len(cells):]})
            jobs.append(_job(path, line, row, ids))
    except csv.Error as e:
        raise ManifestError(f"{path}:{reader.line_num}: {e}") from None
    return jobs


def _job(path, line: int, row: dict, ids: dict) -> dict:
    if not row["id"] or not row["path"]:
        raise ManifestError(f"{path}:{line}: empty id or path")
    try:
        check_id(row["id"])
    except ValueError as e:
        raise ManifestError(f"{path}:{line}: {e}") from None
    key = id_key(row["id"])
    if key in ids:
        same = "" if ids[key][1] == row["id"] else f" as '{ids[key][1]}'"
        raise ManifestError(f"{path}:{line}: id '{row['id']}' repeated (line {ids[key][0]}{same}; "
                            f"ids are compared in NFC, case-folded)")
    ids[key] = (line, row["id"])
    if row["path"].startswith("-"):
        raise ManifestError(f"{path}:{line}: path {row['path']!r} starts with '-' (it would be "
                            f"read as an option)")
    geometry = _geometry_cell(path, line, row.get("geometry", ""))
    args = _row_args({k: v for k, v in row.items() if k != "geometry"})
    if geometry != "parallel":  # parallel, the default, adds no argument (nor a new hash)
        args.insert(0, f"--geometry={geometry}")
    return {"id": row["id"], "path": row["path"], "line": line, "geometry": geometry,
            "args": args}


def _geometry_cell(path, line: int, cell: str) -> str:
    """The row's geometry: parallel (an empty cell too) or cone; ManifestError otherwise, and
    for cone where this fvr-render has no cone beam."""
    geometry = cell.lower() or "parallel"
    if geometry not in GEOMETRIES:
        raise ManifestError(f"{path}:{line}: geometry {cell!r}: expected "
                            f"{' or '.join(GEOMETRIES)}")
    if geometry == "cone" and not RENDERS_CONE:
        raise ManifestError(f"{path}:{line}: geometry 'cone': this fvr-render renders parallel "
                            f"projections only (it has no --geometry cone)")
    return geometry


def job_geometry(job: dict) -> str:
    """A job's geometry: its "geometry", else (a job made by hand) its --geometry argument."""
    if "geometry" in job:
        return job["geometry"]
    given = [a.partition("=")[2] for a in job["args"] if a.partition("=")[0] == "--geometry"]
    return given[-1] if given else "parallel"


def _row_args(row: dict) -> list:
    """fvr-render arguments: `--name` for a flag, else one `--name=value` argument (a value
    that looks like an option stays the option's value)."""
    args = []
    for key, value in row.items():
        if key in ("id", "path") or value == "":
            continue
        name = "--" + _column_name(key)
        if value.lower() in _TRUE:
            args.append(name)
        elif value.lower() not in _FALSE:
            args.append(f"{name}={value}")
    return args


def output_paths(job: dict, out_dir, fmt: str) -> list:
    """Every path a study's rendering names in --out: its output and sidecar, and the
    temporaries (fvr-render's FILE.json, the Zarr conversion's .npy, the .part names)."""
    out = Path(out_dir)
    output, sidecar = _paths(out, job["id"], fmt)
    npy = _npy_path(out, job["id"], fmt)
    return [output, sidecar, npy, Path(str(npy) + ".json"), _part(sidecar), _part(output)]


# Which defaults fvr-render fills in for the options a row leaves out. 2: core's RenderSettings
# (the AP view, mu, kaiser-bessel4 with gridding correction at 1.25x); before it (no key): the
# axial view, raw values, linear at 1x. A row rendered under other defaults renders again.
DEFAULTS_VERSION = 2


def settings_hash(job: dict, fmt: str) -> str:
    """What decides a study's output: its input, its settings (threads aside: they change the
    speed, not the pixels), the defaults that fill in the rest, and the format."""
    args = []
    for a in job["args"]:  # as separate words (--name value), the hash's form from the start
        name, eq, value = a.partition("=")
        if name != "--threads":
            args += [name, value] if eq else [name]
    text = json.dumps({"path": job["path"], "args": args, "format": fmt,
                       "defaults": DEFAULTS_VERSION}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def _paths(out_dir: Path, job_id: str, fmt: str):
    return out_dir / f"{job_id}.{fmt}", out_dir / f"{job_id}.json"


def _npy_path(out_dir: Path, job_id: str, fmt: str) -> Path:
    """The .npy fvr-render writes: the output itself, or the Zarr conversion's input."""
    return out_dir / f"{job_id}.npy" if fmt == "npy" else out_dir / f".{job_id}.part.npy"


_part_count = itertools.count(1)


def _writer_identity() -> str:
    """This process's pid space as fvr's writers name it (core::writerIdentity): FNV-1a (32
    bits) of the host name, a newline and the pid namespace link /proc/self/ns/pid, in 8 hex
    digits. A cleaner on another host or in another container sees another identity and keeps
    the file (its pid cannot be checked there)."""
    import socket

    text = socket.gethostname().encode() + b"\n"
    try:
        text += os.readlink("/proc/self/ns/pid").encode()
    except OSError:
        pass
    h = 2166136261
    for c in text:
        h = ((h ^ c) * 16777619) & 0xFFFFFFFF
    return f"{h:08x}"


def _part(path: Path) -> Path:
    """A temporary name for `path` in its folder, this process's own: .NAME.PID-ID.N.part (the
    form fvr-render's writers use, so that fvr-render on this host removes it once this process
    is dead, and one on another host sharing --out never does)."""
    return path.with_name(
        f".{path.name}.{os.getpid()}-{_writer_identity()}.{next(_part_count)}.part")


def is_done(job: dict, out_dir: Path, fmt: str) -> bool:
    """Whether the study's output exists with a sidecar holding its settings' hash."""
    output, sidecar = _paths(out_dir, job["id"], fmt)
    try:
        record = json.loads(sidecar.read_text()).get("dataset", {})
    except (OSError, ValueError):
        return False
    return output.exists() and record.get("settings_hash") == settings_hash(job, fmt)


def _add_record(sidecar: Path, record: dict, replace: Optional[tuple] = None) -> None:
    """Adds the "dataset" record at the end of fvr-render's sidecar (its text kept as written)
    and replaces it atomically; `replace` (old, new) swaps a path in it."""
    text = sidecar.read_text().rstrip()
    if replace:
        text = text.replace(json.dumps(replace[0])[1:-1], json.dumps(replace[1])[1:-1])
    assert text.endswith("}"), f"{sidecar}: not a JSON object"
    text = text[:-1].rstrip() + ',\n  "dataset": ' + json.dumps(record) + "\n}\n"
    tmp = _part(sidecar)
    try:
        tmp.write_text(text)
        os.replace(tmp, sidecar)
    finally:
        tmp.unlink(missing_ok=True)


def _require(module: str, package: str, what: str):
    """Imports `module`, or stops with what to install (Debian's package) instead of a traceback."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        sys.exit(f"fvr.dataset: {what} needs {module} (Debian: apt install {package})")


def _to_zarr(npy: Path, target: Path) -> None:
    import shutil

    zarr = _require("zarr", "python3-zarr", "--format zarr")

    stack = np.load(npy, mmap_mode="r")
    part = _part(target)
    try:
        z = zarr.open(str(part), mode="w", shape=stack.shape, dtype="f4",
                      chunks=(1,) + stack.shape[1:])
        for i in range(stack.shape[0]):
            z[i] = stack[i]
        shutil.rmtree(target, ignore_errors=True)
        os.replace(part, target)
    finally:
        shutil.rmtree(part, ignore_errors=True)
    npy.unlink()


def render_study(job: dict, out_dir: str, fmt: str = "npy", threads: int = 0) -> dict:
    """One study (a Dask task): fvr-render in this process. Returns {"id", "ok", "views",
    "seconds"} and, when it failed, "error" (the message); never raises."""
    t0 = time.perf_counter()
    out = Path(out_dir)
    output, sidecar = _paths(out, job["id"], fmt)
    npy = _npy_path(out, job["id"], fmt)
    args = [job["path"], *job["args"]]
    if threads > 0 and not any(a.split("=")[0] == "--threads" for a in args):
        args += ["--threads", str(threads)]
    try:
        check_id(job["id"])  # a job made by hand, not read_manifest's: its files stay in out_dir
        fvr.run_cli(args + ["--out", str(npy)])
        os.replace(str(npy) + ".json", sidecar)  # fvr-render's FILE.npy.json
        if fmt == "zarr":
            _to_zarr(npy, output)
        record = {"id": job["id"], "geometry": job_geometry(job), "args": job["args"],
                  "settings_hash": settings_hash(job, fmt), "format": fmt}
        _add_record(sidecar, record, None if fmt == "npy" else (str(npy), str(output)))
        views = len(json.loads(sidecar.read_text())["views"])
        return {"id": job["id"], "ok": True, "views": views, "seconds": time.perf_counter() - t0}
    except Exception as e:  # one study's failure is reported, the others go on
        return {"id": job["id"], "ok": False, "error": f"{type(e).__name__}: {e}",
                "seconds": time.perf_counter() - t0}


def _log(result: dict, done: int, total: int) -> None:
    head = f"fvr.dataset: [{done}/{total}] {result['id']}:"
    if result["ok"]:
        print(f"{head} {result['views']} views in {result['seconds']:.1f} s", file=sys.stderr)
    else:
        print(f"{head} FAILED: {result['error']}", file=sys.stderr)


def _client(scheduler: Optional[str], workers: int, processes: bool):
    distributed = _require("dask.distributed", "python3-distributed",
                           "a cluster (--scheduler, or --workers N > 0; --workers 0 needs none)")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster

    if scheduler:
        return Client(scheduler), None
    # Worker processes listen on the loopback only; threads (processes=False) talk in-process.
    where = {"host": "127.0.0.1"} if processes else {}
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                           dashboard_address=":0", **where)
    return Client(cluster), cluster


def run(manifest, out_dir, scheduler: Optional[str] = None, workers: int = 2,
        fmt: str = "npy", threads: Optional[int] = None, processes: bool = True) -> list:
    """Renders the manifest's studies not done yet; returns their results (render_study's),
    the skipped ones as {"id", "ok": True, "skipped": True}. Raises ManifestError."""
    jobs = read_manifest(manifest)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    results = [{"id": j["id"], "ok": True, "skipped": True} for j in jobs if is_done(j, out, fmt)]
    todo = [j for j in jobs if not is_done(j, out, fmt)]
    print(f"fvr.dataset: {len(jobs)} studies, {len(results)} done before, {len(todo)} to render",
          file=sys.stderr)
    if threads is None:  # the machine's cores shared among the local workers
        threads = 0 if scheduler else max(1, (os.cpu_count() or 1) // max(1, workers))
    if not todo:
        return results
    if workers == 0 and not scheduler:
        for k, job in enumerate(todo, 1):
            results.append(render_study(job, str(out), fmt, threads))
            _log(results[-1], k, len(todo))
        return results
    from dask.distributed import as_completed

    client, cluster = _client(scheduler, workers, processes)
    try:
        futures = [client.submit(render_study, job, str(out.resolve()), fmt, threads, pure=False,
                                 key=f"fvr-study-{job['id']}-{settings_hash(job, fmt)[:12]}")
                   for job in todo]
        for k, future in enumerate(as_completed(futures), 1):
            results.append(future.result())
            _log(results[-1], k, len(todo))
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return results


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python3 -m fvr.dataset", description=__doc__.split("\n")[0])
    p.add_argument("manifest", help="CSV: id, path and fvr-render options by name")
    p.add_argument("--out", required=True, help="output folder (DIR/<id>.npy|zarr, DIR/<id>.json)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", help="address of an existing Dask scheduler")
    where.add_argument("--workers", type=int, default=2,
                       help="LocalCluster worker processes (default 2; 0: no Dask, in this process)")
    p.add_argument("--format", choices=["npy", "zarr"], default="npy")
    p.add_argument("--threads", type=int,
                   help="threads per study (default: cores / workers; all a worker's cores "
                        "with --scheduler)")
    a = p.parse_args(argv)
    try:
        results = run(a.manifest, a.out, a.scheduler, a.workers, a.format, a.threads)
    except (ManifestError, OSError) as e:
        print(f"fvr.dataset: error: {e}", file=sys.stderr)
        return 2
    failed = [r for r in results if not r["ok"]]
    print(f"fvr.dataset: {len(results) - len(failed)} studies done, {len(failed)} failed"
          + "".join(f"\n  {r['id']}: {r['error']}" for r in failed), file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    from fvr.dataset import main as _main  # the tasks pickle as fvr.dataset's, not __main__'s

    sys.exit(_main())
