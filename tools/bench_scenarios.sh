#!/usr/bin/env bash
# The scenario suite: the localizer on synthetic "another day, another camera" variants of the
# street and on the shared KITTI drive under several protocols, each run several times (other seeds
# of the random parts), one table row per scenario with the WORST run's figures.
#
#   bash tools/bench_scenarios.sh [BUILD_DIR]
#
# Environment:
#   EPILOC_SCENARIO_RUNS    runs per scenario (default 3; seeds 1..RUNS)
#   EPILOC_SCENARIO_CACHE   generated worlds, imported drives and databases, reused across calls
#                           (default BUILD_DIR/scenarios; delete it after changing the generator)
#   EPILOC_SCENARIO_FILTER  extended regex: only scenarios whose name matches
#   EPILOC_SCENARIO_ARGS    extra options for every `epiloc localize` (default none)
#   EPILOC_KITTI_RAW        the KITTI drive (default ../shared/data/kitti_raw/.../drive_0005_sync;
#                           its scenarios are skipped when it is absent)
# A benchmark, not a test: it prints figures and exits 0 unless something crashes. Per-run
# outputs (result CSV, diagnostics, evaluation JSON, per-frame errors, logs) stay in the cache
# under runs/.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
runs=${EPILOC_SCENARIO_RUNS:-3}
cache=${EPILOC_SCENARIO_CACHE:-$build/scenarios}
filter=${EPILOC_SCENARIO_FILTER:-.}
extra_args=${EPILOC_SCENARIO_ARGS:-}
kitti=${EPILOC_KITTI_RAW:-../shared/data/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync}
epiloc=$build/tools/epiloc
if [[ ! -x $epiloc ]]; then
  bash tools/install_deps.sh
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
  cmake --build "$build" -j"$(nproc)" --target epiloc
fi
# Per-frame errors (evaluate --errors) where the binary has them (not before issue 16).
evaluate_errors=no
"$epiloc" evaluate --help 2>/dev/null | grep -q -- '--errors' && evaluate_errors=yes
mkdir -p "$cache/runs"
cache=$(cd "$cache" && pwd)
log="$cache/suite.log"
: > "$log"
results="$cache/runs/table_input.tsv"
: > "$results"
suite_start=$(date +%s)

bench_name=bench_scenarios
# shellcheck source=tools/bench_lib.sh
source tools/bench_lib.sh

# localize + evaluate one run: localize_run NAME RUN DB QUERY_DIR [localize options...]
localize_run() {
  local name=$1 run=$2 db=$3 query=$4
  shift 4
  local out="$cache/runs/${name}_run${run}"
  mkdir -p "$out"
  # shellcheck disable=SC2086
  if ! /usr/bin/time -f "%M" -o "$out/max_rss_kb" "$epiloc" localize --db "$db" --drive "$query" \
      --out "$out/result.csv" --diagnostics "$out/diagnostics.csv" -q "$@" $extra_args \
      > "$out/localize.log" 2>&1; then
    echo "bench_scenarios: localize failed for $name run $run:" >&2
    cat "$out/localize.log" >&2
    exit 1
  fi
  local errors=()
  [[ $evaluate_errors == yes ]] && errors=(--errors "$out/errors.csv")
  quiet "$epiloc" evaluate --result "$out/result.csv" --truth "$query" --route "$db" \
    --json "$out/summary.json" "${errors[@]}" -q
  local frames fps
  frames=$(grep -oE ': [0-9]+ frames' "$out/localize.log" | head -1 | grep -oE '[0-9]+')
  fps=$(grep -oE '[0-9.]+ frames/s' "$out/localize.log" | head -1 | grep -oE '^[0-9.]+')
  printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$name" "$run" "$frames" "$fps" "$(cat "$out/max_rss_kb")" \
    "$out/summary.json" >> "$results"
}

# synthetic NAME "WORLD_OPTIONS" "QUERY_OPTIONS": `epiloc synth` with both option sets; WORLD_OPTIONS
# are those that change the world or the survey drive (the route database is shared by every
# scenario with the same world options and seed: later ones generate their query only),
# QUERY_OPTIONS change only the query drive.
synthetic_length_m=${EPILOC_SCENARIO_LENGTH_M:-80}
synthetic() {
  local name=$1 world_options=$2 query_options=$3
  [[ $name =~ $filter ]] || return 0
  local world_key query_key
  world_key=$(echo "len$synthetic_length_m $world_options" | md5sum | cut -c1-10)
  query_key=$(echo "len$synthetic_length_m $world_options | $query_options" | md5sum | cut -c1-10)
  mkdir -p "$cache/synth" "$cache/db"
  for run in $(seq 1 "$runs"); do
    local world="$cache/synth/${name}_${query_key}_seed$run"
    local db="$cache/db/synth_${world_key}_seed$run.sqlite"
    local only=""
    [[ -e $db ]] && only="--query-only"
    say "$name run $run: synth $only"
    # shellcheck disable=SC2086
    cached "$world" "$epiloc" synth --out "$world.tmp" --seed "$run" \
      --length-m "$synthetic_length_m" --no-lidar -q $only $world_options $query_options
    if [[ ! -e $db ]]; then
      say "$name run $run: build-db"
      rm -f "$db.tmp"
      quiet "$epiloc" build-db --drive "$world/survey" --db "$db.tmp" -q
      mv "$db.tmp" "$db"
    fi
    say "$name run $run: localize"
    localize_run "$name" "$run" "$db" "$world/query"
  done
}

