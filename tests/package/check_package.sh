#!/usr/bin/env bash
# Builds the Debian package from a configured and built tree and checks what it holds:
# the programs, the desktop entry, the icon, runtime dependencies, and a working fvr-render.
set -euo pipefail
build=${1:?usage: check_package.sh BUILD_DIR}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
(cd "$build" && cpack -G DEB -B "$out" > "$out/cpack.log" 2>&1) || { cat "$out/cpack.log"; exit 1; }
deb=$(ls "$out"/*.deb | head -n 1)
[ -f "$deb" ] || { echo "no .deb produced"; exit 1; }
echo "package: $(basename "$deb")"
files=$(dpkg-deb -c "$deb")
fail=0
for f in ./usr/bin/fvr-workstation ./usr/bin/fvr-render ./usr/share/applications/fvr-workstation.desktop \
         ./usr/share/icons/hicolor/scalable/apps/fvr-workstation.svg \
         ./usr/lib/python3/dist-packages/fvr/__init__.py ./usr/lib/python3/dist-packages/fvr/dataset.py \
         ./usr/lib/python3/dist-packages/fvr/__init__.pyi; do
  if grep -q " $f\$" <<<"$files"; then echo "contains $f"; else echo "MISSING $f"; fail=1; fi
done
depends=$(dpkg-deb -f "$deb" Depends)
echo "Depends: $depends"
for d in libfftw3 libdcmtk libqt6 python3-numpy libavcodec; do
  if grep -q "$d" <<<"$depends"; then echo "depends on $d"; else echo "MISSING dependency $d"; fail=1; fi
done
dpkg-deb -x "$deb" "$out/root"
if "$out/root/usr/bin/fvr-render" --help > /dev/null; then echo "fvr-render --help runs"; else echo "fvr-render --help failed"; fail=1; fi
# The Python module from the installed tree (Debian's python3, as the package depends on).
pkgs="$out/root/usr/lib/python3/dist-packages"
if ls "$pkgs"/fvr/_fvr.cpython-*.so > /dev/null 2>&1 && \
   PYTHONPATH="$pkgs" PYTHONDONTWRITEBYTECODE=1 /usr/bin/python3 -c '
import fvr, os
assert os.path.dirname(fvr.__file__) == os.path.join(os.environ["PYTHONPATH"], "fvr"), fvr.__file__
img = fvr.Renderer(fvr.load("phantom:shepp-logan:64"), values="mu").render(view="AP", size=128)
assert img.shape == (128, 128) and img.max() > 0'; then
  echo "import fvr from the installed tree renders"
else
  echo "import fvr from the installed tree failed"; fail=1
fi
exit $fail
