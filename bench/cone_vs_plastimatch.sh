#!/usr/bin/env bash
# Cone-beam speed target: a C-arm orbit of a CT (default 90 views of the 512x512x140 Philips CT at
# 512^2, SID 1200 mm, SOD 750 mm, the isocentre at the volume's centre, the detector framing the
# volume) by `plastimatch drr -i exact` and by our box model (Siddon's exact path lengths, the
# same voxel model), each run as one whole job (load to last file written), on the same cores;
# prints a Markdown table of ms per view, and checks that both drew the same images.
#
# Usage: bench/cone_vs_plastimatch.sh [BUILD_DIR] [CT]
#   BUILD_DIR   default build (fvr-render in app/, fvr_bench_cone in bench/)
#   CT          default ../shared/data/dicom/ct_phantom_philips_512x512x140 (a DICOM folder)
#   env VIEWS (90), SIZE (512), SID (1200), SOD (750): the orbit
#   env PLM_VIEWS   plastimatch's views (default VIEWS; fewer saves time, ms per view compares)
#   env REPEATS     runs of each whole job (default 1): the median and the best are reported
#   env ONE_THREAD  1: also both on one thread (plastimatch OMP_NUM_THREADS=1, ours --threads 1)
#   env FVR_RENDER  the fvr-render to time (default BUILD_DIR/app/fvr-render)
#   env WORK        scratch folder (default: a fresh one under /tmp, deleted at the end)
# Needs plastimatch (a test dependency: packaging/install-deps.sh --tests), /usr/bin/time and
# /usr/bin/python3 with numpy. Our whole job is `fvr-render --geometry cone --ray-model box`;
# where that fvr-render has no --geometry yet, only fvr_bench_cone's per-view times are given.
# Not a ctest test: one run takes a few minutes.
#
# Like with like:
#   - geometry: plastimatch's own orbit (-a, -N) turns the gantry the other way from DICOM's
#     primary angle and starts at -y radians (its 1.9.4 reads -y in radians, -N in degrees,
#     although --help says degrees for both): -y -pi/2 -N -360/VIEWS puts its view k where our
#     view k is (primary angle k 360/VIEWS, secondary 0); its columns are ours mirrored
#     (tests/support/plastimatch.h has the whole mapping and how it was found);
#   - values: plastimatch -P none integrates the HU as stored; fvr-render runs twice, with its
#     default --values mu (air is 0: empty blocks skipped) and with --values raw (HU: nothing
#     to skip, every voxel on a ray visited, as plastimatch visits them);
#   - plastimatch reads a MetaImage made once, not timed (plastimatch convert, then resample
#     onto the same grid plus one layer of zeros: its exact tracer leaves out each ray's last
#     voxel, then always a zero); fvr-render decodes the DICOM series inside its timed job;
#     both write every view (plastimatch .pfm files, fvr-render one .npy stack);
#   - threads: both use every core by default (plastimatch's ray loop is an OpenMP loop).
set -euo pipefail
trap 'echo "cone_vs_plastimatch.sh: line $LINENO failed: $BASH_COMMAND" >&2' ERR

BUILD=${1:-build}
CT=${2:-../shared/data/dicom/ct_phantom_philips_512x512x140}
VIEWS=${VIEWS:-90}
PLM_VIEWS=${PLM_VIEWS:-$VIEWS}
SIZE=${SIZE:-512}
SID=${SID:-1200}
SOD=${SOD:-750}
REPEATS=${REPEATS:-1}
PY=/usr/bin/python3
FVR=${FVR_RENDER:-$BUILD/app/fvr-render}
BENCH=$BUILD/bench/fvr_bench_cone

for tool in plastimatch /usr/bin/time "$PY" "$BENCH"; do
    command -v "$tool" > /dev/null || { echo "cone_vs_plastimatch.sh: $tool not found" >&2; exit 2; }
