#!/usr/bin/env bash
# Benchmark of `epiloc build-db` on the shared KITTI drive (camera 0, all frames, full
# resolution): frames/s, peak memory and database bytes per frame. Prints figures; not a test.
#   bash tools/bench_build_db.sh [BUILD_DIR] [THREADS]
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
"$epiloc" import-kitti --raw "$raw" --camera 0 --out "$work/drive" --quiet
/usr/bin/time -f "%e %M %U %S" -o "$work/time" \
  "$epiloc" build-db --drive "$work/drive" --db "$work/route.sqlite" --threads "$threads" --quiet \
  > "$work/out"
read -r wall_s rss_kb user_s sys_s < "$work/time"
frames=$(sqlite3 "$work/route.sqlite" "SELECT COUNT(*) FROM frames")
features=$(sqlite3 "$work/route.sqlite" "SELECT SUM(num_features) FROM frames")
sqlite3 "$work/route.sqlite" "PRAGMA wal_checkpoint(TRUNCATE);" > /dev/null
bytes=$(stat -c %s "$work/route.sqlite")
echo "build-db benchmark: KITTI 2011_09_26_drive_0005 camera 0, 1242x375, $(nproc) cores, threads=$threads"
awk -v f="$frames" -v w="$wall_s" -v r="$rss_kb" -v u="$user_s" -v s="$sys_s" -v b="$bytes" -v n="$features" 'BEGIN {
  printf "  frames            %d (%.0f features/frame)\n", f, n / f
  printf "  wall time         %.2f s  (%.2f frames/s, CPU %.2f s = %.1f cores busy)\n", w, f / w, u + s, (u + s) / w
  printf "  peak memory       %.1f MB\n", r / 1024
  printf "  database          %.1f MB, %.1f kB per frame\n", b / 1e6, b / 1e3 / f
}'
