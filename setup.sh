#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a rendered image:
# installs the Debian packages, builds theia (Release) and renders the demo
# scene to out/cornell-box.exr, .png and .json.
set -euo pipefail
cd "$(dirname "$0")"
./tools/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release ${THEIA_CMAKE_ARGS:-}
cmake --build build -j"$(nproc)"
mkdir -p out
./build/theia render scenes/cornell-box/scene.pbrt -o out/cornell-box.exr "$@"
echo "demo rendered: out/cornell-box.exr, out/cornell-box.png, out/cornell-box.json"
