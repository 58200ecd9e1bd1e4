#!/usr/bin/env bash
# Runs every fuzz target one after the other for SECONDS each: the libFuzzer targets of the DICOM
# file reader and of the local store's C-STORE handling (run_fuzz.sh, clang + ASan/UBSan), then
# the dataset manifest reader (fuzz_manifest.py, hypothesis where installed). `make test-fuzz`
# runs it for 60 s each; ctest's `fuzz.smoke` for a few seconds each, so that every target keeps
# building and running. Exit status: 0 when no target found anything, 1 on a finding, 2 on a
# build or usage error, 77 when clang++/libFuzzer are missing (the manifest fuzz still runs).
#
#   tests/fuzz/run_all.sh [--build-dir DIR] [--time SECONDS] [--data SHARED_DATA_DIR]
#                         [--python PYTHON] [--pythonpath DIR]
set -uo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD="$ROOT/build-fuzz"
TIME=60
PYTHON=python3
PYPATH="$ROOT/build/python"
DATA="${FVR_SHARED_DATA_DIR:-$ROOT/../shared/data}"
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) BUILD="$2"; shift 2 ;;
    --time) TIME="$2"; shift 2 ;;
    --python) PYTHON="$2"; shift 2 ;;
    --pythonpath) PYPATH="$2"; shift 2 ;;
    --data) DATA="$2"; shift 2 ;;
    *) echo "usage: $0 [--build-dir DIR] [--time SECONDS] [--data DIR] [--python PYTHON] [--pythonpath DIR]" >&2
       exit 2 ;;
  esac
done

worst=0
skipped=0
note() { # the worst status wins: 1 (finding) over 2 (error) over 0; 77 counts as skipped
  case "$1" in
    0) ;;
    77) skipped=1 ;;
    1) worst=1 ;;
    *) [ "$worst" -eq 0 ] && worst=2 ;;
  esac
}
for target in fuzz_dicom_file fuzz_store_instance; do
  echo "== $target, $TIME s"
  bash "$ROOT/tests/fuzz/run_fuzz.sh" --target "$target" --build-dir "$BUILD" --time "$TIME" \
    --data "$DATA"
  note $?
done
echo "== dataset manifest, $TIME s"
PYTHONPATH="$PYPATH${PYTHONPATH:+:$PYTHONPATH}" PYTHONDONTWRITEBYTECODE=1 \
  "$PYTHON" "$ROOT/tests/fuzz/fuzz_manifest.py" --time "$TIME"
note $?
if [ "$worst" -eq 0 ] && [ "$skipped" -eq 1 ]; then exit 77; fi
exit "$worst"
