#!/usr/bin/env bash
# Compiles every firmware/core source for Cortex-M4 (no link) with warnings as
# errors and soft-float, then fails if any object calls a floating-point helper:
# the control code must be integer only.
set -euo pipefail
out=build/m4-check; mkdir -p "$out"
flags=(-std=c99 -Wall -Wextra -Werror -pedantic -mcpu=cortex-m4 -mthumb -mfloat-abi=soft
       -O2 -ffreestanding -Ifirmware/core -Ifirmware/hal -Ifirmware)
n=0
for src in "$@"; do
  obj=$out/$(echo "${src%.c}" | tr / _).o
  arm-none-eabi-gcc "${flags[@]}" -c "$src" -o "$obj"
  fp=$(arm-none-eabi-nm -u "$obj" | grep -E '__aeabi_[fd](add|sub|mul|div|cmp|2|to)|__aeabi_[ifu]2[fd]|__aeabi_l2[fd]|__aeabi_ul2[fd]' || true)
  if [ -n "$fp" ]; then
    echo "m4-check: $src uses floating point:"; echo "$fp"; exit 1
  fi
  n=$((n + 1))
done
echo "m4-check: $n core sources compile for cortex-m4, integer only"
