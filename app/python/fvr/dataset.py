"""Datasets of DRRs on a Dask cluster: ``python3 -m fvr.dataset MANIFEST.csv --out DIR``.

The manifest is a CSV with a header: ``id`` and ``path`` (what fvr-render takes as INPUT) are
required; any other column is an fvr-render option by its name (``sweep``, ``views``, ``size``,
``pixel_size`` or ``pixel-size``, ``kernel``, ``oversampling``, ``values``, ``voxel_model``,
``view``, ``axis``, ``deapodize``, ``beer_lambert``...); an empty cell or an absent column is
fvr-render's default, ``true``/``yes`` gives a flag, ``false``/``no`` leaves it out.

Each row is one Dask task (load, preprocess once, all views) that runs fvr-render itself in
the worker's process (fvr.run_cli): ``DIR/<id>.npy`` is the (N, M, M) float32 stack that
``fvr-render PATH ... --out X.npy`` writes, ``DIR/<id>.json`` its sidecar, with a "dataset"
record added at its end (the row's id, its settings and their hash). With ``--format zarr``
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
import json
import os
import sys
import time
from pathlib import Path
from typing import Optional

import numpy as np

import fvr

# Options the dataset decides itself (the output) or that do not render.
_RESERVED = {"out", "info", "bench", "numbered", "gpu-info", "help"}
_TRUE, _FALSE = {"true", "yes"}, {"false", "no"}


class ManifestError(ValueError):
    """A manifest that cannot be read: names the file, the line and the problem."""


def read_manifest(path) -> list:
    """The manifest's rows as jobs: {"id", "path", "args" (fvr-render options), "line"}."""
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        columns = [c.strip() for c in reader.fieldnames or []]
        for need in ("id", "path"):
            if need not in columns:
                raise ManifestError(f"{path}: no '{need}' column (columns: {', '.join(columns)})")
        for c in columns:
            if c.replace("_", "-") in _RESERVED:
                raise ManifestError(f"{path}: column '{c}': the dataset decides it (not a setting)")
        jobs, ids = [], set()
        for line, row in enumerate(reader, start=2):
            if None in row:  # csv's key for the cells beyond the header's columns
                raise ManifestError(f"{path}:{line}: {len(columns) + len(row[None])} cells, "
                                    f"the header names {len(columns)} columns")
            row = {k.strip(): (v or "").strip() for k, v in row.items()}
            if not row["id"] or not row["path"]:
                raise ManifestError(f"{path}:{line}: empty id or path")
            if row["id"] in ids or "/" in row["id"]:
                raise ManifestError(f"{path}:{line}: id '{row['id']}' repeated or holding '/'")
            ids.add(row["id"])
            jobs.append({"id": row["id"], "path": row["path"], "line": line,
                         "args": _row_args(row)})
    return jobs


def _row_args(row: dict) -> list:
    args = []
    for key, value in row.items():
        if key in ("id", "path") or value == "":
            continue
        name = "--" + key.replace("_", "-")
        if value.lower() in _TRUE:
            args.append(name)
        elif value.lower() not in _FALSE:
            args += [name, value]
    return args


def settings_hash(job: dict, fmt: str) -> str:
    """What decides a study's output: its input, its settings (threads aside: they change the
    speed, not the pixels) and the format."""
    args = list(job["args"])
    if "--threads" in args:
        i = args.index("--threads")
        del args[i:i + 2]
    text = json.dumps({"path": job["path"], "args": args, "format": fmt}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def _paths(out_dir: Path, job_id: str, fmt: str):
    return out_dir / f"{job_id}.{fmt}", out_dir / f"{job_id}.json"


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
    tmp = sidecar.with_name(sidecar.name + ".part")
    tmp.write_text(text)
    os.replace(tmp, sidecar)


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
    part = target.with_name(target.name + ".part")
    shutil.rmtree(part, ignore_errors=True)
    z = zarr.open(str(part), mode="w", shape=stack.shape, dtype="f4",
                  chunks=(1,) + stack.shape[1:])
    for i in range(stack.shape[0]):
        z[i] = stack[i]
    shutil.rmtree(target, ignore_errors=True)
    os.replace(part, target)
    npy.unlink()


def render_study(job: dict, out_dir: str, fmt: str = "npy", threads: int = 0) -> dict:
    """One study (a Dask task): fvr-render in this process. Returns {"id", "ok", "views",
    "seconds"} and, when it failed, "error" (the message); never raises."""
    t0 = time.perf_counter()
    out = Path(out_dir)
    output, sidecar = _paths(out, job["id"], fmt)
    npy = output if fmt == "npy" else out / f".{job['id']}.part.npy"
    args = [job["path"], *job["args"]]
    if threads > 0 and "--threads" not in args:
        args += ["--threads", str(threads)]
    try:
        fvr.run_cli(args + ["--out", str(npy)])
        os.replace(str(npy) + ".json", sidecar)  # fvr-render's FILE.npy.json
        if fmt == "zarr":
            _to_zarr(npy, output)
        record = {"id": job["id"], "args": job["args"], "settings_hash": settings_hash(job, fmt),
                  "format": fmt}
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
