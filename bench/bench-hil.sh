#!/usr/bin/env bash
# Realtime factor of the HIL simulator (three axes at 10 kHz, circle scenario):
# simulated seconds per wall-clock second, best of three 20 s runs, with the
# default (fast) encoder model and with the edge-accurate reference; the
# machine's 1-minute load average at the time (wall clock on a shared
# machine); and the deterministic companion: x86 instructions per simulated
# tick inside sim_run under callgrind (20000 ticks, both models).
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p build/bench
bin=build/bench/bench_hil
src=$(find firmware/core -name '*.c' | sort)
cc -std=c99 -O2 -g -D_DEFAULT_SOURCE -Ifirmware/core -Ifirmware/hal -Ifirmware -Ihil_sim \
  -Ifirmware/ports/sim -o "$bin" bench/bench_hil.c $src hil_sim/*.c firmware/ports/sim/*.c -lm
echo "hil_load_average_1min_before: $(cut -d' ' -f1 /proc/loadavg) runnable"
"$bin" fast
"$bin" edges
echo "hil_load_average_1min_after: $(cut -d' ' -f1 /proc/loadavg) runnable"
n=20000
bash bench/callgrind.sh hil_tick_instructions_x86 "$bin" sim_run "$n" ticks "$n" fast
bash bench/callgrind.sh hil_tick_instructions_x86_edges "$bin" sim_run "$n" ticks "$n" edges
