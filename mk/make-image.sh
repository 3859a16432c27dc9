#!/usr/bin/env bash
# Firmware image next to an ELF: ELF -> .bin (payload), .img (header + payload)
# and .hex (Intel HEX of a validated application slot). Format and layout:
# docs/bootloader.md. Used by `make firmware` for the real targets.
#
#   mk/make-image.sh build/fw/app.elf BOARD VERSION [BUILD_ID_HEX]
#   BOARD: number or sim / stm32f4 / qemu / linux; VERSION: MAJOR.MINOR.PATCH
#   BUILD_ID_HEX defaults to the git commit of the tree (or the payload hash).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -lt 3 ]; then
  echo "usage: $0 ELF BOARD VERSION [BUILD_ID_HEX]" >&2
  exit 2
fi
elf=$1 board=$2 version=$3 build_id=${4:-}
if [ -z "$build_id" ]; then
  build_id=$(git rev-parse HEAD 2>/dev/null | cut -c1-32 || true)
fi
py=.venv/bin/python
[ -x "$py" ] || py=python3
args=(build "$elf" --board "$board" --version "$version" -o "${elf%.elf}.img")
[ -n "$build_id" ] && args+=(--build-id "$build_id")
PYTHONPATH=host_tools${PYTHONPATH:+:$PYTHONPATH} "$py" -m contour.image "${args[@]}"
