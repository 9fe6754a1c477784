#!/usr/bin/env bash
# Benchmark of `epiloc localize` against a long synthetic route: a database of 10,000 survey frames
# (8 km of synthetic street, 800x400 colour frames every 0.8 m) and a 300 m query drive at its
# start, with GPS and without (--no-gps: whole-route image retrieval places the drive). The same
# query against a 320 m database shows that memory does not grow with the route. Prints frames/s,
# peak memory and the along-track accuracy. Not a test.
#   bash tools/bench_localize_synth.sh [BUILD_DIR] [WORK_DIR]
# WORK_DIR (default /tmp/epiloc_bench_synth) keeps the generated data between runs: generating
# and building the 10,000-frame database takes about 30 minutes on 2 cores, once.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=${2:-/tmp/epiloc_bench_synth}
epiloc=$build/tools/epiloc
[[ -x $epiloc ]] || { echo "bench: build first ($epiloc missing)" >&2; exit 1; }
mkdir -p "$work"

prepare() {  # name length_m
  local dir=$work/$1
  if [[ ! -f $dir/route.sqlite || ! -f $dir/.complete ]]; then
    echo "bench: generating $1 ($2 m route, 300 m query) in $dir"
    rm -rf "$dir"
    "$epiloc" synth --out "$dir" --length-m "$2" --query-length-m 300 --no-lidar --quiet
    /usr/bin/time -f "%e %M" -o "$dir/build_time" \
      "$epiloc" build-db --drive "$dir/survey" --db "$dir/route.sqlite" --quiet > /dev/null
    touch "$dir/.complete"
  fi
}

run() {  # name label extra-args...
  local dir=$work/$1 label=$2
  shift 2
  local frames
  frames=$(($(wc -l < "$dir/query/frames.csv") - 1))
  /usr/bin/time -f "%e %M %U %S" -o "$dir/time" \
    "$epiloc" localize --db "$dir/route.sqlite" --drive "$dir/query" --mode online \
    --out "$dir/result.csv" --quiet "$@" > /dev/null
  read -r wall_s rss_kb user_s sys_s < "$dir/time"
  local mean
  mean=$("$epiloc" evaluate --result "$dir/result.csv" --truth "$dir/query" \
    --route "$dir/route.sqlite" --no-gnss 2>/dev/null | awk '/^Mean\|e\|/ {print $NF; exit}')
  awk -v l="$label" -v n="$frames" -v w="$wall_s" -v r="$rss_kb" -v u="$user_s" -v s="$sys_s" \
    -v e="$mean" 'BEGIN {
    printf "  %-34s %6.2f frames/s  (%d frames, %.1f s wall, %.1f cores)  peak memory %6.1f MB  along-track mean %s m\n",
      l, n / w, n, w, (u + s) / w, r / 1024, e }'
}

prepare long 8020
prepare short 320
db_frames=$(($(wc -l < "$work/long/survey/frames.csv") - 1))
read -r build_s build_kb < "$work/long/build_time"
echo "localize benchmark: synthetic street, $(nproc) cores"
printf "  database: %d frames, %.1f MB on disk (built in %.0f s, peak %.0f MB)\n" "$db_frames" \
  "$(du -m "$work/long/route.sqlite" | cut -f1)" "$build_s" "$((build_kb / 1024))"
run long "10,000-frame database, online" 
run long "10,000-frame database, online --no-gps" --no-gps
run short "$(($(wc -l < "$work/short/survey/frames.csv") - 1))-frame database, online"
