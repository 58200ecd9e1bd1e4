#!/usr/bin/env bash
# DRR batch benchmark: a fvr-render --sweep of a CT against `plastimatch drr -i exact`
# on the same CT and detector, timed in the same run; prints a Markdown table.
#
# Usage: bench/drr_vs_plastimatch.sh [FVR_RENDER] [CT_DIR] [PLASTIMATCH_VIEWS]
#   FVR_RENDER         default build/app/fvr-render
#   CT_DIR             default ../shared/data/dicom/ct_phantom_philips_512x512x140
#   PLASTIMATCH_VIEWS  default 36 (plastimatch is slow; its per-view time is what compares)
#   env REPEATS        runs of each timing: the median and the best are reported (default 3)
#   env SWEEP, SIZE    fvr-render views (default 360) and detector size (default 512)
#   env WORK           scratch folder (default: a fresh one under /tmp, deleted at the end)
#   env FVR_EXTRA      more fvr-render options, e.g. "--kernel kaiser-bessel --oversampling 1.25"
#                      (the workstation's default: slower; its images correlate 0.994 with
#                      plastimatch's, the linear default's 0.96, measured on the Philips CT)
# Needs plastimatch (Debian package; a bench-only tool, not a test dependency) and /usr/bin/python3
# with numpy (the image check). Not a ctest test: one run takes about a minute or more.
#
# Like with like: both render the same CT at SIZE x SIZE with the same pixel size at the rotation
# axis (fvr-render's default, the volume diagonal / SIZE, read from its JSON sidecar), rotating
# about the head-feet axis through the volume centre over 360 degrees: a gantry rotation.
# fvr-render gets --view AP (its default view too): a view along the head-feet axis, about which
# the sweep turns, would only spin one projection in the image plane.
# What differs, on purpose:
#   - projection: fvr-render is parallel; plastimatch is perspective, run here with a 100 m SAD
#     (and the detector 0.5 m beyond the axis) so its rays diverge by <= 0.1 degree;
#   - interpolation: plastimatch -i exact sums exact path lengths through voxel boxes (Siddon);
#     fvr-render renders the trilinear voxel model with the linear kernel at 1x, as the published
#     numbers were taken (FVR_EXTRA picks another);
#   - values: fvr-render --values mu (1 + HU/1000, the line integral in mm); plastimatch's default
#     HU conversion (its attenuation scale differs by a constant factor: reported, not compared);
#   - plastimatch reads the CT as one MetaImage (converted once, not timed); fvr-render decodes the
#     DICOM series in its timed job; both write every view (plastimatch .pfm files, fvr-render one
#     .npy stack);
#   - threads: fvr-render --threads default (all cores), plastimatch OpenMP default (all cores;
#     its drr_ray_trace_image calls GOMP_parallel, yet on the 2-core machine its CPU use stayed
#     at 1.0 and OMP_NUM_THREADS=1 ran as fast), and both again on one thread; the CPU use
#     (user + sys) / wall of each run is reported.
set -euo pipefail
trap 'echo "drr_vs_plastimatch.sh: line $LINENO failed: $BASH_COMMAND" >&2' ERR

FVR=${1:-build/app/fvr-render}
CT=${2:-../shared/data/dicom/ct_phantom_philips_512x512x140}
PLM_VIEWS=${3:-36}
REPEATS=${REPEATS:-3}
SWEEP=${SWEEP:-360}
SIZE=${SIZE:-512}
PY=/usr/bin/python3

for tool in plastimatch /usr/bin/time "$PY" "$FVR"; do
    command -v "$tool" > /dev/null || { echo "drr_vs_plastimatch.sh: $tool not found" >&2; exit 2; }
done
[[ -d $CT ]] || { echo "drr_vs_plastimatch.sh: $CT: no such folder" >&2; exit 2; }
FVR=$(realpath "$FVR")
CT=$(realpath "$CT")
if [[ -z ${WORK:-} ]]; then
    WORK=$(mktemp -d /tmp/drr-bench.XXXXXX)
    trap 'rm -rf "$WORK"' EXIT
