#!/usr/bin/env bash
# tools/fuzz.sh [SECONDS] [HARNESS...]: builds the libFuzzer harnesses of the parsers (tests/fuzz)
# with clang, AddressSanitizer and UndefinedBehaviorSanitizer into build-fuzz/ and runs each for
# SECONDS (default 60) on a working copy of its seed corpus (tests/fuzz/corpus/<name>, new inputs
# go to build-fuzz/corpus/<name>). Prints executions and coverage per harness; crashes, leaks,
# sanitizer reports and out-of-memory inputs are saved as build-fuzz/artifacts/<name>/... and make
# the script exit non-zero. The normal build replays the seed corpora under CTest
# (fuzz_<name>_replay), without libFuzzer.
set -euo pipefail
seconds=${1:-60}
shift || true
root=$(cd "$(dirname "$0")/.." && pwd)
build=${EPILOC_FUZZ_BUILD_DIR:-$root/build-fuzz}
all=(csv nmea drive_json config cloud trajectory stella_map georef db_blob)
harnesses=("$@")
((${#harnesses[@]})) || harnesses=("${all[@]}")

# The libraries of the normal build, plus clang and its libFuzzer runtime (needed only here).
bash "$root/tools/install_deps.sh"
missing=()
for p in clang libclang-rt-14-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "fuzz: installing ${missing[*]}"
  sudo=""
  [[ $(id -u) -ne 0 ]] && sudo="sudo"
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

flags="-g -O1 -fno-omit-frame-pointer -fsanitize=address,undefined,fuzzer-no-link -fno-sanitize-recover=undefined"
launcher=()
command -v ccache > /dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_C_COMPILER=clang "${launcher[@]}" \
  -DEPILOC_FUZZ=ON -DEPILOC_BUILD_TESTS=OFF \
  -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" > /dev/null
targets=()
for h in "${harnesses[@]}"; do targets+=("${h}_fuzz"); done
nice -n 15 cmake --build "$build" -j "$(nproc)" --target "${targets[@]}"

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
status=0
summary=()
for h in "${harnesses[@]}"; do
  corpus="$build/corpus/$h" artifacts="$build/artifacts/$h"
  mkdir -p "$corpus" "$artifacts"
  cp -n "$root/tests/fuzz/corpus/$h/"* "$corpus/" 2> /dev/null || true
  log="$build/$h.log"
  echo "fuzz: $h for ${seconds} s"
  set +e
  (cd "$build" && nice -n 15 "./tests/fuzz/${h}_fuzz" "$corpus" -max_total_time="$seconds" \
     -rss_limit_mb=2048 -malloc_limit_mb=1024 -timeout=20 -print_final_stats=1 \
     -artifact_prefix="$artifacts/" > "$log" 2>&1)
  rc=$?
  set -e
  execs=$(grep -Eo 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -Eo '[0-9]+$' || echo "?")
  last=$(grep -E '#[0-9]+.*(DONE|cov:)' "$log" | tail -1)
  cov=$(grep -Eo 'cov: [0-9]+' <<< "$last" | grep -Eo '[0-9]+' || echo "?")
  ft=$(grep -Eo 'ft: [0-9]+' <<< "$last" | grep -Eo '[0-9]+' || echo "?")
  files=$(find "$corpus" -type f | wc -l)
  line=$(printf '%-11s %4s s  exit %d  execs %10s  cov %5s  ft %6s  corpus %5d' "$h" "$seconds" \
         "$rc" "$execs" "$cov" "$ft" "$files")
  summary+=("$line")
  if [[ $rc -ne 0 ]]; then
    status=1
    echo "fuzz: $h FAILED (exit $rc), see $log and $artifacts/"
    grep -E 'ERROR|runtime error|Uncaught|deadly|SUMMARY' "$log" | head -5 || true
  fi
done
echo
echo "harness     time     exit  executions              coverage (edges, features)  corpus"
printf '%s\n' "${summary[@]}"
# Scratch folders of harness runs that have ended (the harnesses write their inputs there).
for d in /tmp/epiloc_fuzz_*; do
  [[ -d $d ]] && ! kill -0 "${d##*_}" 2> /dev/null && rm -rf "$d"
done
exit $status
