#!/usr/bin/env bash
# Figures of the cross-compiled firmware (docs/ports.md):
#   firmware_flash_bytes, firmware_ram_bytes   STM32F4 application image
#       (text + data; data + bss), from arm-none-eabi-size
#   control_tick_instructions_m4 (_max)        drive_tick(), three axes running a helix
#   planner_block_instructions_m4              plan_push + plan_pop per block, ring full
#       measured on the Cortex-M4 instruction set: the QEMU board's benchmark
#       image under qemu-system-arm -icount (1 instruction = 1 ns of virtual
#       time, read on the board's 25 MHz timer, calibrated in the image).
set -euo pipefail
cd "$(dirname "$0")/.."
./mk/firmware.sh > build/bench/firmware-build.log
read -r text data bss _ < <(arm-none-eabi-size build/fw/stm32f4/app.elf | tail -n 1)
echo "firmware_flash_bytes: $((text + data)) bytes"
echo "firmware_ram_bytes: $((data + bss)) bytes"
out=$(timeout 120 qemu-system-arm -M mps2-an386 -nographic -monitor none -serial stdio \
        -icount shift=0 -semihosting-config enable=on,target=native \
        -kernel build/fw/mps2_an386/bench.elf)
if ! grep -q '^control_tick_instructions_m4:' <<< "$out" ||
   ! grep -q '^planner_block_instructions_m4:' <<< "$out"; then
  echo "bench-firmware: the QEMU benchmark image failed:" >&2
  echo "$out" >&2
  exit 1
fi
# a count of 0 means the measurement failed (no call measured, or the
# calibration failed): no figure then, and a failed bench
if grep -qE '^[a-z0-9_]+: 0 (instr|ticks)$' <<< "$out"; then
  echo "bench-firmware: a measurement counted nothing:" >&2
  grep -E '^[a-z0-9_]+: 0 (instr|ticks)$' <<< "$out" >&2
  exit 1
fi
grep -E '^[a-z0-9_]+: [0-9]+ [a-z]+$' <<< "$out"
