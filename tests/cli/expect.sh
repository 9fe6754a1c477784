#!/usr/bin/env bash
# expect.sh CODE REGEX COMMAND...: runs COMMAND, passes if it exits with CODE and its combined
# stdout+stderr matches the extended REGEX. For a non-zero CODE the error must be one line on stderr.
set -u
want_code=$1 regex=$2
shift 2
out=$(mktemp) err=$(mktemp)
"$@" > "$out" 2> "$err"
code=$?
status=0
if [[ $code -ne $want_code ]]; then
  echo "exit code $code, expected $want_code"; status=1
fi
if ! cat "$out" "$err" | grep -Eq -- "$regex"; then
  echo "output does not match /$regex/"; status=1
fi
if [[ $want_code -ne 0 && $(grep -c . "$err") -ne 1 ]]; then
  echo "expected exactly one line on stderr, got $(grep -c . "$err")"; status=1
fi
if [[ $status -ne 0 ]]; then
  echo "--- stdout"; cat "$out"; echo "--- stderr"; cat "$err"
fi
rm -f "$out" "$err"
exit $status
