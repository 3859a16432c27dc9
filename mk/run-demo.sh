#!/usr/bin/env bash
# The main job on the simulated drive (see README). Grows with the product.
set -euo pipefail
cd "$(dirname "$0")/.."
if .venv/bin/contour sim --help >/dev/null 2>&1; then
  exec .venv/bin/contour sim demo --out out/demo
fi
echo "make run: the simulator (hil_sim) is not built yet; running what exists:"
.venv/bin/contour --help
bash bench/bench-fixmath.sh
