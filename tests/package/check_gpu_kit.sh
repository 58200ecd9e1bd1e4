#!/usr/bin/env bash
# The hardware bench kit (make gpu-kit) from a built tree: assembles it, unpacks the tarball in an
# empty directory and checks what it holds (no glibc, no GL/EGL stack, every other library from
# the kit's lib/ with LD_LIBRARY_PATH unset, size <= 48 MB), then runs ./run.sh --quick there
# headless (EGL: Mesa surfaceless llvmpipe where no GPU) and checks its results: the files, the
# Table 1 rows, GPU = CPU >= 140 dB.
set -euo pipefail
trap 'echo "check_gpu_kit.sh:$LINENO: failed (status $?): $BASH_COMMAND" >&2' ERR
build=$(realpath "${1:?usage: check_gpu_kit.sh BUILD_DIR}")
src=$(cd "$(dirname "$0")/../.." && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0
bad() { echo "FAIL: $*"; fail=1; }

bash "$src/packaging/gpu-kit/make_kit.sh" "$build" "$tmp/assemble" "$tmp/fvr-gpu-kit.tar.gz"
size=$(stat -c %s "$tmp/fvr-gpu-kit.tar.gz")
[ "$size" -le 48000000 ] || bad "the tarball is $size bytes, over 48 MB"
mkdir "$tmp/unpacked"
tar -C "$tmp/unpacked" -xzf "$tmp/fvr-gpu-kit.tar.gz"
kit=$tmp/unpacked/fvr-gpu-kit
for f in run.sh README.txt MANIFEST.txt bin/fvr-render bin/fvr_bench_gpu bin/fvr_compare_npy \
         bin/fvr_table1_md bin/fvr_register_eval share/dicom.dic lib/libfftw3f.so.3 \
         lib/libdcmdata.so.17 lib/libepoxy.so.0; do
  [ -e "$kit/$f" ] || bad "the kit lacks $f"
done

# What the host provides never travels with the kit; the rest comes from the kit's lib/.
host='^(linux-vdso|ld-linux-x86-64|libc|libm|libdl|libpthread|librt|libresolv|libEGL|libGL|libGLX|libGLdispatch|libOpenGL)\.so'
for f in "$kit"/lib/*; do
  n=$(basename "$f")
  [[ $n =~ $host || $n =~ ^lib(gbm|glapi|drm|EGL_mesa|GLX_mesa|gallium) ]] && bad "lib/ holds $n"
done
for p in "$kit"/bin/*; do
  dynamic=$(readelf -d "$p")
  grep -qF "Library rpath: [\$ORIGIN/../lib]" <<<"$dynamic" || bad "$(basename "$p"): RPATH is not \$ORIGIN/../lib"
  while read -r name arrow path _; do
    [[ $name =~ $host ]] && continue
    [ "$arrow" = "=>" ] || continue
    [ "$(readlink -f "$path")" = "$kit/lib/$name" ] || bad "$(basename "$p") loads $name from $path"
  done < <(env -u LD_LIBRARY_PATH ldd "$p")
done

# The comparison tool against its oracle: an image against itself is 300 dB (identical); two
# different shapes are an error.
(cd "$kit" && ./bin/fvr-render phantom:shepp-logan:32 --size 128 --backend cpu --out "$tmp/a.npy" \
  && ./bin/fvr-render phantom:shepp-logan:32 --size 256 --backend cpu --out "$tmp/b.npy") > /dev/null
same=$("$kit/bin/fvr_compare_npy" "$tmp/a.npy" "$tmp/a.npy")
grep -q '"psnr":300' <<<"$same" || bad "an image against itself: $same"
if "$kit/bin/fvr_compare_npy" "$tmp/a.npy" "$tmp/b.npy" 2> /dev/null; then bad "128² vs 256² compared"; fi

# DICOM decodes with the kit's own data dictionary alone (a bare machine has no other): a file
# the kit wrote, JPEG Lossless compressed (decoding it needs the dictionary; without one it fails),
# reads back with DCMDICTPATH naming the kit's copy (DCMTK then reads no other).
(cd "$kit" && ./bin/fvr-render phantom:shepp-logan:32 --size 64 --backend cpu --out "$tmp/d.dcm") > /dev/null
dcmcjpeg +e1 "$tmp/d.dcm" "$tmp/j.dcm"
if DCMDICTPATH=/nonexistent "$kit/bin/fvr-render" "$tmp/j.dcm" --info > /dev/null 2>&1; then
  bad "a JPEG DICOM decoded without any dictionary: the dictionary check below proves nothing"
fi
DCMDICTPATH=$kit/share/dicom.dic "$kit/bin/fvr-render" "$tmp/j.dcm" --info > /dev/null 2> "$tmp/j.err" ||
  bad "a JPEG DICOM with the kit's dictionary: $(cat "$tmp/j.err")"

# The quick run, from an unrelated working directory, with no display.
mkdir "$tmp/cwd"
(cd "$tmp/cwd" && env -u DISPLAY -u FVR_EGL_DEVICE -u LD_LIBRARY_PATH "$kit/run.sh" --quick) ||
  bad "run.sh --quick failed (exit status $?)"
r=$kit/results
for f in gpu-info.json table1.json table1.md cone.json correctness.json correctness.md; do
  [ -s "$r/$f" ] || bad "results/$f is missing or empty"
done
grep -q '"available": true' "$r/gpu-info.json" || bad "gpu-info: no OpenGL context"
runs=$(grep -c '"name": "BM_Gpu' "$r/table1.json" || true)
[ "$runs" -eq 8 ] || bad "table1.json holds $runs benchmarks, expected 8 (Stages, Frame x fft, fht x nearest, linear)"
for s in "## FFT, N = 128" "## FHT, N = 128" "| 256×256 |"; do
  grep -qF "$s" "$r/table1.md" || bad "table1.md lacks '$s'"
done
cones=$(grep -c '"name": "BM_ConeGpu/N256/256x256/box' "$r/cone.json" || true)
[ "$cones" -eq 1 ] || bad "cone.json holds $cones box runs at 256x256, expected 1"
# Google Benchmark writes counters as d.ddde+XX: a leading 0 is 0 views/s.
grep -q '"views_per_s": [1-9]' "$r/cone.json" || bad "cone.json: views_per_s is 0 or missing"
psnrs=$( (grep -o '"psnr":[0-9.e+-]*' "$r/correctness.json" || true) | cut -d: -f2)
[ "$(wc -w <<<"$psnrs")" -eq 2 ] || bad "correctness.json: expected 2 cases, found: $psnrs"
for p in $psnrs; do
  echo "GPU = CPU: $p dB"
  # Stricter than run.sh's 90 dB: here the GPU is llvmpipe, which rounds as the CPU does.
  awk -v p="$p" 'BEGIN { exit !(p >= 140) }' || bad "GPU = CPU PSNR $p dB < 140"
done
grep -q '"all_passed":true' "$r/correctness.json" || bad "correctness.json: not all passed"
[ $fail = 0 ] && echo "gpu kit: $size bytes, $(ls "$kit/lib" | wc -l) libraries, quick run passed"
exit $fail
