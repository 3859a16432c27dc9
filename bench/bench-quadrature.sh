#!/usr/bin/env bash
# Quadrature decoder: x86 host instructions per edge and per sample
# (callgrind, *_instructions_x86), and
# the velocity estimator's error, delay and noise at a 10 kHz loop.
set -euo pipefail
bin=build/bench/bench_quadrature
mkdir -p build/bench
cc -std=c99 -O2 -g -D_DEFAULT_SOURCE -Ifirmware/core -Ifirmware/hal -Ihil_sim -o "$bin" \
  bench/bench_quadrature.c firmware/core/qdec.c firmware/core/comp.c firmware/core/crc.c \
  firmware/core/fixmath.c firmware/core/fixmath_div.c hil_sim/qgen.c -lm
n=100000
bash bench/callgrind.sh quadrature_edge_instructions_x86 "$bin" qdec_edge "$n" edge "$n"
bash bench/callgrind.sh quadrature_sample_instructions_x86 "$bin" qdec_sample_counter "$n" sample "$n"
bash bench/callgrind.sh quadrature_sample_edge_input_instructions_x86 "$bin" qdec_sample "$n" sample_edge "$n"
"$bin" figures
