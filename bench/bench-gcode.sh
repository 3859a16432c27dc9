#!/usr/bin/env bash
# G-code reader throughput: a generated one-million-line CAM-style file
# (N, X, Y, Z words) read with contour.gcode.read. Prints lines/s.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p build/bench
.venv/bin/python - <<'PY'
import math
import time

from contour import gcode

path = "build/bench/gcode_1m.nc"
n = 1_000_000
with open(path, "w") as fh:
    fh.write("G21 G90 G17 G64\nG1 F3000\n")
    for i in range(n - 2):
        a = i * 1e-3
        fh.write(f"N{i + 10} X{50 * math.cos(a):.3f} Y{50 * math.sin(a):.3f} Z{(i % 997) * 1e-3:.3f}\n")
best = math.inf
for _ in range(2):
    t0 = time.perf_counter()
    prog = gcode.read(path)
    best = min(best, time.perf_counter() - t0)
assert prog.lines_read == n
import os

os.remove(path)
print(f"gcode_lines_per_second: {n / best:.0f} lines/s")
PY
