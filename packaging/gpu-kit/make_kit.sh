#!/usr/bin/env bash
# Assembles the hardware bench kit from a built tree (make gpu-kit):
#   OUT/fvr-gpu-kit/{bin,lib,share,licenses,run.sh,README.txt,MANIFEST.txt}  ->  TARBALL
#   (default OUT/fvr-gpu-kit.tar.gz)
# bin/: fvr-render, fvr_bench_gpu, fvr_compare_npy, fvr_table1_md (stripped; DT_RPATH
# $ORIGIN/../lib, set at link time: app/ and bench/CMakeLists.txt). lib/: every shared library
# they load (ldd) except what the GPU machine's own system and driver must provide: glibc
# and the OpenGL/EGL stack (libglvnd, Mesa), which the NVIDIA driver supplies. Fails when a
# library is missing, when a kit program would load a library from outside the kit, or when the
# tarball exceeds the size limit.
set -euo pipefail
trap 'echo "make_kit.sh:$LINENO: failed (status $?): $BASH_COMMAND" >&2' ERR
build=${1:?usage: make_kit.sh BUILD_DIR [OUT_DIR [TARBALL]]}
out=$(realpath -m "${2:-$build/gpu-kit}")
tarball=$(realpath -m "${3:-$out/fvr-gpu-kit.tar.gz}")
limit_bytes=${FVR_KIT_LIMIT_BYTES:-48000000} # 48 MB
here=$(cd "$(dirname "$0")" && pwd)
programs=(app/fvr-render bench/fvr_bench_gpu bench/fvr_compare_npy bench/fvr_table1_md bench/fvr_register_eval)
# Sonames the host provides: glibc, the dynamic loader, libglvnd's GL/EGL and Mesa's drivers.
# (libnsl.so.2, which DCMTK's network library needs, is libnsl2, not glibc: it travels.)
excluded='^(ld-linux.*|libc|libm|libmvec|libpthread|libdl|librt|libresolv|libutil|libanl|libBrokenLocale|libcrypt|libEGL.*|libGL.*|libGLX.*|libGLdispatch|libOpenGL|libgbm|libglapi|libdrm.*|libgallium.*|libvulkan|libLLVM.*|libnvidia.*|libcuda)\.so'

fail() { echo "make_kit: $*" >&2; exit 1; }

for p in "${programs[@]}"; do
  [ -x "$build/$p" ] || fail "$build/$p is missing (build with -DFVR_BUILD_BENCH=ON and the GPU renderer)"
done
build_type=$(sed -n 's/^CMAKE_BUILD_TYPE:[A-Z]*=//p' "$build/CMakeCache.txt")
[ "$build_type" = Release ] || echo "make_kit: warning: $build is a '$build_type' build, not Release" >&2

kit=$out/fvr-gpu-kit
rm -rf "$kit" "$tarball"
mkdir -p "$kit/bin" "$kit/lib" "$kit/share" "$kit/licenses"

# The libraries the programs load, resolved on this machine (LD_LIBRARY_PATH unset).
declare -A libs=()
for p in "${programs[@]}"; do
  cp "$build/$p" "$kit/bin/"
  strip --strip-unneeded "$kit/bin/$(basename "$p")"
  cmake -DFILE="$kit/bin/$(basename "$p")" -P "$here/set_rpath.cmake" > /dev/null
  dynamic=$(readelf -d "$kit/bin/$(basename "$p")")
  grep -qF '(RPATH)              Library rpath: [$ORIGIN/../lib]' <<<"$dynamic" ||
    fail "$p: no DT_RPATH \$ORIGIN/../lib (app/ and bench/CMakeLists.txt link it)"
  while read -r name arrow path _; do
    [ "$arrow" = "=>" ] || continue
    [ "$path" = "not" ] && fail "$p needs $name, which is not found on this machine"
    [[ $name =~ $excluded ]] && continue
    libs[$name]=$path
  done < <(env -u LD_LIBRARY_PATH ldd "$build/$p")
done
for name in "${!libs[@]}"; do
  cp -L "${libs[$name]}" "$kit/lib/$name"
  chmod 644 "$kit/lib/$name"
done
# DCMTK's data dictionary: the library reads it from /usr/share/libdcmtkNN at run time, which a
# bare machine lacks (without it no DICOM file decodes); run.sh points DCMDICTPATH here.
dictionary=$(ls /usr/share/libdcmtk*/dicom.dic 2> /dev/null | head -1)
[ -n "$dictionary" ] || fail "DCMTK's dicom.dic is missing (Debian package libdcmtk17)"
cp "$dictionary" "$kit/share/dicom.dic"
cp "$here/run.sh" "$here/README.txt" "$kit/"
chmod 755 "$kit/run.sh"

# Every library a kit program loads is the kit's own or one the host provides.
for p in "$kit"/bin/*; do
  while read -r name arrow path _; do
    [ "$arrow" = "=>" ] || continue
    [[ $name =~ $excluded ]] && continue
    [ "$(readlink -f "$path")" = "$kit/lib/$name" ] || fail "$(basename "$p") loads $name from $path, not from the kit"
  done < <(env -u LD_LIBRARY_PATH ldd "$p")
done

bash "$here/manifest.sh" "$build" "$kit" > "$kit/MANIFEST.txt"
tar -C "$out" -czf "$tarball" fvr-gpu-kit
size=$(stat -c %s "$tarball")
echo "gpu-kit: $tarball: $size bytes ($((size / 1000000)) MB; limit $((limit_bytes / 1000000)) MB)," \
  "${#libs[@]} libraries"
[ "$size" -le "$limit_bytes" ] || fail "the kit is $size bytes, over the limit of $limit_bytes"