fi
mkdir -p "$WORK/plm"
LOAD_AT_START=$(cut -d' ' -f1-3 /proc/loadavg)
# The share of the last 10 s in which some task waited for a CPU (Linux PSI): other work on a
# shared machine shows here at once, where the load average lags.
cpu_pressure() { awk '/^some/ {sub("avg10=", "", $2); print $2 "%"}' /proc/pressure/cpu 2> /dev/null || echo "n/a"; }
PRESSURE_AT_START=$(cpu_pressure)
CPU_MODEL=$(awk -F': ' '/^model name/{print $2; exit}' /proc/cpuinfo)

# /usr/bin/time's "wall user sys" of one command; its own output goes to $WORK/last.log.
timed() {
    /usr/bin/time -f "%e %U %S" -o "$WORK/time.txt" "$@" > "$WORK/last.log" 2>&1 || {
        echo "drr_vs_plastimatch.sh: failed: $*" >&2
        tail -20 "$WORK/last.log" >&2
        return 1
    }
    cat "$WORK/time.txt"
}
median() { sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }

# 1. Not timed: the MetaImage plastimatch reads (this also brings the DICOM files into the page
#    cache, so the fvr-render runs below all read them from memory).
plastimatch convert --input "$CT" --output-img "$WORK/ct.mha" > "$WORK/convert.log" 2>&1
read -r ISO_X ISO_Y ISO_Z < <(plastimatch header "$WORK/ct.mha" | awk '
    /^Origin/ {ox = $3; oy = $4; oz = $5} /^Size/ {nx = $3; ny = $4; nz = $5}
    /^Spacing/ {sx = $3; sy = $4; sz = $5}
    END {printf "%.4f %.4f %.4f\n", ox + (nx - 1) / 2 * sx, oy + (ny - 1) / 2 * sy, oz + (nz - 1) / 2 * sz}')

# 2. fvr-render: per repeat, a first run with a new (empty) FFTW wisdom file, then a warm run
#    with the wisdom the first one saved.
read -r -a FVR_EXTRA_ARGS <<< "${FVR_EXTRA:-}"
FVR_ARGS=(--view AP --sweep "$SWEEP" --size "$SIZE" --values mu --kernel linear --oversampling 1
    "${FVR_EXTRA_ARGS[@]}"
    --out "$WORK/fvr.npy")
WISDOM="$WORK/wisdom"
: > "$WORK/fvr_cold.txt"
: > "$WORK/fvr_warm.txt"
for ((r = 0; r < REPEATS; ++r)); do
    rm -f "$WISDOM"
    FVR_FFTW_WISDOM="$WISDOM" timed "$FVR" "$CT" "${FVR_ARGS[@]}" >> "$WORK/fvr_cold.txt"
    FVR_FFTW_WISDOM="$WISDOM" timed "$FVR" "$CT" "${FVR_ARGS[@]}" >> "$WORK/fvr_warm.txt"
done
read -r PIXEL FVR_THREADS < <("$PY" -c '
import json, sys
s = json.load(open(sys.argv[1]))["settings"]
print("%.6f %d" % (s["pixel_size_mm"], s["threads"]))' "$WORK/fvr.npy.json")
# One thread each, a per-core comparison (plastimatch's ray tracing, drr_ray_trace_image, is an
# OpenMP loop; OMP_NUM_THREADS=1 below): fvr-render --threads 1, warm (a first untimed run adds
# the one-thread plans to the wisdom).
FVR_FFTW_WISDOM="$WISDOM" timed "$FVR" "$CT" "${FVR_ARGS[@]}" --threads 1 > /dev/null
: > "$WORK/fvr_one.txt"
for ((r = 0; r < REPEATS; ++r)); do
    FVR_FFTW_WISDOM="$WISDOM" timed "$FVR" "$CT" "${FVR_ARGS[@]}" --threads 1 >> "$WORK/fvr_one.txt"
done

# 3. plastimatch: the same pixel size at the axis, the same detector size, near-parallel rays.
SAD=100000
SID=100500
DET=$(awk -v p="$PIXEL" -v n="$SIZE" -v a="$SAD" -v i="$SID" 'BEGIN {printf "%.4f", p * n * i / a}')
STEP=$(awk -v n="$PLM_VIEWS" 'BEGIN {printf "%.6g", 360 / n}')
PLM_CMD=(plastimatch drr -A cpu -i exact -r "$SIZE $SIZE" -z "$DET $DET" --sad "$SAD" --sid "$SID"
    -o "$ISO_X $ISO_Y $ISO_Z" -a "$PLM_VIEWS" -N "$STEP" -t pfm -O "$WORK/plm/view_" "$WORK/ct.mha")
: > "$WORK/plm.txt"
: > "$WORK/plm_render.txt"
for ((r = 0; r < REPEATS; ++r)); do
    timed "${PLM_CMD[@]}" >> "$WORK/plm.txt"
    awk '/^Total time:/ {print $3}' "$WORK/last.log" >> "$WORK/plm_render.txt"
done
# plastimatch on one thread: on a busy machine it can beat its own OpenMP default.
: > "$WORK/plm_one.txt"
for ((r = 0; r < REPEATS; ++r)); do
    OMP_NUM_THREADS=1 timed "${PLM_CMD[@]}" >> "$WORK/plm_one.txt"
done

# 4. The table: for each series of runs the median and (in brackets) the best wall time; the
#    machine is shared, so the best is often the better estimate of what the code can do.
stats() { # file of "wall user sys" lines -> "median best cpu_use_of_the_median_run all_walls"
    local m
    m=$(awk '{print $1}' "$1" | median)
    awk -v m="$m" '{a = a s $1; s = ", "; if (NR == 1 || $1 < b) b = $1}
        $1 == m && !c {c = sprintf("%.2f", ($2 + $3) / ($1 > 0 ? $1 : 1))}
        END {print m, b, c, a}' "$1"
}
per() { awk -v t="$1" -v n="$2" 'BEGIN {printf "%.1f", 1000 * t / n}'; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN {printf "%.1f", a / b}'; }
read -r PLM PLM_B _ _ < <(stats "$WORK/plm.txt")
read -r PLM1 PLM1_B _ _ < <(stats "$WORK/plm_one.txt")
awk '{print $1, 0, 0}' "$WORK/plm_render.txt" > "$WORK/plm_render3.txt"
read -r PLMR PLMR_B _ _ < <(stats "$WORK/plm_render3.txt")
# The reference: plastimatch's faster setting (default threads or one thread) in this run.
lesser() { awk -v a="$1" -v b="$2" 'BEGIN {print (a < b ? a : b)}'; }
PLM_V=$(per "$(lesser "$PLM" "$PLM1")" "$PLM_VIEWS")
PLM_VB=$(per "$(lesser "$PLM_B" "$PLM1_B")" "$PLM_VIEWS")
# row LABEL FILE VIEWS [REFERENCE_MEDIAN_MS REFERENCE_BEST_MS]: one table row; sets ROW_M, ROW_B.
row() {
    local m b c all vm vb r=""
    read -r m b c all < <(stats "$2")
    vm=$(per "$m" "$3")
    vb=$(per "$b" "$3")
    [[ $# -ge 5 ]] && r="$(ratio "$4" "$vm") ($(ratio "$5" "$vb"))"
    echo "| $1 | $3 | $m ($b) | $vm ($vb) | $c | $r |"
    ALL_RUNS+=("$1: $all s")
    ROW_M=$m
    ROW_B=$b
}
ALL_RUNS=()
FVR_CMD="FVR_FFTW_WISDOM=W $(basename "$FVR") CT ${FVR_ARGS[*]}"
FVR_CMD=${FVR_CMD//$WORK\//}
PLM_TEXT=$(for a in "${PLM_CMD[@]}"; do [[ $a == *" "* ]] && printf '"%s" ' "$a" || printf '%s ' "$a"; done)
PLM_TEXT=${PLM_TEXT% }
PLM_TEXT=${PLM_TEXT//$WORK\//}

echo "### DRR batch: fvr-render against plastimatch (CT $(basename "$CT"), ${SIZE}x${SIZE})"
echo
echo "Machine: $(nproc) cores, $CPU_MODEL, load average at start $LOAD_AT_START, CPU pressure" \
    "(PSI some avg10) at start $PRESSURE_AT_START and at the end $(cpu_pressure). Pixel" \
    "${PIXEL} mm at the axis. Times: median (best) of $REPEATS runs; CPU use: (user + sys) /" \
    "wall of the median run."
echo
echo "| run | views | whole job (s) | per view (ms) | CPU use | plastimatch per view / this |"
echo "|---|---:|---:|---:|---:|---:|"
row "plastimatch drr -i exact (load, render, write)" "$WORK/plm.txt" "$PLM_VIEWS" "$PLM_V" "$PLM_VB"
row "plastimatch, OMP_NUM_THREADS=1" "$WORK/plm_one.txt" "$PLM_VIEWS" "$PLM_V" "$PLM_VB"
row "fvr-render warm (wisdom from the run before)" "$WORK/fvr_warm.txt" "$SWEEP" "$PLM_V" "$PLM_VB"
WARM=$ROW_M
WARM_B=$ROW_B
row "fvr-render first run, no FFTW wisdom" "$WORK/fvr_cold.txt" "$SWEEP" "$PLM_V" "$PLM_VB"
COLD=$ROW_M
COLD_B=$ROW_B
row "fvr-render warm, --threads 1" "$WORK/fvr_one.txt" "$SWEEP" "$(per "$PLM1" "$PLM_VIEWS")" \
    "$(per "$PLM1_B" "$PLM_VIEWS")"
echo
echo "Ratios: against plastimatch's faster setting in this run (per statistic: median with" \
    "median, best with best); the last row against plastimatch OMP_NUM_THREADS=1 (one thread each)."
echo "First run / warm run: $(ratio "$COLD" "$WARM") ($(ratio "$COLD_B" "$WARM_B") from the best)." \
    "plastimatch's own \"Total time\" (render and write, no load): $(per "$PLMR" "$PLM_VIEWS")" \
    "($(per "$PLMR_B" "$PLM_VIEWS")) ms per view; warm fvr-render is" \
    "$(ratio "$(per "$PLMR" "$PLM_VIEWS")" "$(per "$WARM" "$SWEEP")")" \
    "($(ratio "$(per "$PLMR_B" "$PLM_VIEWS")" "$(per "$WARM_B" "$SWEEP")")) times faster per view than that." \
    "fvr-render threads: $FVR_THREADS; plastimatch: OpenMP, OMP_NUM_THREADS=${OMP_NUM_THREADS:-unset (all cores)}."
echo
echo "All runs (s): $(printf '%s; ' "${ALL_RUNS[@]}")"
echo
echo "- plastimatch: \`$PLM_TEXT\` (ct.mha from \`plastimatch convert --input CT --output-img" \
    "ct.mha\`, not timed; -o is the volume centre)"
echo "- fvr-render: \`$FVR_CMD\` (W: the wisdom file, deleted before each first run)"

# 5. Do both draw the same radiograph? Plastimatch's first view and the one a quarter turn
#    later, each against every fvr-render view, flipped either way; the best normalised
#    correlation, not a claim of equality.
"$PY" - "$WORK/fvr.npy" "$WORK/plm" "$PLM_VIEWS" << 'EOF'
import sys
import numpy as np

stack = np.load(sys.argv[1], mmap_mode="r")
n = int(sys.argv[3])


def read_pfm(path):
    with open(path, "rb") as f:
        f.readline()
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        a = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4").reshape(h, w)
    return a[::-1].astype(np.float64)  # PFM rows run bottom to top


def normalise(a):
    a = a - a.mean()
    return a / (np.linalg.norm(a) or 1.0)


flat = stack.reshape(stack.shape[0], -1).astype(np.float64)
flat -= flat.mean(axis=1, keepdims=True)
flat /= np.maximum(np.linalg.norm(flat, axis=1, keepdims=True), 1e-30)
print()
print("| plastimatch view (gantry deg) | best fvr-render view | flip | correlation | scale (plastimatch / fvr) |")
print("|---|---:|---|---:|---:|")
for k in sorted({0, n // 4}):
    p = read_pfm("%s/view_%04d.pfm" % (sys.argv[2], k))
    best = (-2.0, 0, "none", p)
    for name, q in (("none", p), ("left-right", p[:, ::-1]), ("up-down", p[::-1]),
                    ("both", p[::-1, ::-1])):
        c = flat @ normalise(q).ravel()
        i = int(np.argmax(c))
        if c[i] > best[0]:
            best = (float(c[i]), i, name, q)
    c, i, name, q = best
    f = np.asarray(stack[i], dtype=np.float64)
    scale = float((q * f).sum() / max((f * f).sum(), 1e-30))
    print("| %d (%.4g) | %d | %s | %.4f | %.4g |" % (k, 360.0 * k / n, i, name, c, scale))
print()
print("Shapes: fvr-render stack %s, plastimatch view %s." % (stack.shape, p.shape))
EOF
