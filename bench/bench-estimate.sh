#!/usr/bin/env bash
# Peak memory of `contour estimate` (planner model, generic profile) on a
# generated one-million-line CAM-style file (N, X, Y, Z words at one feed):
# the resident set of the child process at its largest (getrusage). Issue 17
# asks for under 150 MB.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p build/bench
.venv/bin/python - <<'PY'
import math
import os
import resource
import subprocess
import sys

path = "build/bench/estimate_1m.nc"
n = 1_000_000
with open(path, "w") as fh:
    fh.write("G21 G90 G17 G64\nG1 F3000\n")
    for i in range(n - 2):
        a = i * 1e-3
        fh.write(f"N{i + 10} X{50 * math.cos(a):.3f} Y{50 * math.sin(a):.3f} Z{(i % 997) * 1e-3:.3f}\n")
try:
    subprocess.run(
        [sys.executable, "-m", "contour", "estimate", path, "--profile", "profiles/generic.toml",
         "--json"],
        check=True,
        stdout=subprocess.DEVNULL,
    )
finally:
    os.remove(path)
peak_kb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss  # kB on Linux
print(f"estimate_peak_rss_mb_1m_lines: {peak_kb / 1024:.0f} MB")
PY