# kitti NAME SURVEY_STEP QUERY_FRAMES GPS_NOISE [localize options...]: survey = camera 0, every
# SURVEY_STEP-th frame, RTK positions; query = camera 1 frames QUERY_FRAMES (START:STOP:STEP)
# with GPS noise GPS_NOISE m (seed = run).
kitti() {
  local name=$1 survey_step=$2 query_frames=$3 noise=$4
  shift 4
  [[ $name =~ $filter ]] || return 0
  if [[ ! -d $kitti ]]; then
    say "$name: skipped ($kitti not found)"
    return 0
  fi
  mkdir -p "$cache/kitti"
  local survey="$cache/kitti/survey_every$survey_step"
  local db="$cache/kitti/survey_every$survey_step.sqlite"
  cached "$survey" "$epiloc" import-kitti --raw "$kitti" --camera 0 \
    --frames "0:154:$survey_step" --out "$survey.tmp" -q
  if [[ ! -e $db ]]; then
    say "$name: build-db (survey every $survey_step frames)"
    rm -f "$db.tmp"
    quiet "$epiloc" build-db --drive "$survey" --db "$db.tmp" -q
    mv "$db.tmp" "$db"
  fi
  for run in $(seq 1 "$runs"); do
    local query="$cache/kitti/query_${query_frames//:/_}_noise${noise}_seed$run"
    cached "$query" "$epiloc" import-kitti --raw "$kitti" --camera 1 --frames "$query_frames" \
      --gps-noise "$noise" --seed "$run" --out "$query.tmp" -q
    say "$name run $run: localize"
    localize_run "$name" "$run" "$db" "$query" "$@"
  done
}

# ---- The scenarios ---------------------------------------------------------------------------
# The synthetic street (80 m; the default query: 640x360 dashcam with barrel distortion, 0.7 m to
# the left, noise, blur, darker exposure, heading wobble, a 2 s stop, 6-10 m/s, 15 Hz, 3 m GPS).
synthetic synth_default "" ""
# Another day: parked cars, light (the survey's day overcast, the query's sunny with shadows,
# brighter and warmer), traffic, a lead vehicle in both drives, vegetation.
synthetic synth_parked_cars "" "--query-parked-cars-changed 0.5"
synthetic synth_light "" "--query-sun 250,25 --query-exposure 1.3 --query-white-balance 1.15,1,0.8"
synthetic synth_traffic "--traffic 6" "--query-parked-cars-changed 0.3"
synthetic synth_lead_vehicle "--lead-vehicle-gap-m 10" ""
synthetic synth_vegetation "--vegetation 0.6" ""
# Another camera.
synthetic synth_dashcam_1080p "" "--query-camera dashcam1080 --query-jpeg-quality 90 --query-length-m 35"
synthetic synth_vga_grey_jpeg "" "--query-camera vga --query-grey --query-jpeg-quality 60 --query-exposure-s 0.02"
synthetic synth_same_line "" "--query-offset-m 0"
# Another speed profile.
synthetic synth_stops_creep "" "--query-start-from-rest --query-creep-mps 1 --query-creep-m 8 --query-max-accel-mps2 4 --query-stops 0.5:6 --query-stop-at-end 3"
synthetic synth_fast "" "--query-speed-mps 16 --query-speed-sections none --query-stops none"
synthetic synth_beyond_ends "" "--query-start-offset-m -15 --query-end-offset-m -15"
# Curves and turns.
synthetic synth_turn_in "--query-turn-in-deg 90" ""
synthetic synth_sharp_curves "--sharp-curves" "--query-line-m 1"
# Combined: the failures seen on unseen real drives.
synthetic combo_lead_vegetation_fast "--lead-vehicle-gap-m 12 --vegetation 0.6 --traffic 4" "--query-speed-mps 15 --query-speed-sections none --query-stops none"
synthetic combo_turn_from_rest_same_line "--query-turn-in-deg 90" "--query-start-from-rest --query-creep-mps 0.8 --query-creep-m 6 --query-offset-m 0 --query-grey"
synthetic combo_another_day "" "--query-sun 120,30 --query-exposure 0.7 --query-parked-cars-changed 0.3 --query-camera vga --query-jpeg-quality 75"

# The shared KITTI drive: survey camera 0, query camera 1 (0.54 m to the side).
kitti kitti_dev 2 1:154:2 3
kitti kitti_survey_every1 1 1:154:2 3
kitti kitti_survey_every4 4 1:154:2 3
kitti kitti_query_every1 2 0:154:1 3
kitti kitti_query_every3 2 1:154:3 3
kitti kitti_gps1 2 1:154:2 1
kitti kitti_gps10 2 1:154:2 10
kitti kitti_no_gps 2 1:154:2 3 --no-gps

# ---- The table -------------------------------------------------------------------------------
elapsed=$(($(date +%s) - suite_start))
python3 tools/scenario_table.py "$results" "$runs"
echo "suite: ${elapsed} s on $(nproc) cores; outputs in $cache/runs"
