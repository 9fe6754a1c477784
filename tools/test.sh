#!/usr/bin/env bash
# Installs the dependencies, builds epiloc and runs the whole test suite (CTest).
# Real-data tests use ../shared/data next to the repository and skip when it is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)"
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 900
