# shellcheck shell=bash
# Helpers shared by the benchmark suites (tools/bench_scenarios.sh, tools/bench_anchor_scenarios.sh):
# sourced after the caller has set `log` (the suite's log file) and `bench_name` (its name in
# error messages).
# shellcheck disable=SC2154  # log and bench_name: set by the caller

say() { echo "[$(date +%H:%M:%S)] $*" | tee -a "$log" >&2; }

# Runs a command quietly, its output appended to the suite log; on failure prints it and exits.
quiet() {
  if ! "$@" >> "$log" 2>&1; then
    echo "$bench_name: failed: $*" >&2
    tail -n 20 "$log" >&2
    exit 1
  fi
}

# A cached step: the directory (or file) $1 is made by the remaining command unless it exists;
# the command writes into "$1.tmp" (removed first) which is renamed on success.
cached() {
  local target=$1
  shift
  [[ -e $target ]] && return 0
  rm -rf "$target.tmp"
  quiet "$@"
  mv "$target.tmp" "$target"
}
