#!/usr/bin/env bash
# Instruction counts per call of the fixed-point primitives (callgrind,
# host compiler -O2, collected inside the fx_ function only). Each line:
#   fixmath_<case>_instructions_x86: N instr
# (fx_mul32_shift is inline since it serves the tick: not counted here)
# "_wide" cases take the 128-bit paths (components >= 2^31, quotients of
# 128-bit numerators); the others the common fast paths.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=build/bench/bench_fixmath
mkdir -p build/bench
cc -std=c99 -O2 -g -Ifirmware/core -o "$bin" bench/bench_fixmath.c firmware/core/fixmath.c firmware/core/fixmath_div.c
n=10000
# case:function measured
for spec in \
  sat_mul32:fx_sat_mul32 mul64_shift:fx_mul64_shift \
  mul64x32_shift:fx_mul64x32_shift div_sat32:fx_div_sat32 div_round64:fx_div_round64 \
  div_shift64_wide:fx_div_shift64 muldiv64:fx_muldiv64 muldiv64_wide:fx_muldiv64 \
  recip_q16:fx_recip_q16 isqrt32:fx_isqrt32 isqrt64:fx_isqrt64 icbrt64:fx_icbrt64 \
  sin:fx_sin cos:fx_cos sincos:fx_sincos atan2:fx_atan2 hypot2:fx_hypot2 hypot3:fx_hypot3 \
  hypot2_wide:fx_hypot2 hypot3_wide:fx_hypot3; do
  name=${spec%%:*}; fn=${spec#*:}
  bash bench/callgrind.sh "fixmath_${name}_instructions_x86" "$bin" "$fn" "$n" "$name" "$n"
done
