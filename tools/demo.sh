#!/usr/bin/env bash
# The main job on the embedded default: installs what is missing, builds, generates a synthetic
# street (survey + query drives with exact ground truth), builds the route database from the
# survey, localizes the query drive with every method, and evaluates it against the ground truth
# (table on stdout, HTML report). Output in demo/ (or the folder given as $1).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-demo}
bash tools/install_deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)" --target epiloc
epiloc=build/tools/epiloc

mkdir -p "$out"
rm -rf "$out/world" "$out"/route.sqlite*
"$epiloc" synth --out "$out/world" --length-m 100 --query-rate-hz 5 --no-lidar
"$epiloc" build-db --drive "$out/world/survey" --db "$out/route.sqlite"
"$epiloc" info --db "$out/route.sqlite"
"$epiloc" localize --db "$out/route.sqlite" --drive "$out/world/query" --all-methods \
  --out "$out/result.csv" --geojson "$out/result.geojson"
"$epiloc" evaluate --result "$out/result.csv" --truth "$out/world/query" \
  --route "$out/route.sqlite" --report "$out/report.html" --json "$out/summary.json"
echo "demo: outputs in $out/ (report.html: error table and plots; world/top_view.png: the street)"
