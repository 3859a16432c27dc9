#!/usr/bin/env bash
# Prints one "name: value unit" line per figure. Each bench/bench-*.sh script
# builds what it measures (with the host compiler, -O2, no sanitizers) and
# prints its own lines; a failing script fails the run.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p build/bench
for script in bench/bench-*.sh; do
  bash "$script"
done
