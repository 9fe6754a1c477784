#!/usr/bin/env bash
# tools/test_sanitizers.sh [CTEST ARGS...]: builds the whole suite with AddressSanitizer and
# UndefinedBehaviorSanitizer (-fsanitize=address,undefined, any report is fatal) into build-asan/
# and runs it with CTest; extra arguments go to ctest (e.g. -R core_ -j 1). EPILOC_ASAN_TARGETS
# (space-separated build targets) builds only those, for a quicker partial run; EPILOC_ASAN_JOBS
# (default: all cores) is the build's parallelism, e.g. 1 on a machine shared with a benchmark.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${EPILOC_ASAN_BUILD_DIR:-$root/build-asan}
bash "$root/tools/install_deps.sh"
launcher=()
command -v ccache > /dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
# GCC's `undefined` group leaves out float-cast-overflow (a double beyond the range of the integer
# it is converted to); clang's includes it, and the fuzz harnesses found one: it is added here.
flags="-g -O1 -fno-omit-frame-pointer -fsanitize=address,undefined,float-cast-overflow"
flags+=" -fno-sanitize-recover=undefined,float-cast-overflow"
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${launcher[@]}" \
  -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined,float-cast-overflow" > /dev/null
targets=()
for t in ${EPILOC_ASAN_TARGETS:-}; do targets+=(--target "$t"); done
nice -n 15 cmake --build "$build" -j "${EPILOC_ASAN_JOBS:-$(nproc)}" "${targets[@]}"
# Leaks are reported too; OpenCV's and FFmpeg's process-lifetime caches are not leaks of ours.
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:strict_string_checks=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$root/tools/lsan.supp:print_suppressions=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
nice -n 15 ctest --test-dir "$build" -j "$(nproc)" --output-on-failure "$@"
