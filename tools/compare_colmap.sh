#!/usr/bin/env bash
# Side-by-side comparison of epiloc with COLMAP (issue 8) on one survey/query drive pair.
#
# COLMAP (Debian package `colmap`, CPU only) is given the survey's known poses and asked to
# register the query frames:
#   1. workspace: symlinks to the frames (no copies), database.db
#   2. feature_extractor on survey and query frames: PINHOLE camera per drive from drive.json
#   3. matches_importer: survey frame i with i+1..i+K, and every query frame with the survey
#      frames within --radius-m of the query drive's own (noisy) GNSS at that frame
#   4. the survey ground-truth poses as a text model (world = ENU at the first survey
#      ground-truth sample), point_triangulator (poses and intrinsics held fixed)
#   5. image_registrator for the query frames (PnP + pose refinement; no bundle adjustment,
#      survey poses never move)
#   6. model_converter --output_type TXT
#   7. registered query poses -> epiloc result CSV (method colmap, WGS-84, enu_from_cam).
#      COLMAP 3.8's image_registrator refines the query camera's focal length on the first
#      image it registers (no CLI switch) and keeps that focal length for the others; colmap.csv
#      therefore re-runs COLMAP's pose-only refinement (Cauchy loss, same inliers) with the
#      calibrated intrinsics (what COLMAP does for an already refined camera); the verbatim
#      COLMAP poses go to colmap_raw.csv and are evaluated too (evaluate_raw.txt).
#   8. epiloc evaluate (and side by side with an epiloc localize result when one is given)
# Every COLMAP stage is timed (/usr/bin/time).
#
# usage: tools/compare_colmap.sh --work W [--epiloc BIN] [--kitti RAW_DRIVE] [--out DIR]
#            [--epiloc-result F.csv | --localize] [--radius-m 12] [--survey-neighbours 4]
#            [--threads N] [--max-features 8192] [--survey-poses timestamp|frame] [--exhaustive]
#            [--force | --resume]
#   W holds survey/ and query/ (epiloc drive directories) and route.sqlite (built from survey/).
#   --kitti RAW creates them first when absent (the development scenario):
#       import-kitti --camera 0 --frames 0:154:2 -> W/survey (RTK poses)
#       import-kitti --camera 1 --frames 1:154:2 --gps-noise 3 --seed 1 -> W/query
#       build-db --drive W/survey --db W/route.sqlite
#   --epiloc BIN (or $EPILOC): the epiloc binary, default build/tools/epiloc.
#   --epiloc-result F: an epiloc localize result to evaluate next to COLMAP (default
#       W/epiloc.csv when it exists); --localize runs `epiloc localize` to make W/epiloc.csv.
#   --survey-poses: survey ground truth interpolated at the frame timestamps (default, as
#       `epiloc build-db` positions the survey) or the sample carrying the frame number.
#   --resume: keep an existing workspace in --out and skip the COLMAP stages that finished
#       there (their recorded timings are reused); --force: delete it and start over.
#   --exhaustive: exhaustive_matcher over all frames instead of the pair lists (slow on CPU).
# Outputs in --out (default W/colmap): colmap.csv, evaluate.txt, timings.txt, logs/, models.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/.." && pwd)"
helper="$here/colmap_to_result.py"

work="" out="" raw="" epiloc="${EPILOC:-$repo/build/tools/epiloc}" epiloc_result="" localize=0
radius=12 neighbours=4 threads=-1 max_features=8192 exhaustive=0 force=0 resume=0 survey_poses=timestamp
die() { echo "compare_colmap.sh: $*" >&2; exit 1; }
while [[ $# -gt 0 ]]; do
  case "$1" in
    --work) work="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --kitti) raw="$2"; shift 2 ;;
    --epiloc) epiloc="$2"; shift 2 ;;
    --epiloc-result) epiloc_result="$2"; shift 2 ;;
    --localize) localize=1; shift ;;
    --radius-m) radius="$2"; shift 2 ;;
    --survey-neighbours) neighbours="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    --max-features) max_features="$2"; shift 2 ;;
    --survey-poses) survey_poses="$2"; shift 2 ;;
    --exhaustive) exhaustive=1; shift ;;
    --force) force=1; shift ;;
    --resume) resume=1; shift ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) die "unknown option $1 (see --help)" ;;
  esac
done
[[ -n "$work" ]] || die "--work W is required (see --help)"
command -v colmap >/dev/null || die "colmap not found: apt-get install -y colmap"
command -v python3 >/dev/null || die "python3 not found"
[[ -x /usr/bin/time ]] || die "/usr/bin/time not found: apt-get install -y time"
[[ -x "$epiloc" ]] || die "epiloc binary $epiloc not found (--epiloc BIN or EPILOC=...)"
mkdir -p "$work"
work="$(cd "$work" && pwd)"
out="${out:-$work/colmap}"

