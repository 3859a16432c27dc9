#!/usr/bin/env bash
# CANopen CSP with SYNC on two simulated drives, in simulated time
# (contour.sim.canopen_bench: the master, the bus at 1 Mbit/s, what a missed
# cycle is; docs/canopen.md "Figures"). Deterministic: the same build gives
# the same figures.
#   canopen_csp_sync_hz     highest SYNC rate (of 500, 1000, 1250, 2000,
#                           2500 Hz) two drives follow for 400 cycles
#                           without a missed cycle
#   canopen_drive_skew_us   worst difference between the two drives' position
#                           sample times at one SYNC, at that rate
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(cd host_tools && ../.venv/bin/python -m contour.sim.canopen_bench)
echo "$out"
if grep -q '^canopen_csp_sync_hz: 0 Hz' <<< "$out"; then
  echo "bench-canopen: no SYNC rate ran without a missed cycle" >&2
  exit 1
fi
