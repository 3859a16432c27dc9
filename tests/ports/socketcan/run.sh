#!/usr/bin/env bash
# make test-socketcan: the Linux port's SocketCAN link, tested inside a QEMU
# guest (these machines' kernel has no CAN). A stock Debian bookworm kernel
# (linux-image-*-amd64) boots under qemu-system-x86_64 with a tiny initramfs
# (busybox-static, the kernel's vcan / can / can-raw and 9p / virtio modules);
# the host's root is shared read-only (-virtfs), so the guest runs the host's
# build/fw/linux/contour-drive on vcan0 and the host tool (.venv python,
# python-can `socketcan` interface) against it: tests/ports/socketcan/guest.sh.
# Packages are fetched once with mk/debian-fetch.sh into .cache/vcan-guest.
# Pass: the guest prints "SOCKETCAN: PASS". Bounded by a timeout (TIMEOUT s).
set -euo pipefail
cd "$(dirname "$0")/../../.."
repo=$PWD
out=build/socketcan
g=.cache/vcan-guest
timeout_s=${TIMEOUT:-180}
mkdir -p "$out"

./mk/firmware.sh linux > "$out/firmware.log"

# kernel + busybox (the kernel package named by the linux-image-amd64 metapackage)
if ! ls $g/debroot/boot/vmlinuz-* > /dev/null 2>&1; then
  ./mk/debian-fetch.sh bookworm "$g/meta" linux-image-amd64 > /dev/null
  kpkg=$(dpkg-deb -f "$(ls -t .cache/debs/linux-image-amd64_*.deb | head -n 1)" Depends |
         sed -n 's/^\(linux-image-[^ ,]*-amd64\).*/\1/p')
  ./mk/debian-fetch.sh bookworm "$g/debroot" "$kpkg" busybox-static > /dev/null
fi
kernel=$(ls $g/debroot/boot/vmlinuz-* | head -n 1)
kver=${kernel##*/vmlinuz-}
moddir=$g/debroot/lib/modules/$kver

# initramfs: busybox, /init, the modules in dependency order
rm -rf "$out/initramfs"
mkdir -p "$out/initramfs"/{bin,dev,proc,sys,host,lib/modules}
cp $g/debroot/bin/busybox "$out/initramfs/bin/busybox"
mods=$(python3 - "$moddir" <<'PY'
import glob, os, sys
d = sys.argv[1]
mods = {os.path.basename(p)[:-3].replace("-", "_"): p
        for p in glob.glob(f"{d}/kernel/**/*.ko", recursive=True)}
def deps(n):
    data = open(mods[n], "rb").read()
    i = data.find(b"\0depends=")
    if i < 0:
        return []
    end = data.index(b"\0", i + 1)
    return [x.replace("-", "_") for x in data[i + 9:end].decode().split(",") if x]
order = []
def visit(n):
    if n in order:
        return
    for x in deps(n):
        visit(x)
    order.append(n)
for n in ("virtio_pci", "9pnet_virtio", "9p", "can_raw", "vcan"):
    visit(n)
print(" ".join(mods[n] for n in order))
PY
)
list=""
for m in $mods; do
  cp "$m" "$out/initramfs/lib/modules/"
  list="$list $(basename "$m")"
done
cat > "$out/initramfs/init" <<INIT
#!/bin/busybox sh
/bin/busybox --install -s /bin
mount -t proc proc /proc
mount -t sysfs sys /sys
mount -t devtmpfs dev /dev
for m in $list; do insmod /lib/modules/\$m || echo "insmod \$m failed"; done
if mount -t 9p -o trans=virtio,version=9p2000.L,ro hostroot /host; then
  mount -t proc proc /host/proc
  mount -t sysfs sys /host/sys
  mount -t devtmpfs dev /host/dev
  # the guest's own /tmp hides the host's: keep the checkout reachable when
  # it lives below /tmp (a bind mount taken before, put back after)
  mkdir -p /repo
  mount -o bind /host$repo /repo
  mount -t tmpfs tmp /host/tmp
  if [ ! -d /host$repo/tests ]; then
    mkdir -p /host$repo && mount -o bind /repo /host$repo
  fi
  chroot /host /bin/sh $repo/tests/ports/socketcan/guest.sh $repo
else
  echo "SOCKETCAN: FAIL (no 9p host root)"
fi
echo "guest: done"
poweroff -f
INIT
chmod +x "$out/initramfs/init"
(cd "$out/initramfs" && find . | cpio -o -H newc --quiet | gzip -1) > "$out/initramfs.cpio.gz"

accel=(-accel tcg)
[ "${SOCKETCAN_KVM:-0}" = 1 ] && accel=(-accel kvm -accel tcg)
start=$(date +%s)
set +e
timeout "$timeout_s" qemu-system-x86_64 "${accel[@]}" -cpu max -m 1024 -smp 1 -nographic -no-reboot \
  -kernel "$kernel" -initrd "$out/initramfs.cpio.gz" \
  -append "console=ttyS0 quiet loglevel=3 panic=-1" \
  -virtfs local,path=/,mount_tag=hostroot,security_model=none,readonly=on \
  -nic none < /dev/null > "$out/guest.log" 2>&1
rc=$?
set -e
grep -E '^(guest|SOCKETCAN|  )' "$out/guest.log" | tr -d '\r' || true
if [ $rc = 124 ]; then
  echo "test-socketcan: the guest did not finish within ${timeout_s} s (log: $out/guest.log)" >&2
  exit 1
fi
if ! grep -q 'SOCKETCAN: PASS' "$out/guest.log"; then
  echo "test-socketcan: FAILED (log: $out/guest.log)" >&2
  exit 1
fi
echo "test-socketcan: passed in $(( $(date +%s) - start )) s"
