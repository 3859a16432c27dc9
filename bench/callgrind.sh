#!/usr/bin/env bash
# callgrind.sh NAME BINARY FUNCTION CALLS [ARGS...]
# Runs BINARY under callgrind collecting only inside FUNCTION (inclusive) and
# prints "NAME: N instr" with N = instructions / CALLS, rounded.
# Instruction counts are repeatable on a loaded machine; wall times are not.
set -euo pipefail
name=$1; bin=$2; fn=$3; calls=$4; shift 4
out=$(mktemp)
trap 'rm -f "$out"' EXIT
valgrind --tool=callgrind --callgrind-out-file="$out" --toggle-collect="$fn" \
  "$bin" "$@" >/dev/null 2>&1
total=$(awk '/^summary:/{print $2}' "$out")
if [ -z "$total" ]; then total=$(awk '/^totals:/{print $2}' "$out"); fi
echo "$name: $(( (total + calls / 2) / calls )) instr"
