#!/usr/bin/env bash
# Benchmark of `epiloc localize` on the development scenario of the shared KITTI drive: survey =
# camera 0 frames 0:154:2, query = camera 1 frames 1:154:2 (1242x375) with 3 m GPS noise.
# Prints frames/s per mode, peak memory and the along-track accuracy. Not a test.
#   bash tools/bench_localize.sh [BUILD_DIR] [THREADS]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
threads=${2:-0}
epiloc=$build/tools/epiloc
raw=../shared/data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync
[[ -x $epiloc ]] || { echo "bench: build first ($epiloc missing)" >&2; exit 1; }
[[ -d $raw ]] || { echo "bench: $raw not found" >&2; exit 1; }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$epiloc" import-kitti --raw "$raw" --camera 0 --frames 0:154:2 --out "$work/survey" --quiet
"$epiloc" import-kitti --raw "$raw" --camera 1 --frames 1:154:2 --gps-noise 3 --seed 1 \
  --out "$work/query" --quiet
"$epiloc" build-db --drive "$work/survey" --db "$work/route.sqlite" --quiet > /dev/null
echo "localize benchmark: KITTI 2011_09_26_drive_0005, query camera 1 (77 frames, 1242x375), $(nproc) cores, threads=$threads"
for mode in online free fixed; do
  /usr/bin/time -f "%e %M %U %S" -o "$work/time" \
    "$epiloc" localize --db "$work/route.sqlite" --drive "$work/query" --mode "$mode" \
    --threads "$threads" --out "$work/$mode.csv" --quiet > /dev/null
  read -r wall_s rss_kb user_s sys_s < "$work/time"
  # Along-track mean of each method in the file ("online 0.105 pnp 0.049").
  mean=$("$epiloc" evaluate --result "$work/$mode.csv" --truth "$work/query" \
    --route "$work/route.sqlite" --no-gnss 2>/dev/null | awk '
      NR == 2 { for (i = 1; i <= NF; ++i) name[i] = $i; n = NF }
      /^Mean\|e\|/ { for (i = 2; i <= NF; ++i) printf "%s%s %s", (i > 2 ? ", " : ""), name[i - 1], $i; exit }')
  awk -v m="$mode" -v w="$wall_s" -v r="$rss_kb" -v u="$user_s" -v s="$sys_s" -v e="$mean" 'BEGIN {
    printf "  %-7s %6.2f frames/s  (%.1f s wall, %.1f cores busy)  peak memory %6.1f MB  along-track mean [m] %s\n",
      m, 77 / w, w, (u + s) / w, r / 1024, e }'
done
