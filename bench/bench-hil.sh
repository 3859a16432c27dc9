#!/usr/bin/env bash
# Realtime factor of the HIL simulator (three axes at 10 kHz, circle scenario):
# simulated seconds per wall-clock second, best of three 20 s runs.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p build/bench
bin=build/bench/bench_hil
src=$(find firmware/core -name '*.c' | sort)
cc -std=c99 -O2 -D_DEFAULT_SOURCE -Ifirmware/core -Ifirmware/hal -Ifirmware -Ihil_sim \
  -Ifirmware/ports/sim -o "$bin" bench/bench_hil.c $src hil_sim/*.c firmware/ports/sim/*.c -lm
"$bin"
