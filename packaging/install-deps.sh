#!/usr/bin/env bash
# Installs what a fresh Debian 12 machine lacks to build and run FVR Workstation; with --tests,
# also what only the tests need (make test): a real PACS (Orthanc; Debian starts its service,
# which the tests never use: `systemctl disable --now orthanc` if you do not want it), pytest,
# Dask and Zarr for the dataset tests, plastimatch (the cone-beam box model's oracle) and pydicom
# (its rtplan.dcm test file).
# Non-interactive and idempotent: packages already present are not touched, apt is not even
# called when nothing is missing. Uses sudo only when not running as root.
set -euo pipefail

packages=(
  build-essential dpkg-dev cmake pkg-config ninja-build python3
  libfftw3-dev zlib1g-dev libcli11-dev nlohmann-json3-dev libglm-dev
  libdcmtk-dev libopenjp2-7-dev
  libxrl-dev libnlopt-dev
  libavcodec-dev libavformat-dev libswscale-dev # MP4 movies of a cine (FFmpeg)
  qt6-base-dev libqt6opengl6-dev libgl-dev libepoxy-dev libegl-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  clang libclang-rt-14-dev clang-format
  xvfb xauth libgl1-mesa-dri libegl-mesa0
  pybind11-dev python3-dev python3-numpy
)
if [ "${1:-}" = "--tests" ]; then
  packages+=(
    orthanc # the real PACS the pacs tests start on their own ports (its service is not used)
    dcmtk # storescu/echoscu: the pacs tests' other peers of our storage listener
    dicom3tools # dciodvfy: checks the X-ray DICOM objects we write against their IOD
    openssl # the DICOM TLS tests make their CA and certificates with it
    python3-pytest python3-distributed python3-zarr
    python3-hypothesis # the dataset manifest fuzz (tests/fuzz/fuzz_manifest.py)
    plastimatch # `plastimatch drr -i exact`: the oracle of the cone-beam box model's tests
    python3-pydicom # its test file rtplan.dcm: a real RT Plan for the RT Plan reader's test
  )
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "install-deps: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then
    SUDO="sudo"
  else
    echo "install-deps: missing packages (${missing[*]}) and not root, no sudo available" >&2
    exit 1
  fi
fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
