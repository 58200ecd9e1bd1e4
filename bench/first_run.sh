#!/usr/bin/env bash
# First run on a fresh machine (no FFTW wisdom) against a warm run (wisdom saved by a run that
# measured its plans), for fvr-render, interleaved so that drifts of the machine's load hit both.
# Prints every run (wall and CPU seconds, the preprocessing and per-view times of the JSON
# sidecar) and the medians with the ratio first/warm.
#   bench/first_run.sh [-n RUNS] [-b FVR_RENDER] STUDY -- [fvr-render options]
#   e.g. bench/first_run.sh -n 3 ../shared/data/dicom/ct_phantom_philips_512x512x140 -- \
#          --sweep 360 --size 512
# Needs /usr/bin/time and python3. Uses FVR_FFTW_WISDOM (two files in a scratch folder), so the
# user's own wisdom is neither read nor written.
set -euo pipefail
runs=3
bin=build/app/fvr-render
while getopts "n:b:" opt; do
    case $opt in
    n) runs=$OPTARG ;;
    b) bin=$OPTARG ;;
    *) exit 2 ;;
    esac
done
shift $((OPTIND - 1))
study=${1:?usage: first_run.sh [-n RUNS] [-b FVR_RENDER] STUDY -- [options]}
shift
[ "${1:-}" = "--" ] && shift
opts=("$@")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

run() { # run KIND WISDOM: one timed run, prints "KIND wall cpu preprocess_ms ms_per_view"
    /usr/bin/time -o "$work/time" -f "%e %U %S" env FVR_FFTW_WISDOM="$2" "$bin" "$study" "${opts[@]}" \
        --out "$work/out.npy" >/dev/null 2>"$work/err" || { cat "$work/err" >&2; exit 1; }
    read -r wall user sys <"$work/time"
    python3 - "$1" "$wall" "$user" "$sys" "$work/out.npy.json" <<'PY'
import json, sys
kind, wall, user, sys_, sidecar = sys.argv[1:]
out = json.load(open(sidecar))["output"]
print(f"{kind} {float(wall):.2f} {float(user) + float(sys_):.2f} "
      f"{out['preprocess_ms']:.0f} {out['render_ms_per_view']:.2f}")
PY
}

# The warm wisdom: a run that measures every plan before it runs (the policy of old).
FVR_FFTW_PLANNING=foreground FVR_FFTW_WISDOM="$work/warm" "$bin" "$study" "${opts[@]}" \
    --out "$work/out.npy" >/dev/null 2>&1
echo "run   wall_s cpu_s preprocess_ms ms_per_view load"
for _ in $(seq "$runs"); do
    rm -f "$work/first"
    echo "$(run first "$work/first") $(cut -d' ' -f1 /proc/loadavg)" | tee -a "$work/log"
    echo "$(run warm "$work/warm") $(cut -d' ' -f1 /proc/loadavg)" | tee -a "$work/log"
done
python3 - "$work/log" <<'PY'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1])]
med = {k: statistics.median(float(r[1]) for r in rows if r[0] == k) for k in ("first", "warm")}
print(f"median wall: first {med['first']:.2f} s, warm {med['warm']:.2f} s, "
      f"ratio {med['first'] / med['warm']:.2f}")
PY
