#!/usr/bin/env bash
# firmware.sh [BOARD...] - cross-compiles the real-target images with Debian's
# arm-none-eabi-gcc (newlib-nano for memcpy/memset and, on the QEMU board,
# libm for the simulated axes) into build/fw/<board>/:
#   boot.elf/.bin/.hex   bootloader (flashed once by a programmer / -kernel)
#   app.elf              application, and with mk/make-image.sh
#   app.bin/.img/.hex    payload, flashable image (header), validated-slot HEX
#   bench.elf            (mps2_an386) the -icount benchmark image
# then prints the size report (arm-none-eabi-size). Boards: stm32f4,
# mps2_an386 (default: both), linux (build/fw/linux/contour-drive and
# contour-drive-fake, host compiler). Sources: docs/ports.md.
set -euo pipefail
shopt -s inherit_errexit
cd "$(dirname "$0")/.."
boards=("$@")
[ ${#boards[@]} -eq 0 ] && boards=(stm32f4 mps2_an386)
version=$(sed -n 's/^version *= *"\(.*\)"/\1/p' host_tools/pyproject.toml | head -n 1)
version=${FW_VERSION:-${version:-0.1.0}}

CC=arm-none-eabi-gcc
ARCH=(-mcpu=cortex-m4 -mthumb -mfloat-abi=soft)
CFLAGS=(-std=c99 -Wall -Wextra -Werror -pedantic -O2 -g -ffunction-sections -fdata-sections
        "${ARCH[@]}" -Ifirmware/core -Ifirmware/hal -Ifirmware -Ifirmware/ports/common)
LDFLAGS=("${ARCH[@]}" -nostartfiles --specs=nano.specs --specs=nosys.specs -Wl,--gc-sections)

core_src=$(find firmware/core -name '*.c' | sort)
common_src=$(ls firmware/ports/common/*.c)

# compile SRC OBJ [extra flags...] (only when the object is older than its inputs)
compile() {
  local src=$1 obj=$2; shift 2
  local dep=${obj%.o}.d
  if [ -f "$obj" ] && [ -f "$dep" ]; then
    local stale=0 f
    for f in $(sed -e 's/^[^:]*://' -e 's/\\$//' "$dep"); do
      [ "$f" -nt "$obj" ] && { stale=1; break; }
    done
    [ $stale = 0 ] && return 0
  fi
  mkdir -p "$(dirname "$obj")"
  $CC "${CFLAGS[@]}" "$@" -MMD -MF "$dep" -c "$src" -o "$obj"
}

# objects DIR EXTRA_FLAGS... -- SRC...: prints the object paths
objects() {
  local dir=$1; shift
  local flags=()
  while [ "$1" != "--" ]; do flags+=("$1"); shift; done
  shift
  local s o
  for s in "$@"; do
    o=$dir/$(echo "${s%.c}" | tr / _).o
    compile "$s" "$o" "${flags[@]}"
    echo "$o"
  done
}

# link OUT.elf LDSCRIPT OBJS... (libcore.a of the board - the core and the
# shared port code, pulled in only where referenced - and the C libraries last)
link() {
  local out=$1 ld=$2; shift 2
  local lib=$(dirname "$out")/libcore.a
  $CC "${LDFLAGS[@]}" -L"$(dirname "$ld")" -T"$ld" -Wl,-Map="${out%.elf}.map" -o "$out" "$@" \
    -Wl,--start-group "$lib" -lc -lm -lgcc -Wl,--end-group
}

libcore() {
  local dir=$1; shift
  local objs
  objs=$(objects "$dir/core" "$@" -- $core_src $common_src)
  rm -f "$dir/libcore.a"
  arm-none-eabi-ar rcs "$dir/libcore.a" $objs
}

bootbin() { # ELF: raw binary + HEX of a bootloader
  arm-none-eabi-objcopy --gap-fill 0xff -O binary "$1" "${1%.elf}.bin"
  arm-none-eabi-objcopy -O ihex "$1" "${1%.elf}.hex"
}

build_mps2() {
  local d=build/fw/mps2_an386 p=firmware/ports/mps2_an386
  local bflags=(-I$p -Ihil_sim)
  mkdir -p "$d"
  libcore "$d" "${bflags[@]}"
  local common plant
  common=$(objects "$d/port" "${bflags[@]}" -- $p/hal_mps2.c $p/vectors_mps2.c)
  # the simulated axes: hil_sim's model (doubles, soft-float) as the board's hardware
  plant=$(objects "$d/plant" "${bflags[@]}" -std=gnu99 -Wno-pedantic -- \
          hil_sim/axis_model.c $p/plant_mps2.c)
  link "$d/boot.elf" $p/mps2_boot.ld $common $(objects "$d/port" "${bflags[@]}" -- $p/boot_mps2.c)
  bootbin "$d/boot.elf"
  link "$d/app.elf" $p/mps2_app.ld $common $plant $(objects "$d/port" "${bflags[@]}" -- $p/app_mps2.c)
  ./mk/make-image.sh "$d/app.elf" qemu "$version" > /dev/null
  link "$d/bench.elf" $p/mps2_bench.ld $common $plant $(objects "$d/port" "${bflags[@]}" -- $p/bench_mps2.c)
}

build_stm32f4() {
  local d=build/fw/stm32f4 p=firmware/ports/stm32f4
  local bflags=(-I$p)
  mkdir -p "$d"
  libcore "$d" "${bflags[@]}"
  local common
  common=$(objects "$d/port" "${bflags[@]}" -- $p/hal_stm32f4.c $p/vectors_stm32f4.c)
  link "$d/boot.elf" $p/stm32f4_boot.ld $common $(objects "$d/port" "${bflags[@]}" -- $p/boot_stm32f4.c)
  bootbin "$d/boot.elf"
  link "$d/app.elf" $p/stm32f4_app.ld $common $(objects "$d/port" "${bflags[@]}" -- $p/app_stm32f4.c)
  ./mk/make-image.sh "$d/app.elf" stm32f4 "$version" > /dev/null
}

# The Linux board: the drive as a process (host compiler), against the real
# libgpiod v2 headers and library from Debian bookworm-backports (fetched into
# .cache/gpiod), plus contour-drive-fake linked with the link-time fake of
# tests/ports/gpiod_fake.c instead of libgpiod (for machines without GPIO).
build_linux() {
  local d=build/fw/linux p=firmware/ports/linux g=.cache/gpiod
  if [ ! -f $g/usr/include/gpiod.h ]; then
    ./mk/debian-fetch.sh bookworm-backports $g libgpiod-dev libgpiod3 > /dev/null
  fi
  local gl
  gl=$(dirname "$(find $g -name 'libgpiod.so.3' | head -n 1)")
  local hcc=${HOSTCC:-cc}
  local v=(${version//./ })
  local hflags=(-std=c99 -D_GNU_SOURCE -Wall -Wextra -Werror -pedantic -O2 -g
                -Ifirmware/core -Ifirmware/hal -Ifirmware -Ifirmware/ports/common -I$p -I$g/usr/include
                -DPORT_FW_VERSION="$(( ${v[0]} << 16 | ${v[1]} << 8 | ${v[2]} ))u")
  local src=($core_src $p/hal_linux.c $p/main_linux.c)
  mkdir -p "$d"
  # up to date: both binaries newer than every source, header and this script
  if [ -x "$d/contour-drive" ] && [ -x "$d/contour-drive-fake" ] &&
     [ -z "$(find firmware/core firmware/hal firmware/ports/common $p tests/ports/gpiod_fake.c \
               mk/firmware.sh host_tools/pyproject.toml -newer "$d/contour-drive-fake" \
               \( -name '*.[ch]' -o -name '*.sh' -o -name '*.toml' \) | head -n 1)" ]; then
    return 0
  fi
  $hcc "${hflags[@]}" -o "$d/contour-drive" "${src[@]}" -L"$gl" -Wl,-rpath,"$PWD/$gl" -lgpiod
  $hcc "${hflags[@]}" -o "$d/contour-drive-fake" "${src[@]}" tests/ports/gpiod_fake.c
}

for b in "${boards[@]}"; do
  case $b in
    mps2_an386) build_mps2 ;;
    stm32f4) build_stm32f4 ;;
    linux) build_linux; echo "firmware: linux (version $version): build/fw/linux/contour-drive{,-fake}"; continue ;;
    *) echo "firmware.sh: unknown board $b (stm32f4, mps2_an386, linux)" >&2; exit 2 ;;
  esac
  echo "firmware: $b (version $version)"
  arm-none-eabi-size build/fw/$b/boot.elf build/fw/$b/app.elf | sed 's/^/  /'
done
