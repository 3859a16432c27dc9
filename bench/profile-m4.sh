#!/usr/bin/env bash
# profile-m4.sh tick|planner|splanner|uplanner|vplanner [TOP] (planner: the planner workload
# with the default continuous S-curve; splanner: with the per-block S-curve;
# uplanner, vplanner: the same two with Z's a and j at half of X/Y's)
# Flat instruction profile of one workload of the QEMU benchmark image
# (bench_mps2.c) on the Cortex-M4 instruction set: QEMU runs one instruction
# per translation block and logs each execution; the log is counted per
# function (instructions, calls = entries at the function's first address).
# The whole workload is counted, including the simulated axes between ticks
# (plant_*, axis_*, soft-float helpers) and the timing code around each call.
# A development tool, not a figure of `make bench` (slow: ~1 s per 2 M lines).
set -euo pipefail
cd "$(dirname "$0")/.."
what=${1:?usage: profile-m4.sh tick|planner|splanner|uplanner|vplanner [TOP]}
top=${2:-30}
case $what in tick|planner|splanner|uplanner|vplanner) ;; *) echo "profile-m4: unknown workload '$what'" >&2; exit 2;; esac
[ -f build/fw/mps2_an386/bench.elf ] || ./mk/firmware.sh >/dev/null
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkfifo "$tmp/log"
arm-none-eabi-nm build/fw/mps2_an386/bench.elf > "$tmp/syms"
python3 - "$tmp/log" "$tmp/syms" "$top" <<'PY' &
import collections, sys
log, syms, top = sys.argv[1], sys.argv[2], int(sys.argv[3])
start = {}
for line in open(syms):
    f = line.split()
    if len(f) == 3 and f[1] in "tTwW":
        start[int(f[0], 16) & ~1] = f[2]
count = collections.Counter()
calls = collections.Counter()
with open(log) as fh:
    for line in fh:
        if not line.startswith("Trace"):
            continue
        b = line.index("[")
        pc = int(line[b + 10:b + 18], 16)
        name = line.rsplit(None, 1)[-1]
        count[name] += 1
        if start.get(pc) == name:
            calls[name] += 1
total = sum(count.values())
print(f"{'function':32s} {'instr':>10s} {'%':>6s} {'calls':>8s} {'per call':>9s}")
for name, n in count.most_common(top):
    c = calls[name]
    per = f"{n / c:9.1f}" if c else " " * 9
    print(f"{name:32s} {n:10d} {100 * n / total:6.2f} {c:8d} {per}")
print(f"{'total':32s} {total:10d}")
PY
py=$!
timeout 600 qemu-system-arm -M mps2-an386 -nographic -monitor none -serial stdio \
  -icount shift=0 -semihosting-config enable=on,target=native,arg="$what" \
  -kernel build/fw/mps2_an386/bench.elf -singlestep -d exec,nochain -D "$tmp/log" >&2
wait "$py"
