#!/usr/bin/env bash
# Instruction counts per call of the fixed-point primitives (callgrind).
set -euo pipefail
bin=build/bench/bench_fixmath
cc -std=c99 -O2 -g -Ifirmware/core -o "$bin" bench/bench_fixmath.c firmware/core/fixmath.c
n=10000
for fn in isqrt64 icbrt64 sin atan2 hypot3 mul64_shift div_sat32; do
  bash bench/callgrind.sh "fixmath_${fn}_instructions" "$bin" "bench_$fn" "$n" "$fn" "$n"
done
