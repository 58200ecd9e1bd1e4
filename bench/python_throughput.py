"""Views per second of the Python module fvr (docs/dev/performance.md): one process (fvr.Renderer,
render_many of a sweep; preprocessing apart) and python3 -m fvr.dataset on a LocalCluster
(end to end: load, preprocess and render every study, write the stacks), against the same
manifest in one process (--workers 0). Median of REPEATS runs.

    PYTHONPATH=build/python /usr/bin/python3 bench/python_throughput.py [CT] [--views N]
"""
import argparse
import statistics
import tempfile
import time
from pathlib import Path

import fvr
from fvr import dataset

def main():
    p = argparse.ArgumentParser()
    p.add_argument("ct", nargs="?", default=str(Path(__file__).resolve().parents[2] /
                                                "shared/data/dicom/ct_phantom_philips_512x512x140"))
    p.add_argument("--views", type=int, default=32)
    p.add_argument("--studies", type=int, default=4)
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args()

    def median_of(fn):
        return statistics.median(fn() for _ in range(a.repeats))

    vol = fvr.load(a.ct)
    t0 = time.perf_counter()
    # The setting docs/dev/performance.md's numbers were taken with (linear, 1x, mu).
    r = fvr.Renderer(vol, sweep=a.views, values="mu", kernel="linear", oversampling=1)
    print(f"{a.ct}: {vol.shape}, preprocessing {time.perf_counter() - t0:.2f} s")
    for size in (256, 512):
        def once():
            t = time.perf_counter()
            r.render_many(size=size)
            return a.views / (time.perf_counter() - t)
        r.render_many(size=size)  # warm-up: plans, buffers
        print(f"one process, render_many {size}^2: {median_of(once):.1f} views/s")

    for size in (256, 512):
        with tempfile.TemporaryDirectory() as tmp:
            manifest = Path(tmp) / "m.csv"
            rows = [f"s{i},{a.ct},{a.views},{size},mu" for i in range(a.studies)]
            manifest.write_text("id,path,sweep,size,values\n" + "\n".join(rows) + "\n")
            for label, workers in (("dataset, one process", 0), ("dataset, LocalCluster 2 workers", 2)):
                def once(k=[0]):
                    k[0] += 1
                    t = time.perf_counter()
                    res = dataset.run(manifest, Path(tmp) / f"out{workers}-{k[0]}", workers=workers,
                                      threads=2 if workers == 0 else 1)
                    assert all(x["ok"] for x in res), res
                    return a.studies * a.views / (time.perf_counter() - t)
                print(f"{label}, {a.studies} studies x {a.views} views {size}^2: "
                      f"{median_of(once):.1f} views/s (end to end)")


if __name__ == "__main__":  # LocalCluster spawns workers that import this file
    main()
