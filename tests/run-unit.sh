#!/usr/bin/env bash
# Runs Unity test binaries and prints one closing line for all of them.
set -uo pipefail
passed=0; failed=0; bad=()
for t in "$@"; do
  out=$("$t" 2>&1); rc=$?
  echo "$out" | grep -E 'FAIL|Tests|ERROR|runtime error' || true
  line=$(echo "$out" | grep -E '^[0-9]+ Tests [0-9]+ Failures' | tail -n 1)
  n=$(echo "$line" | awk '{print $1}'); f=$(echo "$line" | awk '{print $3}')
  if [ -z "$line" ] || [ $rc -ne 0 ]; then
    bad+=("$(basename "$t")"); failed=$((failed + ${f:-1})); passed=$((passed + ${n:-0} - ${f:-0}))
    [ -z "$line" ] && echo "$out" | tail -n 20
  else
    passed=$((passed + n - f)); failed=$((failed + f))
  fi
done
echo "unit: $passed passed, $failed failed"
if [ ${#bad[@]} -ne 0 ]; then echo "failing: ${bad[*]}"; exit 1; fi
