#!/usr/bin/env bash
# Instruction count of one full servo tick for three axes (callgrind, host
# compiler -O2, collected inside bench_tick): decode of three edge-input
# decoders, the reference hand-over, the contour error controller and three
# axis PIDs with feed-forward, on a 20 mm circle at 10 m/min, 10 kHz.
#   control_tick_instructions             CEC exact (the product's default)
#   control_tick_instructions_<mode>      CEC off / tangent / curvature
set -euo pipefail
cd "$(dirname "$0")/.."
bin=build/bench/bench_servo
mkdir -p build/bench
cc -std=c99 -O2 -g -D_DEFAULT_SOURCE -Ifirmware/core -Ifirmware/hal -Ihil_sim -o "$bin" \
  bench/bench_servo.c firmware/core/fixmath.c firmware/core/fixmath_div.c firmware/core/pid.c firmware/core/cec.c \
  firmware/core/servo.c firmware/core/qdec.c firmware/core/comp.c firmware/core/crc.c \
  hil_sim/qgen.c -lm
n=10000
"$bin" exact "$n" # fails the bench if the run itself faults
bash bench/callgrind.sh control_tick_instructions "$bin" bench_tick "$n" exact "$n"
for mode in off tangent curvature; do
  bash bench/callgrind.sh "control_tick_instructions_${mode}" "$bin" bench_tick "$n" "$mode" "$n"
done