done
[[ -e $CT ]] || { echo "cone_vs_plastimatch.sh: $CT: not found" >&2; exit 2; }
CT=$(realpath "$CT")
BENCH=$(realpath "$BENCH")
HAVE_CONE=0
FVR_HELP=$([[ -x $FVR ]] && "$FVR" --help 2>&1 || true)
if [[ $FVR_HELP == *"--geometry parallel|cone"* ]]; then
    HAVE_CONE=1
    FVR=$(realpath "$FVR")
fi
if [[ -z ${WORK:-} ]]; then
    WORK=$(mktemp -d /tmp/cone-bench.XXXXXX)
    trap 'rm -rf "$WORK"' EXIT
fi
mkdir -p "$WORK/plm" "$WORK/fvr"
LOAD_AT_START=$(cut -d' ' -f1-3 /proc/loadavg)
CPU_MODEL=$(awk -F': ' '/^model name/{print $2; exit}' /proc/cpuinfo)

# /usr/bin/time's "wall user sys" of one command; its own output goes to $WORK/last.log.
timed() {
    /usr/bin/time -f "%e %U %S" -o "$WORK/time.txt" "$@" > "$WORK/last.log" 2>&1 || {
        echo "cone_vs_plastimatch.sh: failed: $*" >&2
        tail -20 "$WORK/last.log" >&2
        return 1
    }
    cat "$WORK/time.txt"
}
median() { sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }
# A file of "wall user sys" lines -> "median best cpu_use_of_the_median_run".
stats() {
    local m
    m=$(awk '{print $1}' "$1" | median)
    awk -v m="$m" '{if (NR == 1 || $1 < b) b = $1}
        $1 == m && !c {c = sprintf("%.2f", ($2 + $3) / ($1 > 0 ? $1 : 1))}
        END {print m, b, c}' "$1"
}
per() { awk -v t="$1" -v n="$2" 'BEGIN {printf "%.1f", 1000 * t / n}'; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN {printf "%.1f", (b > 0 ? a / b : 0)}'; }

# 1. Not timed: the MetaImage plastimatch reads, padded with one layer of zeros, and the geometry
#    (fvr-render's defaults: the isocentre at the volume's centre; the pitch that fits the
#    volume's diagonal, magnified SID/SOD, on the detector).
plastimatch convert --input "$CT" --output-img "$WORK/ct.mha" --output-type float \
    > "$WORK/convert.log" 2>&1
# (The MetaImage header's own numbers: `plastimatch header` prints 4 decimals only.)
read -r ISO_X ISO_Y ISO_Z PAD_ORIGIN PAD_DIM PAD_SPACING DET < <(
    awk -v sid="$SID" -v sod="$SOD" -v n="$SIZE" '
    /^Offset =/ {ox = $3; oy = $4; oz = $5} /^DimSize =/ {nx = $3; ny = $4; nz = $5}
    /^ElementSpacing =/ {sx = $3; sy = $4; sz = $5}
    /^ElementDataFile/ {exit}
    END {
        d = sqrt((nx * sx) ^ 2 + (ny * sy) ^ 2 + (nz * sz) ^ 2)
        printf "%.10f %.10f %.10f %.12g,%.12g,%.12g %d,%d,%d %.12g,%.12g,%.12g %.10f\n",
            ox + (nx - 1) / 2 * sx, oy + (ny - 1) / 2 * sy, oz + (nz - 1) / 2 * sz,
            ox - sx, oy - sy, oz - sz, nx + 2, ny + 2, nz + 2, sx, sy, sz, d * sid / sod}' \
        "$WORK/ct.mha")
plastimatch resample --input "$WORK/ct.mha" --output "$WORK/ct_pad.mha" --interpolation nn \
    --default-value 0 --output-type float --origin "${PAD_ORIGIN//,/ }" --dim "${PAD_DIM//,/ }" \
    --spacing "${PAD_SPACING//,/ }" > "$WORK/resample.log" 2>&1
rm -f "$WORK/ct.mha"

# 2. plastimatch, the whole job.
STEP=$(awk -v n="$PLM_VIEWS" 'BEGIN {printf "%.9g", -360 / n}')
PLM_CMD=(plastimatch drr -A cpu -i exact -P none -t pfm -r "$SIZE $SIZE" -z "$DET $DET"
    --sad "$SOD" --sid "$SID" -o "$ISO_X $ISO_Y $ISO_Z" -a "$PLM_VIEWS" -N "$STEP"
    -y -1.5707963267948966 -O "$WORK/plm/view_" "$WORK/ct_pad.mha")
: > "$WORK/plm.txt"
for ((r = 0; r < REPEATS; ++r)); do timed "${PLM_CMD[@]}" >> "$WORK/plm.txt"; done
if [[ ${ONE_THREAD:-0} == 1 ]]; then
    : > "$WORK/plm_one.txt"
    for ((r = 0; r < REPEATS; ++r)); do
        OMP_NUM_THREADS=1 timed "${PLM_CMD[@]}" >> "$WORK/plm_one.txt"
    done
fi

# 3. fvr-render, the whole job: mu (its default) and raw.
FVR_BASE=(--geometry cone --ray-model box --sid "$SID" --sod "$SOD" --detector-size "${SIZE}x${SIZE}"
    --sweep "$VIEWS")
if [[ $HAVE_CONE == 1 ]]; then
    for values in mu raw; do
        : > "$WORK/fvr_$values.txt"
        for ((r = 0; r < REPEATS; ++r)); do
            timed "$FVR" "$CT" "${FVR_BASE[@]}" --values "$values" --out "$WORK/fvr/$values.npy" \
                >> "$WORK/fvr_$values.txt"
        done
    done
    if [[ ${ONE_THREAD:-0} == 1 ]]; then
        : > "$WORK/fvr_one.txt"
        for ((r = 0; r < REPEATS; ++r)); do
            timed "$FVR" "$CT" "${FVR_BASE[@]}" --values raw --threads 1 \
                --out "$WORK/fvr/one.npy" >> "$WORK/fvr_one.txt"
        done
    fi
fi

# 4. fvr_bench_cone: the load, the projector's set-up and the views, each timed on its own.
FVR_BENCH_CT="$CT" "$BENCH" --benchmark_format=json --benchmark_out="$WORK/bench.json" \
    --benchmark_filter="BM_LoadCT|BM_Prepare/box/|BM_ConeView/box/(mu|raw)/M${SIZE}(/threads1)?/" \
    > "$WORK/bench.log" 2>&1 || { tail -20 "$WORK/bench.log" >&2; exit 1; }

# 5. The table.
read -r PLM PLM_B PLM_C < <(stats "$WORK/plm.txt")
PLM_V=$(per "$PLM" "$PLM_VIEWS")
echo "### Cone beam: a ${VIEWS}-view orbit at ${SIZE}x${SIZE}, SID $SID, SOD $SOD: plastimatch against our box model"
echo
echo "Machine: $(nproc) cores, $CPU_MODEL, load average at start $LOAD_AT_START, at the end" \
    "$(cut -d' ' -f1-3 /proc/loadavg). CT $(basename "$CT"); detector pitch" \
    "$(awk -v d="$DET" -v n="$SIZE" 'BEGIN {printf "%.4f", d / n}') mm. Whole jobs: median (best)" \
    "of $REPEATS run(s); CPU use = (user + sys) / wall."
echo
echo "| run | views | whole job (s) | per view (ms) | CPU use | plastimatch per view / this |"
echo "|---|---:|---:|---:|---:|---:|"
echo "| plastimatch drr -i exact -P none (load, render, write) | $PLM_VIEWS | $PLM ($PLM_B) | $PLM_V | $PLM_C | 1 |"
if [[ ${ONE_THREAD:-0} == 1 ]]; then
    read -r M B C < <(stats "$WORK/plm_one.txt")
    echo "| plastimatch, OMP_NUM_THREADS=1 | $PLM_VIEWS | $M ($B) | $(per "$M" "$PLM_VIEWS") | $C | |"
fi
if [[ $HAVE_CONE == 1 ]]; then
    for values in mu raw; do
        read -r M B C < <(stats "$WORK/fvr_$values.txt")
        echo "| fvr-render --ray-model box --values $values (load, render, write) | $VIEWS | $M ($B) |" \
            "$(per "$M" "$VIEWS") | $C | **$(ratio "$PLM_V" "$(per "$M" "$VIEWS")")** |"
    done
    if [[ ${ONE_THREAD:-0} == 1 ]]; then
        read -r M B C < <(stats "$WORK/fvr_one.txt")
        echo "| fvr-render --values raw --threads 1 | $VIEWS | $M ($B) | $(per "$M" "$VIEWS") | $C | |"
    fi
else
    echo "| fvr-render --geometry cone | | not in this build ($FVR has no --geometry) | | | |"
fi
"$PY" - "$WORK/bench.json" "$PLM_V" << 'EOF'
import json, sys

runs = json.load(open(sys.argv[1]))["benchmarks"]
plm = float(sys.argv[2])
for b in runs:
    name = b["name"].split("/iterations")[0]
    ms = b.get("ms_per_view", b["real_time"])
    what = {"BM_LoadCT": "fvr_bench_cone: load the CT (once per job)"}.get(name)
    if what is None and name.startswith("BM_Prepare"):
        what = "fvr_bench_cone: %s set-up (once per job)" % name[len("BM_Prepare/"):]
    if what:
        print("| %s | | %.3f | | | |" % (what, b["real_time"] / 1000.0))
    else:
        print("| fvr_bench_cone %s: one view, rendering only | %d | | %.1f | | %.1f |"
              % (name[len("BM_ConeView/"):], b["iterations"], ms, plm / ms if ms else 0))
EOF
echo
PLM_TEXT="${PLM_CMD[*]}"
echo "- plastimatch: \`${PLM_TEXT//$WORK\//}\` (ct_pad.mha: the CT made by"
echo "  \`plastimatch convert\` and \`plastimatch resample\` with one layer of zeros, not timed)"
[[ $HAVE_CONE == 1 ]] && echo "- fvr-render: \`fvr-render CT ${FVR_BASE[*]} --values mu|raw --out v.npy\`"
echo "- fvr_bench_cone: \`FVR_BENCH_CT=CT fvr_bench_cone --benchmark_filter=...\` (per-view times" \
    "over the same orbit, rendering only; threads: every core unless /threads1)"

# 6. Did both draw the same images? plastimatch's views against fvr-render --values raw's (its
#    columns mirrored back; its line integrals x 10: it writes value x cm).
if [[ $HAVE_CONE == 1 ]]; then
    "$PY" - "$WORK/fvr/raw.npy" "$WORK/plm" "$PLM_VIEWS" "$VIEWS" << 'EOF'
import math, sys
import numpy as np

ours = np.load(sys.argv[1], mmap_mode="r")
n_plm, n_ours = int(sys.argv[3]), int(sys.argv[4])


def read_pfm(path):
    with open(path, "rb") as f:
        assert f.readline().strip() == b"Pf"
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        a = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4").reshape(h, w)
    return a.astype(np.float64)  # plastimatch writes its top row first


print()
print("| view (primary angle) | PSNR, ours against plastimatch (dB) |")
print("|---|---:|")
for k in sorted({0, n_plm // 4, n_plm // 3}):
    angle = 360.0 * k / n_plm
    j = angle * n_ours / 360.0
    if abs(j - round(j)) > 1e-9:
        continue
    ref = 10.0 * read_pfm("%s/view_%04d.pfm" % (sys.argv[2], k))[:, ::-1]
    img = np.asarray(ours[int(round(j))], dtype=np.float64)
    rmse = math.sqrt(np.mean((img - ref) ** 2))
    psnr = 20 * math.log10(np.abs(ref).max() / rmse) if rmse > 0 else float("inf")
    print("| %d (%.4g) | %.1f |" % (k, angle, psnr))
EOF
fi
