#!/usr/bin/env bash
# Real-data integration test: import the shared KITTI drive 0005 (camera 0, all 154 frames), build
# a route database, kill build-db halfway (SIGKILL, no clean-up possible), re-run it, and check
# that the database then holds each of the 154 frames exactly once, with features, on a route of
# about 69 m. Skips (exit 77) when ../shared/data is absent.
set -euo pipefail
epiloc=$1
shared=$2
raw=$shared/kitti_raw/2011_09_26/2011_09_26_drive_0005_sync
if [[ ! -d $raw ]]; then
  echo "SKIP: $raw not found (real-data test needs ../shared/data)"
  exit 77
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
db=$work/route.sqlite
count() { sqlite3 "file:$db?mode=ro" "SELECT COUNT(*) FROM frames" 2>/dev/null || echo 0; }

"$epiloc" import-kitti --raw "$raw" --camera 0 --out "$work/drive" --quiet
"$epiloc" build-db --drive "$work/drive" --db "$db" --threads 2 --quiet &
pid=$!
for _ in $(seq 1 600); do
  n=$(count)
  [[ $n -ge 40 ]] && break
  kill -0 "$pid" 2>/dev/null || break
  sleep 0.1
done
kill -9 "$pid" 2>/dev/null || { echo "FAIL: build-db finished before it could be killed"; exit 1; }
wait "$pid" 2>/dev/null || true
killed_at=$(count)
echo "killed build-db with $killed_at frames committed"
[[ $killed_at -gt 0 && $killed_at -lt 154 ]] || { echo "FAIL: expected a partial database"; exit 1; }

"$epiloc" build-db --drive "$work/drive" --db "$db" --threads 2 --quiet
info=$("$epiloc" info --db "$db")
echo "$info"
frames=$(sqlite3 "$db" "SELECT COUNT(*) FROM frames")
distinct=$(sqlite3 "$db" "SELECT COUNT(DISTINCT frame) FROM frames")
without=$(sqlite3 "$db" "SELECT COUNT(*) FROM frames WHERE num_features < 200")
complete=$(sqlite3 "$db" "SELECT complete FROM drives")
length=$(echo "$info" | awk '/^route length/ {print $3}')
status=0
[[ $frames -eq 154 ]] || { echo "FAIL: $frames frames, expected 154"; status=1; }
[[ $distinct -eq 154 ]] || { echo "FAIL: $distinct distinct frames, expected 154"; status=1; }
[[ $without -eq 0 ]] || { echo "FAIL: $without frames with fewer than 200 features"; status=1; }
[[ $complete -eq 1 ]] || { echo "FAIL: drive not marked complete"; status=1; }
awk -v l="$length" 'BEGIN { exit !(l > 66 && l < 72) }' || { echo "FAIL: route length $length m, expected about 69 m"; status=1; }
# A third run adds nothing.
again=$("$epiloc" build-db --drive "$work/drive" --db "$db" --quiet)
echo "$again"
echo "$again" | grep -q " 0 frames added" || { echo "FAIL: re-run added frames"; status=1; }
exit $status
