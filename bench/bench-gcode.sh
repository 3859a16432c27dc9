#!/usr/bin/env bash
# G-code reader throughput: a generated one-million-line CAM-style file read
# end to end (file reading included) with contour.gcode.read. Prints lines/s.
# The file is what CAM posts write: N X Y Z lines, a feed change now and
# then, and arcs (G2/G3 with I J, about one line in eight) each followed by
# a G1 line.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p build/bench
.venv/bin/python - <<'PY'
import math
import random
import time

from contour import gcode

path = "build/bench/gcode_1m.nc"
n = 1_000_000
rng = random.Random(20)
x = y = 0.0
with open(path, "w") as fh:
    fh.write("G21 G90 G17 G64\nG1 F3000\n")
    i = 2
    while i < n:
        if rng.random() < 0.07 and i + 1 < n:
            # A quarter turn about a centre at a distance r, then a G1 line.
            r = rng.uniform(0.5, 5.0)
            a = rng.uniform(0.0, 2 * math.pi)
            cx, cy = x - r * math.cos(a), y - r * math.sin(a)
            g = rng.choice((2, 3))
            b = a + (math.pi / 2 if g == 3 else -math.pi / 2)
            ex, ey = f"{cx + r * math.cos(b):.4f}", f"{cy + r * math.sin(b):.4f}"
            fh.write(f"N{i} G{g} X{ex} Y{ey} I{cx - x:.4f} J{cy - y:.4f}\n")
            x, y = float(ex) + 0.05, float(ey)
            fh.write(f"N{i + 1} G1 X{x:.4f} Y{y:.4f}\n")
            x = float(f"{x:.4f}")
            i += 2
            continue
        x += rng.uniform(-0.5, 0.5)
        y += rng.uniform(-0.5, 0.5)
        f = f" F{rng.choice((1500, 2000, 3000))}" if rng.random() < 0.02 else ""
        fh.write(f"N{i} X{x:.3f} Y{y:.3f} Z{(i % 997) * 1e-3:.3f}{f}\n")
        x, y = float(f"{x:.3f}"), float(f"{y:.3f}")
        i += 1
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
