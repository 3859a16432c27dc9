#!/usr/bin/env bash
# callgrind.sh NAME BINARY FUNCTION CALLS [ARGS...]
# Runs BINARY under callgrind collecting only inside FUNCTION (inclusive) and
# prints "NAME: N instr" with N = instructions / CALLS, rounded.
# Instruction counts are repeatable on a loaded machine; wall times are not.
# Fails (exit 1, no figure line) when BINARY fails, or when FUNCTION is not
# in the profile or counted nothing: renamed, inlined into its callers, or
# never called. A figure of 0 would be a check that checks nothing.
set -euo pipefail
name=$1; bin=$2; fn=$3; calls=$4; shift 4
out=$(mktemp)
trap 'rm -f "$out"' EXIT
if ! valgrind --tool=callgrind --callgrind-out-file="$out" --compress-strings=no \
    --toggle-collect="$fn" "$bin" "$@" >/dev/null 2>&1; then
  echo "callgrind.sh: $name: $bin $* failed under valgrind" >&2
  exit 1
fi
if ! grep -qE "^fn=(\([0-9]+\) )?${fn}\$" "$out"; then
  echo "callgrind.sh: $name: function $fn did not run (renamed, inlined or not called)" >&2
  exit 1
fi
total=$(awk '/^summary:/{print $2}' "$out")
if [ -z "$total" ]; then total=$(awk '/^totals:/{print $2}' "$out"); fi
if [ -z "$total" ] || [ "$total" -le 0 ] || [ "$calls" -le 0 ]; then
  echo "callgrind.sh: $name: no instructions counted in $fn" >&2
  exit 1
fi
echo "$name: $(( (total + calls / 2) / calls )) instr"
