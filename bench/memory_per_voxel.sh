#!/usr/bin/env bash
# Peak memory per input voxel of one fvr-render job: a built-in N^3 phantom rendered
# to one SIZE x SIZE view, for each oversampling, transform and kernel; prints a Markdown table.
#
# Usage: bench/memory_per_voxel.sh [FVR_RENDER] [N]
#   FVR_RENDER     default build/app/fvr-render
#   N              phantom size, default 512 (512^3 voxels: 0.5 GiB as float32)
#   env PHANTOMS       default "shepp-logan chest"
#   env OVERSAMPLINGS  default "1 1.25 2"
#   env TRANSFORMS     default "fft fht"
#   env KERNELS        default "linear kaiser-bessel" (linear: fvr-render's default, no
#                      deapodization; kaiser-bessel: width 4, deapodized, the workstation default)
#   env SIZE           image size, default 512
#   env EXTRA          more fvr-render options for every run (e.g. "--backend cpu": no GPU probe)
# Peak RSS from /usr/bin/time (%M); the spectrum size and padded size from the JSON sidecar.
# "Data" is what the job cannot do without: the float32 volume (4 bytes a voxel) and the padded
# spectrum, both alive while the 3D transform runs. The wall time includes FFTW's planning where
# the wisdom file (FVR_FFTW_WISDOM or the default) lacks the size: a memory table, not a timing one.
# Not a ctest test (minutes at N = 512).
set -euo pipefail
trap 'echo "memory_per_voxel.sh: line $LINENO failed: $BASH_COMMAND" >&2' ERR

FVR=${1:-build/app/fvr-render}
N=${2:-512}
PHANTOMS=${PHANTOMS:-shepp-logan chest}
OVERSAMPLINGS=${OVERSAMPLINGS:-1 1.25 2}
TRANSFORMS=${TRANSFORMS:-fft fht}
KERNELS=${KERNELS:-linear kaiser-bessel}
SIZE=${SIZE:-512}
read -r -a EXTRA_ARGS <<< "${EXTRA:-}"
command -v /usr/bin/time > /dev/null || { echo "memory_per_voxel.sh: needs /usr/bin/time" >&2; exit 2; }
[[ -x $FVR ]] || { echo "memory_per_voxel.sh: $FVR: not an executable" >&2; exit 2; }
WORK=$(mktemp -d /tmp/memory-bench.XXXXXX)
trap 'rm -rf "$WORK"' EXIT

# Runs fvr-render with ARGS; prints "wall_s peak_kb".
measure() {
    if ! /usr/bin/time -f "%e %M" -o "$WORK/time.txt" "$FVR" "$@" "${EXTRA_ARGS[@]}" > "$WORK/log.txt" 2>&1; then
        echo "memory_per_voxel.sh: failed: $FVR $*" >&2
        tail -5 "$WORK/log.txt" >&2
        echo "failed failed"
        return 0
    fi
    tail -1 "$WORK/time.txt"
}
per_voxel() { awk -v k="$1" -v v="$VOXELS" 'BEGIN {printf "%.2f", 1024 * k / v}'; }
mb() { awk -v b="$1" 'BEGIN {printf "%.0f", b / 1048576}'; }

VOXELS=$((N * N * N))
VOLUME_BYTES=$((4 * VOXELS))
echo "### Peak memory per input voxel: fvr-render phantom:P:$N --size $SIZE, one view"
echo
echo "Machine: $(nproc) cores, $(awk '/^MemTotal/ {printf "%.1f GiB", $2 / 1048576}' /proc/meminfo);" \
    "$N^3 = $VOXELS voxels, volume $(mb "$VOLUME_BYTES") MiB as float32."
echo
echo "| phantom | oversampling | transform | kernel | padded | spectrum (MiB) | data: volume + spectrum (MiB) | peak RSS (MiB) | peak / data | bytes per voxel | above the fixed cost | wall (s) |"
echo "|---|---:|---|---|---|---:|---:|---:|---:|---:|---:|---:|"
# The fixed cost of a run: an 8^3 phantom (the program, its libraries, the GPU probe of the
# default backend: --backend cpu skips it).
read -r wall kb < <(measure phantom:shepp-logan:8 --size "$SIZE" --out "$WORK/t.npy")
FIXED_KB=$kb
read -r _ FIXED_INFO_KB < <(measure phantom:shepp-logan:8 --info) # --info: no renderer, no probe
echo "| fixed cost (phantom:shepp-logan:8, ${SIZE}^2 view) | | | | | | | $((kb / 1024)) | | | | $wall |"
for phantom in $PHANTOMS; do
    # The phantom alone (--info: build it, print its facts): the floor before any spectrum.
    read -r wall kb < <(measure "phantom:$phantom:$N" --info)
    if [[ $kb != failed ]]; then
        echo "| $phantom (--info: the volume alone) | | | | | | $(mb "$VOLUME_BYTES") | $((kb / 1024)) |" \
            "$(awk -v k="$kb" -v d="$VOLUME_BYTES" 'BEGIN {printf "%.2f", 1024 * k / d}') |" \
            "$(per_voxel "$kb") | $(per_voxel $((kb - FIXED_INFO_KB))) | $wall |"
    fi
    for f in $OVERSAMPLINGS; do
        for t in $TRANSFORMS; do
            for k in $KERNELS; do
                rm -f "$WORK/m.npy.json"
                read -r wall kb < <(measure "phantom:$phantom:$N" --size "$SIZE" --oversampling "$f" \
                    --transform "$t" --kernel "$k" --out "$WORK/m.npy")
                if [[ $kb == failed ]]; then
                    echo "| $phantom | $f | $t | $k | failed: $(tail -1 "$WORK/log.txt" | tr '|' '/') | | | | | | |"
                    continue
                fi
                read -r padded spectrum_b deap < <(/usr/bin/python3 -c '
import json, sys
s = json.load(open(sys.argv[1]))["settings"]
print("x".join(map(str, s["padded_dims"])), int(round(s["spectrum_mb"] * 1048576)),
      "deapodized" if s["deapodized"] else "plain")' "$WORK/m.npy.json")
                data=$((VOLUME_BYTES + spectrum_b))
                echo "| $phantom | $f | $t | $k ($deap) | $padded | $(mb "$spectrum_b") | $(mb "$data") |" \
                    "$((kb / 1024)) | $(awk -v k="$kb" -v d="$data" 'BEGIN {printf "%.2f", 1024 * k / d}') |" \
                    "$(per_voxel "$kb") | $(per_voxel $((kb - FIXED_KB))) | $wall |"
            done
        done
    done
done
echo
echo "Command: \`/usr/bin/time -f \"%e s %M KB\" $FVR phantom:P:$N --size $SIZE --oversampling F" \
    "--transform T --kernel K --out m.npy ${EXTRA:-}\`; bytes per voxel = peak RSS / $N^3;" \
    "above the fixed cost: (peak RSS - the same run's on an 8^3 phantom) / $N^3."
