#!/usr/bin/env bash
# MANIFEST.txt of the hardware bench kit (make_kit.sh), on stdout: what was built from what, what
# the host must provide (glibc version, OpenGL/EGL driver), and the libraries in lib/ with their
# Debian packages, whose copyright files (the licences of what the kit redistributes) it copies
# into KIT_DIR/licenses.
set -euo pipefail
trap 'echo "manifest.sh:$LINENO: failed (status $?): $BASH_COMMAND" >&2' ERR
PATH=$PATH:/usr/sbin:/sbin # ldconfig, for users whose PATH lacks the sbin folders
build=${1:?usage: manifest.sh BUILD_DIR KIT_DIR}
kit=${2:?usage: manifest.sh BUILD_DIR KIT_DIR}
cache=$build/CMakeCache.txt
src=$(sed -n 's/^CMAKE_HOME_DIRECTORY:INTERNAL=//p' "$cache")
# git may refuse the checkout (another user's clone: "dubious ownership"): the commit is then
# unknown, never a failure.
commit=$(git -C "$src" rev-parse --short HEAD 2>/dev/null || echo unknown)
changes=$(git -C "$src" status --porcelain --untracked-files=no 2>/dev/null || true)
dirty=${changes:0:1}
versions=$(objdump -T "$kit"/bin/* "$kit"/lib/* 2>/dev/null || true)
glibc=$(grep -o 'GLIBC_[0-9][0-9.]*' <<<"$versions" | sort -uV | tail -n 1 || true)
os=$(. /etc/os-release && echo "$PRETTY_NAME")
echo "FVR Workstation GPU bench kit"
echo "built:        $(date -u +%Y-%m-%dT%H:%M:%SZ) on $os, $(uname -m)"
echo "source:       commit $commit${dirty:+ (with uncommitted changes)}"
echo "build type:   $(sed -n 's/^CMAKE_BUILD_TYPE:[A-Z]*=//p' "$cache")"
echo "compiler:     $(sed -n 's/^CMAKE_CXX_COMPILER:[A-Z]*=//p' "$cache") ($(c++ -dumpfullversion 2>/dev/null))"
echo "host needs:   glibc >= ${glibc#GLIBC_} (x86-64), an OpenGL 4.3 driver with EGL (libEGL.so.1, libglvnd)"
echo
echo "lib/ (the shared libraries the programs load, less glibc and the OpenGL/EGL stack):"
mkdir -p "$kit/licenses"
for f in "$kit"/lib/*; do
  name=$(basename "$f")
  # The file the soname resolves to here; dpkg knows it by its real name and multiarch folder
  # (in /lib or /usr/lib: /usr-merged).
  real=$(ldconfig -p | awk -v n="$name" '$1 == n { print $NF }' | head -n 1)
  pkg="" ver=""
  if [ -n "$real" ]; then
    file=$(readlink -f "$real")
    pattern="*/$(basename "$(dirname "$file")")/$(basename "$file")"
    pkg=$(dpkg-query -S "$pattern" 2>/dev/null | head -n 1 | cut -d: -f1 || true)
  fi
  if [ -n "$pkg" ]; then
    ver=$(dpkg-query -W -f='${Version}' "$pkg" 2>/dev/null || true)
    [ -f "/usr/share/doc/$pkg/copyright" ] && cp "/usr/share/doc/$pkg/copyright" "$kit/licenses/$pkg.copyright"
  fi
  printf '  %-26s %9s bytes  %s %s\n' "$name" "$(stat -c %s "$f")" "${pkg:-?}" "$ver"
done
