#!/usr/bin/env bash
# Instruction count of one full servo tick for three axes (callgrind, host
# compiler -O2, collected inside bench_tick): decode of three edge-input
# decoders, the reference hand-over, the contour error controller and three
# axis PIDs with feed-forward, on a 20 mm circle at 10 m/min, 10 kHz.
#   servo_tick_instructions_x86             CEC exact (the product's default)
#   servo_tick_instructions_x86_cec_<mode>  CEC off / tangent / curvature
# x86 host instructions of the decoder + servo part of a tick only: not
# comparable with control_tick_instructions_m4 (bench-firmware.sh), which
# is the whole drive_tick (interpolator, arc reference, calibration too) on
# the Cortex-M4.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=build/bench/bench_servo
mkdir -p build/bench
cc -std=c99 -O2 -g -D_DEFAULT_SOURCE -Ifirmware/core -Ifirmware/hal -Ihil_sim -o "$bin" \
  bench/bench_servo.c firmware/core/fixmath.c firmware/core/fixmath_div.c firmware/core/pid.c \
  firmware/core/cec.c firmware/core/cec_hist.c firmware/core/servo.c firmware/core/qdec.c firmware/core/comp.c firmware/core/crc.c \
  hil_sim/qgen.c -lm
n=10000
"$bin" exact "$n" # fails the bench if the run itself faults
bash bench/callgrind.sh servo_tick_instructions_x86 "$bin" bench_tick "$n" exact "$n"
for mode in off tangent curvature; do
  bash bench/callgrind.sh "servo_tick_instructions_x86_cec_${mode}" "$bin" bench_tick "$n" "$mode" "$n"
done
