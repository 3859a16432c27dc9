#!/usr/bin/env bash
# Flash time of a 64 KiB image into the simulated drive (contour flash, the
# real bootloader against the simulated flash file):
#   flash_seconds_64k_inprocess  bootloader + host tool, no transport (ctypes)
#   flash_seconds_64k_serial     over the serial pseudo-terminal of `contour sim serve`
#   flash_seconds_64k_slcan      over SLCAN (python-can, ISO-TP) of `contour sim serve`
# (the best of two runs each; the pseudo-terminals have no baud-rate limit).
set -euo pipefail
cd "$(dirname "$0")/.."
py=.venv/bin/python
out=build/bench/flash
mkdir -p "$out"
head -c 65536 /dev/urandom > "$out/app64k.bin"
$py -m contour.image build "$out/app64k.bin" --board sim --version 1.0.0 \
  --load-addr 0x08010200 -o "$out/app64k.img" > /dev/null

$py - "$out" <<'PY'
import sys, time
from contour import image as img
from contour.link import boot as fl
from contour.sim.bootsim import SimDriveLink

out = sys.argv[1]
image = img.load(f"{out}/app64k.img")
link = SimDriveLink(f"{out}/inprocess.flash")
t0 = time.perf_counter()
fl.flash(fl.BootClient(link), image, log=lambda s: None)
print(f"flash_seconds_64k_inprocess: {time.perf_counter() - t0:.3f} s")
PY

# The simulated drive in real time (`contour sim serve --flash FILE`, the
# bootloader on a flash file); a first, untimed flash puts an application on
# it, then each timed run is a field update: `contour flash` as a user runs it
# (process start, boot_enter, erase, 64 KiB, read-back CRC, finish, reboot,
# version check).
rm -f "$out/serve.flash"
.venv/bin/contour sim serve --flash "$out/serve.flash" > "$out/serve.log" 2>&1 &
pid=$!
trap 'kill $pid 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  grep -q '^slcan:' "$out/serve.log" 2>/dev/null && break
  sleep 0.1
done
serial=$(sed -n 's/^serial: //p' "$out/serve.log")
slcan=$(sed -n 's/^slcan: //p' "$out/serve.log")
if [ -z "$serial" ] || [ -z "$slcan" ]; then
  echo "bench-flash: contour sim serve printed no serial/slcan path" >&2
  exit 1
fi
$py - "$out/app64k.img" "$serial" "slcan:$slcan" <<'PY'
import subprocess, sys, time
image, serial, can = sys.argv[1:4]

def run(opt):
    t0 = time.perf_counter()
    r = subprocess.run([".venv/bin/contour", "flash", image, *opt, "--no-progress"],
                       capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        sys.exit(f"bench-flash: flash over {opt[0]} failed: {r.stderr.strip()}")
    return time.perf_counter() - t0

run(["--port", serial])  # untimed: the drive now runs an application
for name, opt in (("serial", ["--port", serial]), ("slcan", ["--can", can, "--bitrate", "500000"])):
    print(f"flash_seconds_64k_{name}: {min(run(opt) for _ in range(2)):.2f} s")
PY
