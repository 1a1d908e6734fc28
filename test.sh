#!/usr/bin/env bash
# One command that runs the whole test suite (what CI runs): installs the
# Debian packages if missing, builds with warnings as errors, runs CTest.
set -euo pipefail
cd "$(dirname "$0")"
./tools/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DTHEIA_WERROR=ON ${THEIA_CMAKE_ARGS:-}
cmake --build build -j"$(nproc)"
ctest --test-dir build --output-on-failure -j"$(nproc)" "$@"
