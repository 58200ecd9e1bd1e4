#!/usr/bin/env python3
"""A time-bounded fuzz of the dataset manifest reader, fvr.dataset.read_manifest.

    python3 tests/fuzz/fuzz_manifest.py --time 60 [--seed N] [--engine hypothesis|mutate]

Random CSV bytes and text go in (hypothesis's strategies where python3-hypothesis is importable,
else a seeded mutation loop over valid manifests). For every input, read_manifest must either
return jobs or raise ManifestError (any other exception is a finding), and the jobs must keep
their promises: every file a job's rendering names lies directly inside --out, no two jobs share
one (compared as a case-folding, normalising disk would), the arguments are allowed render
options only (one --name=value word each) and no path starts with '-'. A finding is printed
with its input (also saved as fuzz-manifest-finding-N.csv in the working folder) and the exit
status is 1; otherwise it prints how many inputs were tried and exits 0.

read_manifest needs neither the C++ module nor numpy: where the built package (build/python)
cannot be imported, the source app/python/fvr/dataset.py is loaded with stand-ins for them.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import random
import sys
import tempfile
import time
import traceback
import types
import unicodedata
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def load_dataset():
    """fvr.dataset: the built package, else the source file with stand-ins."""
    build = ROOT / "build" / "python"
    if build.is_dir() and str(build) not in sys.path:
        sys.path.insert(0, str(build))
    try:
        from fvr import dataset  # noqa: PLC0415

        return dataset, f"fvr.dataset from {Path(dataset.__file__).parent}"
    except ImportError:
        pass
    for name in ("fvr", "numpy"):
        if name not in sys.modules:
            try:
                importlib.import_module(name)
            except ImportError:
                sys.modules[name] = types.ModuleType(name)  # unused by read_manifest
    source = ROOT / "app" / "python" / "fvr" / "dataset.py"
    spec = importlib.util.spec_from_file_location("fvr_dataset_source", source)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module, f"{source} (source, without the built module)"


dataset, WHERE = load_dataset()

# Pieces that reach the reader's corners: separators, reserved suffixes, refused columns,
# control characters, Unicode that normalises or folds, bad UTF-8, a BOM, quotes.
TOKENS = [b",", b"\n", b"\r\n", b"\r", b'"', b'""', b"/", b"\\", b".", b"..", b".npy", b".json",
          b".zarr", b".part", b".NPY", b"\x00", b"\t", b"\x7f", b"\xff", b"\xc3", b"\xef\xbb\xbf",
          "é".encode(), "é".encode(), "ß".encode(), "ẞ".encode(), "K".encode(),
          "\u2028".encode(), b"id", b"path", b"material_out", b"material-out", b"send", b"store",
          b"out", b"retrieve", b"size", b"pixel_size", b"pixel-size", b"--", b"-", b"=",
          b"--out=/tmp/x.npy", b"true", b"no", b" ", b"x" * 300, b"phantom:chest"]
IDS = ["a", "a.npy", "A", "b.json", "c.zarr", "d.part", ".", "..", ".h", "x/y", "x\\y", "é",
       "é", "STRASSE", "straße", "a_0001", "-x", "k\x01", "Ω", "Ω", "ﬁ", "fi", ""]
COLUMNS = sorted(dataset.ALLOWED_COLUMNS)[:12] + ["material_out", "send", "store", "out", "bogus",
                                                  "pixel_size", "pixel-size", "id", "path", ""]
SEEDS = [
    b"id,path\na,phantom:chest\n",
    b"id,path,sweep,size,kernel\nbody,/data/ct.mhd,12,128,bspline\nhead,/data/head,,,\n",
    b'id,path,view,beer_lambert\n"x,1",phantom:chest,AP,true\ny,"p ""q""",LEFT,no\n',
    "id,path,size\ncafé,phantom:chest,256\nStudy-1,phantom:shepp-logan:64,128\n".encode(),
    b"\xef\xbb\xbfid,path,threads,seed\r\na,b,2,3\r\nc,d,,\r\n",
]


class Finding(Exception):
    """A broken promise of read_manifest, with its input."""


def fold(name: str) -> str:
    return unicodedata.normalize("NFC", unicodedata.normalize("NFC", name).casefold())


def check(data: bytes, folder: Path) -> None:
    """Runs read_manifest on `data` and checks its promises; raises Finding."""
    manifest = folder / "m.csv"
    manifest.write_bytes(data)
    try:
        jobs = dataset.read_manifest(manifest)
    except dataset.ManifestError as e:
        if not str(e).startswith(str(manifest)):
            raise Finding(f"ManifestError without the file's name: {e}") from None
        return
    except Exception as e:  # noqa: BLE001 -- any other exception is what the fuzz looks for
        raise Finding(f"{type(e).__name__}: {e}\n{traceback.format_exc()}") from None
    out = folder / "out"
    seen = {}
    for job in jobs:
        if job["path"].startswith("-"):
            raise Finding(f"path {job['path']!r} starts with '-'")
        for arg in job["args"]:
            name = arg.partition("=")[0]
            if not name.startswith("--") or name[2:] not in dataset.ALLOWED_COLUMNS:
                raise Finding(f"argument {arg!r} is not an allowed option")
        for fmt in ("npy", "zarr"):
            for p in dataset.output_paths(job, out, fmt):
                name = p.name
                if (p.parent != out or name in ("", ".", "..") or "/" in name or "\0" in name
                        or os.path.normpath(p) != str(p) or len(name.encode()) > 255):
                    raise Finding(f"id {job['id']!r}: {p} is not a file directly in {out}")
                key = (fold(name), fmt)
                if seen.setdefault(key, job["id"]) != job["id"]:
                    raise Finding(f"ids {seen[key]!r} and {job['id']!r} both name {name} ({fmt})")


