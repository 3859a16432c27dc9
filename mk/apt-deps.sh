#!/usr/bin/env bash
# Installs the Debian packages the build needs, only those missing.
# Uses the machine's own apt configuration; run as root (CI and dev machines are).
set -euo pipefail
# libclang-rt-dev: compiler-rt of the default clang (libFuzzer and the
# sanitizer runtimes `make fuzz` and the short fuzz run of `make test` link).
pkgs=(build-essential clang libclang-rt-dev clang-format cppcheck valgrind
      gcc-arm-none-eabi libnewlib-arm-none-eabi binutils-arm-none-eabi
      qemu-system-arm qemu-system-x86 python3-venv socat cpio)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
echo "apt: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO=sudo; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
