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

# Live input: the query drive recorded at 10 Hz while `localize --follow` reads it (each frame's
# image written, then its frames.csv row appended, with the GNSS samples up to its time).
# Latency = frame row available -> its rows written, as the localizer reports it.
cat > "$work/feed.py" <<'PY'
import json, os, sys, time
src, dst = sys.argv[1], sys.argv[2]
manifest = json.load(open(os.path.join(src, "drive.json")))
frames = open(os.path.join(src, "frames.csv")).read().splitlines()
gnss = open(os.path.join(src, "gnss.csv")).read().splitlines()
manifest.pop("ground_truth", None)
manifest.pop("lidar", None)
with open(os.path.join(dst, "frames.csv"), "w") as f:
    f.write(frames[0] + "\n")
with open(os.path.join(dst, "gnss.csv"), "w") as f:
    f.write(gnss[0] + "\n")
# The manifest last, whole (the follower waits for it and reads it at once).
with open(os.path.join(dst, "drive.json.tmp"), "w") as f:
    json.dump(manifest, f)
os.replace(os.path.join(dst, "drive.json.tmp"), os.path.join(dst, "drive.json"))
g = 1
start = time.monotonic()
for i, row in enumerate(frames[1:]):
    t = float(row.split(",")[1])
    with open(os.path.join(dst, "gnss.csv"), "a") as f:
        while g < len(gnss) and float(gnss[g].split(",")[0]) <= t:
            f.write(gnss[g] + "\n")
            g += 1
    with open(os.path.join(dst, "frames.csv"), "a") as f:
        f.write(row + "\n")
    time.sleep(max(0.0, start + 0.1 * (i + 1) - time.monotonic()))
PY
# Twice: every frame tracked, then late frames skipped (--max-latency-s 0.1: a frame one input
# period late while a newer one waits is skipped).
for max_latency in 0 0.1; do
  live="$work/live_$max_latency"
  mkdir -p "$live"
  python3 "$work/feed.py" "$work/query" "$live" &
  feeder=$!
  "$epiloc" localize --db "$work/route.sqlite" --drive "$live" --follow --idle-timeout-s 3 \
    --threads "$threads" --max-latency-s "$max_latency" --out "$work/live.csv" \
    > "$work/live.log" 2>&1
  feeder_status=0
  wait "$feeder" || feeder_status=$?
  latency=$(grep -oE 'latency p50 [0-9]+ ms, p95 [0-9]+ ms, max [0-9]+ ms' "$work/live.log" | head -1 ||
    true)
  if [[ -z $latency ]]; then
    # Say what the follow run and the feeder printed.
    echo "bench: the --follow run printed no latency (feeder exit $feeder_status); its log:" >&2
    tail -n 5 "$work/live.log" >&2
    latency="no latency"
  fi
  skipped=$(grep -oE '[0-9]+ late frames skipped' "$work/live.log" || echo "0 late frames skipped")
  echo "  follow  10 Hz input (77 frames written as recorded), --max-latency-s $max_latency:" \
    "$latency (target p95 <= 100 ms); $skipped"
done
