#!/usr/bin/env bash
# Installs the Debian 12 packages theia builds and tests with (skipped when present).
set -euo pipefail
packages=(
  build-essential cmake pkg-config
  libembree-dev libtbb-dev libopenimageio-dev openimageio-tools libopenexr-dev libpng-dev libstb-dev libglm-dev
  libgtest-dev libcli11-dev libfmt-dev nlohmann-json3-dev libboost-dev libnanoflann-dev
  libjemalloc-dev  # the theia executable's malloc: the heap on huge pages (app/main.cpp)
  libnanovdb-dev zlib1g-dev  # the "nanovdb" medium's reader (header-only NanoVDB, zip-compressed grids)
  python3-numpy python3-matplotlib python3-openimageio
  slurm-wlm munge
  clang  # fuzz/: libFuzzer ships with it (THEIA_FUZZ builds)
  libjs-three  # `theia field view` copies three.js into the page it writes
  chromium python3-websocket python3-pil  # the field viewer's browser test (tests/tools/test_field_view.py)
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then exit 0; fi
echo "installing: ${missing[*]}"
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO=sudo
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