def mutate(data: bytes, rng: random.Random) -> bytes:
    """One to four random edits of `data`: bytes flipped, inserted, deleted, duplicated, a token
    inserted, or another seed spliced in."""
    b = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        k = rng.randrange(len(b) + 1)
        op = rng.randrange(6)
        if op == 0 and b:
            b[rng.randrange(len(b))] = rng.randrange(256)
        elif op == 1:
            b[k:k] = bytes([rng.randrange(256)])
        elif op == 2 and b:
            del b[k:k + rng.randint(1, 8)]
        elif op == 3 and b:
            j = rng.randrange(len(b))
            b[k:k] = b[j:j + rng.randint(1, 16)]
        elif op == 4:
            b[k:k] = rng.choice(TOKENS)
        else:
            other = rng.choice(SEEDS)
            b[k:] = other[rng.randrange(len(other) + 1):]
    return bytes(b[:4096])


def structured(rng: random.Random) -> bytes:
    """A manifest built of tricky columns and ids (a row or two quoted as csv writes them)."""
    columns = ["id", "path"] + rng.sample(COLUMNS, rng.randint(0, 4))
    rng.shuffle(columns)
    lines = [",".join(columns)]
    for _ in range(rng.randint(0, 5)):
        cells = []
        for c in columns:
            v = rng.choice(IDS) if c == "id" else rng.choice(["1", "", "phantom:chest", "--x",
                                                              "a,b", 'q"q', "true", "é"])
            cells.append('"' + v.replace('"', '""') + '"' if rng.random() < 0.3 else v)
        lines.append(",".join(cells))
    return ("\n".join(lines) + rng.choice(["\n", "\r\n", ""])).encode()


def run_mutation(seconds: float, seed: int, folder: Path) -> int:
    rng = random.Random(seed)
    corpus = list(SEEDS)
    tried = 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        data = structured(rng) if rng.random() < 0.3 else mutate(rng.choice(corpus), rng)
        check(data, folder)
        tried += 1
        if len(corpus) < 500 and rng.random() < 0.05:
            corpus.append(data)  # keeps some mutants to mutate further
    return tried


def mutated(data: bytes, seed: int) -> bytes:
    return mutate(data, random.Random(seed))


def run_hypothesis(seconds: float, seed: int, folder: Path) -> int:
    from hypothesis import configuration

    configuration.set_hypothesis_home_dir(str(folder / ".hypothesis"))  # not in the checkout
    from hypothesis import HealthCheck, given, seed as hseed, settings, strategies as st

    rng = random.Random(seed)
    # Cells of tricky characters (no lone surrogates: bad UTF-8 comes from the binary inputs).
    text = st.text(st.sampled_from(list(",\n\r\"/\\.-=_ aAéßΩ\x00\t\u2028é"))
                   | st.characters(blacklist_categories=("Cs",)), max_size=40)
    allowed = st.sampled_from(sorted(dataset.ALLOWED_COLUMNS))
    ids = st.sampled_from(IDS) | text
    paths = st.sampled_from(["phantom:chest", "p", "-p", ""]) | text

    @st.composite
    def manifest(draw):
        """Mostly valid columns (allowed ones; now and then a tricky one), rows of an id, a
        path and cells no more than the columns."""
        extra = draw(st.lists(allowed | allowed | allowed | st.sampled_from(COLUMNS) | text,
                              max_size=4))
        header = ["id", "path"] + extra
        rows = draw(st.lists(st.tuples(ids, paths, st.lists(text, max_size=len(extra))),
                             max_size=6))
        lines = [header] + [[i, p] + rest for i, p, rest in rows]
        newline = draw(st.sampled_from(["\n", "\r\n"]))
        return newline.join(",".join(cells) for cells in lines).encode("utf-8", "surrogatepass")

    inputs = (manifest() | manifest() | manifest() | st.binary(max_size=2048)
              | st.builds(mutated, st.sampled_from(SEEDS), st.integers()))
    tried = 0

    @settings(max_examples=200, deadline=None, database=None, derandomize=False,
              suppress_health_check=list(HealthCheck))
    @given(inputs)
    def one(data):
        nonlocal tried
        tried += 1
        check(data, folder)

    end = time.monotonic() + seconds
    while time.monotonic() < end:
        hseed(rng.randrange(2 ** 32))(one)()
    return tried


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--time", type=float, default=60.0, help="seconds to run (default 60)")
    p.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    p.add_argument("--engine", choices=["auto", "hypothesis", "mutate"], default="auto",
                   help="hypothesis where importable (auto), or the mutation loop")
    a = p.parse_args(argv)
    engine = a.engine
    if engine == "auto":
        engine = "hypothesis" if importlib.util.find_spec("hypothesis") else "mutate"
    print(f"fuzz_manifest: {engine}, {a.time:g} s, seed {a.seed}, {WHERE}", file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="fuzz-manifest-") as tmp:
        try:
            run = run_hypothesis if engine == "hypothesis" else run_mutation
            tried = run(a.time, a.seed, Path(tmp))
        except Finding as e:
            data = (Path(tmp) / "m.csv").read_bytes()
            k = 1
            while Path(f"fuzz-manifest-finding-{k}.csv").exists():
                k += 1
            Path(f"fuzz-manifest-finding-{k}.csv").write_bytes(data)
            print(f"fuzz_manifest: FINDING: {e}\ninput ({len(data)} bytes, saved as "
                  f"fuzz-manifest-finding-{k}.csv): {data!r}", file=sys.stderr)
            return 1
    print(f"fuzz_manifest: {tried} inputs tried, no finding")
    return 0


if __name__ == "__main__":
    sys.exit(main())
