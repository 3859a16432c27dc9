#!/usr/bin/env bash
# Planner, estimator and interpolator figures (host build, -O2, no sanitizers):
#   planner_push_instructions_x86  x86 host instructions to queue one block +
#                                the re-planning it triggers, amortised over
#                                20000 pushes on a full depth-64 ring
#                                (callgrind, bench_push; the ring is never
#                                popped: not comparable with
#                                planner_block_instructions_m4, push + pop)
#   estimator_blocks_per_second  plan_estimate over 1e6 random blocks (best of 3;
#                                S-curve, and _trapezoid: deferred passes)
#   estimator_collinear_us_per_block  plan_estimate over 40 000 collinear 0.1 mm
#                                blocks at depth 1024 (trapezoid, minimum block
#                                time 0.4486 ms: the iTNC530 profile's worst case)
#   interp_random_path_10000hz_* the 100 000-block random-path check of
#                                tests/unit/test_interp.c at 10 kHz
set -euo pipefail
bin=build/bench/bench_planner
mkdir -p build/bench
cc -std=c99 -O2 -g -D_DEFAULT_SOURCE -Ifirmware/core -Itests/unit/support -o "$bin" \
  bench/bench_planner.c tests/unit/support/path_check.c firmware/core/planner*.c \
  firmware/core/scurve.c firmware/core/scurve_reach.c firmware/core/estimator.c firmware/core/interp.c \
  firmware/core/fixmath.c firmware/core/fixmath_div.c -lm
n=20000
bash bench/callgrind.sh planner_push_instructions_x86 "$bin" bench_push "$((n + 64))" push "$n"
"$bin" estimate 1000000
"$bin" estimate 1000000 trapezoid
"$bin" collinear 40000 1024
"$bin" check 100000 10000
