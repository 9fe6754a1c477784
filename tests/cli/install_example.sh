#!/usr/bin/env bash
# The installed package: `cmake --install` into a clean prefix, examples/ configured and built
# against it with find_package(epiloc), then run on a small synthetic street.
# Usage: install_example.sh BUILD_DIR SOURCE_DIR [CXX_COMPILER CXX_FLAGS EXE_LINKER_FLAGS]
# The compiler and flags are the libraries' own: a user builds against the package with the
# flags it was built with (tools/test_sanitizers.sh builds it with ASan + UBSan, and a program
# linking those libraries needs the sanitizers' runtimes).
set -euo pipefail
build=$1
source=$2
compiler=${3:-}
cxx_flags=${4:-}
linker_flags=${5:-}
flags=(-DCMAKE_CXX_FLAGS="$cxx_flags" -DCMAKE_EXE_LINKER_FLAGS="$linker_flags")
[[ -n $compiler ]] && flags+=(-DCMAKE_CXX_COMPILER="$compiler")
work=$(mktemp -d /tmp/epiloc_install_example.XXXXXX)
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/prefix" > "$work/install.log"
test -f "$work/prefix/lib/cmake/epiloc/epilocConfig.cmake"
test -f "$work/prefix/include/epiloc/localize/localizer.h"
cmake -S "$source/examples" -B "$work/build" -DCMAKE_PREFIX_PATH="$work/prefix" \
  -DCMAKE_BUILD_TYPE=Release "${flags[@]}" > "$work/configure.log"
cmake --build "$work/build" -j2 > "$work/build.log"
epiloc="$work/prefix/bin/epiloc"
"$epiloc" synth --out "$work/world" --length-m 40 --no-lidar --query-rate-hz 5 --clean-query -q \
  > /dev/null
"$epiloc" build-db --drive "$work/world/survey" --db "$work/route.sqlite" -q > /dev/null
"$work/build/localize_drive" "$work/route.sqlite" "$work/world/query" > "$work/out.csv"
frames=$(($(wc -l < "$work/out.csv") - 1))
ok=$(grep -c ',ok,' "$work/out.csv" || true)
echo "example through the installed package: $ok of $frames frames localized"
test "$frames" -gt 10
test $((ok * 10)) -ge $((frames * 9))