# ---------------------------------------------------------------- scenario
if [[ -n "$raw" ]]; then
  [[ -d "$work/survey" ]] || "$epiloc" import-kitti --quiet --raw "$raw" --camera 0 --frames 0:154:2 --out "$work/survey"
  [[ -d "$work/query" ]] || "$epiloc" import-kitti --quiet --raw "$raw" --camera 1 --frames 1:154:2 \
      --gps-noise 3 --seed 1 --out "$work/query"
  [[ -f "$work/route.sqlite" ]] || "$epiloc" build-db --quiet --drive "$work/survey" --db "$work/route.sqlite"
fi
for f in survey/drive.json query/drive.json route.sqlite; do
  [[ -e "$work/$f" ]] || die "$work/$f missing (give --kitti RAW to create the development scenario)"
done
if [[ $localize -eq 1 && -z "$epiloc_result" ]]; then
  epiloc_result="$work/epiloc.csv"
  [[ -f "$epiloc_result" ]] || "$epiloc" localize --quiet --db "$work/route.sqlite" --drive "$work/query" --out "$epiloc_result"
fi
[[ -z "$epiloc_result" && -f "$work/epiloc.csv" ]] && epiloc_result="$work/epiloc.csv"

if [[ -e "$out/database.db" && $resume -eq 0 ]]; then
  [[ $force -eq 1 ]] || die "$out already holds a COLMAP workspace (--force to start over, --resume to continue)"
  rm -rf "$out"
fi
mkdir -p "$out/logs" "$out/images"
out="$(cd "$out" && pwd)"
db="$out/database.db"
timings="$out/timings.txt"
: > "$timings"

# stage NAME cmd...: run one timed stage, log in logs/NAME.log, "NAME seconds" in timings.txt
stage() {
  local name="$1"; shift
  if [[ $resume -eq 1 && -s "$out/logs/$name.time" ]] && grep -q "^$name " "$out/logs/timings.done" 2>/dev/null; then
    echo "[$(date +%T)] $name: done before, skipped" >&2
    grep "^$name " "$out/logs/timings.done" | tail -n 1 >> "$timings"
    return 0
  fi
  echo "[$(date +%T)] $name" >&2
  if ! /usr/bin/time -f "%e %U %S %M" -o "$out/logs/$name.time" "$@" > "$out/logs/$name.log" 2>&1; then
    tail -n 30 "$out/logs/$name.log" >&2
    die "stage $name failed (log: $out/logs/$name.log)"
  fi
  read -r wall user sys rss < "$out/logs/$name.time"
  awk -v n="$name" -v w="$wall" -v u="$user" -v s="$sys" -v m="$rss" \
      'BEGIN { printf "%-16s %9.1f s wall %9.1f s cpu %7.0f MB\n", n, w, u + s, m / 1024 }' \
      | tee -a "$out/logs/timings.done" >> "$timings"
}

# ---------------------------------------------------------------- 1. workspace
python3 "$helper" links "$work/survey" "$out/images/survey" --list "$out/survey_images.txt"
python3 "$helper" links "$work/query" "$out/images/query" --list "$out/query_images.txt"
n_survey=$(wc -l < "$out/survey_images.txt")
n_query=$(wc -l < "$out/query_images.txt")
origin=$(python3 "$helper" origin "$work/survey")
echo "survey $n_survey frames, query $n_query frames, COLMAP world = ENU at $origin" >&2

camera_params() {  # fx,fy,cx,cy of a drive (PINHOLE); refuses distortion
  python3 - "$1/drive.json" <<'EOF'
import json, sys
c = json.load(open(sys.argv[1]))["camera"]
if any(abs(d) > 0 for d in c.get("distortion", [])):
    sys.exit("%s: distorted camera; this comparison expects rectified frames" % sys.argv[1])
print("%r,%r,%r,%r" % (c["fx"], c["fy"], c["cx"], c["cy"]))
EOF
}

# ---------------------------------------------------------------- 2. features
sift=(--SiftExtraction.use_gpu 0 --SiftExtraction.num_threads "$threads"
      --SiftExtraction.max_num_features "$max_features")
for drive in survey query; do
  stage "extract_$drive" colmap feature_extractor --database_path "$db" --image_path "$out/images" \
      --image_list_path "$out/${drive}_images.txt" --ImageReader.camera_model PINHOLE \
      --ImageReader.single_camera 1 --ImageReader.camera_params "$(camera_params "$work/$drive")" "${sift[@]}"
done

# ---------------------------------------------------------------- 3. matching
match=(--SiftMatching.use_gpu 0 --SiftMatching.num_threads "$threads")
python3 "$helper" pairs "$work/survey" "$work/query" --out-survey "$out/pairs_survey.txt" \
    --out-query "$out/pairs_query.txt" --radius-m "$radius" --survey-neighbours "$neighbours" \
    | tee "$out/pairs.txt" >&2
if [[ $exhaustive -eq 1 ]]; then
  stage match_all colmap exhaustive_matcher --database_path "$db" "${match[@]}"
else
  stage match_survey colmap matches_importer --database_path "$db" --match_list_path "$out/pairs_survey.txt" \
      --match_type pairs "${match[@]}"
fi

