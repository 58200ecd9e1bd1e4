#!/usr/bin/env python3
"""The CPU Table 1 (the paper's layout) in Markdown from one or more fvr_bench JSON files:

    build/bench/fvr_bench --benchmark_filter='BM_Frame/|BM_BareFft|BM_Preprocess' \\
        --benchmark_out=run.json --benchmark_out_format=json
    /usr/bin/python3 bench/cpu_tables.py run.json

Per (N, transform, M): the slicing rate of every kernel (slice fps), the inverse 2D transform's
rate (the median over the kernels: it does not depend on them), the whole frame in ms per kernel,
and the frame in units of one bare M x M complex FFTW transform measured in the same run
(BM_BareFft: the yardstick a frame is measured in). A cell is the median over the repetitions whose other_cores
(CPU used by other processes meanwhile) is below 0.25; if none is that quiet, the least
disturbed one, marked *."""
import collections
import json
import statistics
import sys

QUIET = 0.25
KERNELS = ["nearest", "linear", "bspline", "catmull-rom", "sinc4", "kaiser-bessel4",
           "kaiser-bessel6"]
HEAD = ["NN", "TL", "B-spline", "C-R", "sinc4", "KB4", "KB6"]

runs = collections.defaultdict(list)
for path in sys.argv[1:]:
    for b in json.load(open(path))["benchmarks"]:
        if b.get("run_type") == "iteration" and "error_occurred" not in b:
            runs[b["run_name"].split("/iterations")[0]].append(b)


def cell(name, key):
    reps = runs.get(name)
    if not reps:
        return None, ""
    quiet = [r for r in reps if r.get("other_cores", 0) < QUIET]
    if quiet:
        return statistics.median(r[key] for r in quiet), ""
    return min(reps, key=lambda r: r.get("other_cores", 0))[key], "*"


def fmt(v, mark, digits=0):
    return "–" if v is None else f"{v:,.{digits}f}{mark}"


out = ["| N, transform | M | " + " | ".join(f"{h} slice fps" for h in HEAD)
       + " | inverse 2D fps | frame ms (" + " / ".join(HEAD) + ") | bare FFT ms | frame / bare FFT ("
       + " / ".join(HEAD) + ") |",
       "|---|---:|" + "---:|" * len(HEAD) + "---:|---|---:|---|"]
for n in (128, 256, 512):
    for t in ("fft", "fht"):
        first = True
        for m in (256, 512, 1024):
            base = f"BM_Frame/N{n}/{t}/M{m}/"
            if not any(base + k in runs for k in KERNELS):
                continue
            sl = [cell(base + k, "slice_fps") for k in KERNELS]
            tot = [cell(base + k, "total_ms") for k in KERNELS]
            inv = [cell(base + k, "inverse_ms")[0] for k in KERNELS]
            inv = [x for x in inv if x is not None]
            fft, fmark = cell(f"BM_BareFft/M{m}", "fft_ms")
            ratios = " / ".join("–" if v is None or fft is None else f"{v / fft:.1f}"
                                for v, _ in tot)
            label = f"{n}³ {t.upper()}" if first else ""
            first = False
            out.append(f"| {label} | {m} | " + " | ".join(fmt(v, mk) for v, mk in sl)
                       + f" | {1000 / statistics.median(inv):,.0f} | "
                       + " / ".join(fmt(v, mk, 2) for v, mk in tot)
                       + f" | {fmt(fft, fmark, 3)} | {ratios} |")

pre = [(n, meth) for n in (128, 256, 512) for meth in ("fft", "fht-fromfft", "fht-dht")
       if f"BM_Preprocess/N{n}/{meth}" in runs]
if pre:
    out.append("\n| N | preprocessing | total ms |")
    out.append("|---:|---|---:|")
    for n, meth in pre:
        v, mk = cell(f"BM_Preprocess/N{n}/{meth}", "total_ms")
        out.append(f"| {n} | {meth} | {fmt(v, mk, 1)} |")
print("\n".join(out))
