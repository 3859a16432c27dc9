#!/usr/bin/env bash
# run.sh [RUNS]: builds the libFuzzer harnesses with Debian's clang and runs
# each for RUNS executions (default 1000000) from the kept corpus
# (tests/fuzz/corpus/<name>, copied to a scratch corpus under build/fuzz so
# the repository does not grow on every run). FUZZ_MERGE=1 merges the new
# interesting inputs back into the kept corpus (minimised).
set -euo pipefail
cd "$(dirname "$0")/../.."
runs=${1:-1000000}
out=build/fuzz; mkdir -p "$out"
core=$(find firmware/core -name '*.c' | sort)
hil=$(ls hil_sim/*.c firmware/ports/sim/*.c)
flags=(-std=c99 -g -O1 -D_DEFAULT_SOURCE -fsanitize=fuzzer,address,undefined
       -fno-sanitize-recover=all -Ifirmware/core -Ifirmware/hal -Ifirmware -Ihil_sim
       -Ifirmware/ports/sim)
clang "${flags[@]}" -o "$out/fuzz_frame" tests/fuzz/fuzz_frame.c \
  firmware/core/proto_frame.c firmware/core/proto_isotp.c firmware/core/proto_msgs.c \
  firmware/core/crc.c
# shellcheck disable=SC2086
clang "${flags[@]}" -o "$out/fuzz_dispatch" tests/fuzz/fuzz_dispatch.c $core $hil -lm
# shellcheck disable=SC2086
clang "${flags[@]}" -o "$out/fuzz_batch" tests/fuzz/fuzz_batch.c $core $hil -lm
clang "${flags[@]}" -o "$out/fuzz_canopen" tests/fuzz/fuzz_canopen.c firmware/core/canopen.c \
  firmware/core/canopen_od.c firmware/core/co_od.c firmware/core/co_pdo.c firmware/core/co_sync.c \
  firmware/core/co_emcy.c firmware/core/co_hb.c
clang "${flags[@]}" -o "$out/fuzz_comp2d" tests/fuzz/fuzz_comp2d.c firmware/core/comp2d.c \
  firmware/core/comp2d_live.c
for name in frame dispatch batch canopen comp2d; do
  work=$out/corpus_$name; mkdir -p "$work"
  cp -n tests/fuzz/corpus/$name/* "$work"/ 2>/dev/null || true
  log=$out/fuzz_$name.log
  max_len=1024; [ "$name" = comp2d ] && max_len=2048 # a full 12 x 12 map: 1764 bytes
  "$out/fuzz_$name" -runs="$runs" -max_len=$max_len -timeout=10 -print_final_stats=1 \
    "$work" >"$log" 2>&1 || { tail -n 40 "$log"; echo "fuzz: $name FAILED (log $log)"; exit 1; }
  execs=$(grep -E '^stat::number_of_executed_units' "$log" | awk '{print $2}')
  cov=$(grep -E '^#[0-9]+.*DONE' "$log" | sed -E 's/.*cov: ([0-9]+).*/\1/' | tail -n 1)
  echo "fuzz: $name: ${execs:-?} executions, coverage ${cov:-?} edges, no crash"
  if [ "${FUZZ_MERGE:-0}" = 1 ]; then
    "$out/fuzz_$name" -merge=1 tests/fuzz/corpus/$name "$work" >/dev/null 2>&1
  fi
done