# ---------------------------------------------------------------- 4. survey model
[[ $resume -eq 1 && -s "$out/known/images.txt" ]] || \
  python3 "$helper" model "$work/survey" --db "$db" --out "$out/known" --survey-poses "$survey_poses" >&2
mkdir -p "$out/triangulated"
stage triangulate colmap point_triangulator --database_path "$db" --image_path "$out/images" \
    --input_path "$out/known" --output_path "$out/triangulated" --Mapper.num_threads "$threads"

# ---------------------------------------------------------------- 5. query registration
if [[ $exhaustive -eq 0 ]]; then
  stage match_query colmap matches_importer --database_path "$db" --match_list_path "$out/pairs_query.txt" \
      --match_type pairs "${match[@]}"
fi
mkdir -p "$out/registered"
stage register colmap image_registrator --database_path "$db" --input_path "$out/triangulated" \
    --output_path "$out/registered" --Mapper.num_threads "$threads"

# ---------------------------------------------------------------- 6. text model
mkdir -p "$out/registered_txt" "$out/triangulated_txt"
colmap model_converter --input_path "$out/triangulated" --output_path "$out/triangulated_txt" \
    --output_type TXT > "$out/logs/convert.log" 2>&1
colmap model_converter --input_path "$out/registered" --output_path "$out/registered_txt" \
    --output_type TXT >> "$out/logs/convert.log" 2>&1

# ---------------------------------------------------------------- 7. result CSV
python3 "$helper" result "$work/query" --survey "$work/survey" --model "$out/registered_txt" \
    --out "$out/colmap_raw.csv" > /dev/null
python3 "$helper" result "$work/query" --survey "$work/survey" --model "$out/registered_txt" \
    --out "$out/colmap.csv" --fixed-intrinsics "$db" | tee "$out/result.txt"
python3 "$helper" check "$out/registered_txt" | tee "$out/check.txt"

# ---------------------------------------------------------------- 8. evaluation
# `epiloc evaluate` accepts only its known method names; builds that predate the 'colmap'
# method get the same rows under 'pnp' (COLMAP's registration is PnP + refinement).
evaluable() {  # CSV -> path of a CSV this epiloc evaluates
  if "$epiloc" evaluate --quiet --result "$1" --truth "$work/query" --route "$work/route.sqlite" \
      > /dev/null 2> "$out/logs/evaluate_probe.log"; then
    echo "$1"
  elif grep -q "unknown method 'colmap'" "$out/logs/evaluate_probe.log"; then
    sed '2,$ s/,colmap,/,pnp,/' "$1" > "${1%.csv}_as_pnp.csv"
    echo "${1%.csv}_as_pnp.csv"
  else
    cat "$out/logs/evaluate_probe.log" >&2
    die "epiloc evaluate failed on $1"
  fi
}
eval_csv=$(evaluable "$out/colmap.csv")
raw_csv=$(evaluable "$out/colmap_raw.csv")
[[ "$eval_csv" == *_as_pnp.csv ]] && \
  echo "note: this epiloc does not know the method 'colmap': COLMAP rows are evaluated as 'pnp'" | tee "$out/method_note.txt"
"$epiloc" evaluate --quiet --result "$raw_csv" --truth "$work/query" --route "$work/route.sqlite" \
    --no-gnss > "$out/evaluate_raw.txt"
if [[ -n "$epiloc_result" ]]; then
  python3 "$helper" merge "$out/both.csv" "$eval_csv" "$epiloc_result"
  eval_csv="$out/both.csv"
fi
"$epiloc" evaluate --quiet --result "$eval_csv" --truth "$work/query" --route "$work/route.sqlite" \
    --json "$out/evaluate.json" | tee "$out/evaluate.txt"
echo
echo "COLMAP poses verbatim (query focal length refined by image_registrator), along-track [m]:"
awk '/^Along-track/ { on = 1 } on && /^(Min|Max|Mean\|e\||Bias|RMSE|P95)/ { print "  " $0 } /^Frames/ { on = 0 }' \
    "$out/evaluate_raw.txt"

# ---------------------------------------------------------------- timings
{
  echo
  echo "COLMAP $(colmap -h 2>&1 | sed -n 's/^COLMAP \([^ ]*\).*/\1/p' | head -1), $(nproc) cores, --threads $threads"
  cat "$timings"
  if [[ $exhaustive -eq 0 ]]; then
    awk -v nq="$n_query" -v ns="$n_survey" '
      { t[$1] = $2 }
      END {
        prep = t["extract_survey"] + t["match_survey"] + t["triangulate"]
        q = t["match_query"] + t["register"]
        printf "survey preparation (extract + match + triangulate, %d frames): %.1f s\n", ns, prep
        printf "query: matching + registration %.2f s per query frame (%d frames); with feature extraction %.2f s per frame\n", q / nq, nq, (q + t["extract_query"]) / nq
      }' "$timings"
  fi
} | tee "$out/timings_summary.txt"
echo "outputs: $out/colmap.csv, $out/evaluate.txt, $out/timings.txt, $out/check.txt" >&2
