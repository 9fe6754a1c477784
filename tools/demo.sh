#!/usr/bin/env bash
# The main job on the embedded default: installs what is missing, builds, generates the synthetic
# street (survey + query drives, LiDAR map), builds the route database from the survey drive and
# summarises it. Output in demo/ (or the folder given as $1).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-demo}
bash tools/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)" --target epiloc
epiloc=build/tools/epiloc

mkdir -p "$out"
"$epiloc" synth --out "$out/world"
rm -f "$out/route.sqlite" "$out/route.sqlite-wal" "$out/route.sqlite-shm"
"$epiloc" build-db --drive "$out/world/survey" --db "$out/route.sqlite"
"$epiloc" info --db "$out/route.sqlite"
echo "demo: outputs in $out/ (world/top_view.png shows the street and both drives)"
