#!/bin/sh
# Runs inside the SocketCAN guest (tests/ports/socketcan/run.sh), chrooted
# into the host's root (read-only, /tmp a tmpfs): vcan0 up, the Linux port on
# it, the host tool's checks against it (guest_test.py).
repo=$1
cd "$repo" || { echo "SOCKETCAN: FAIL (no repo)"; exit 0; }
if ! ip link add dev vcan0 type vcan || ! ip link set up vcan0; then
  echo "SOCKETCAN: FAIL (cannot create vcan0)"
  exit 0
fi
echo "guest: vcan0 up"
build/fw/linux/contour-drive --can vcan0 --node 3 --tick-hz 1000 > /tmp/drive.log 2>&1 &
drive=$!
i=0
while ! grep -q ready /tmp/drive.log && [ $i -lt 100 ]; do sleep 0.1; i=$((i + 1)); done
PYTHONDONTWRITEBYTECODE=1 .venv/bin/python tests/ports/socketcan/guest_test.py vcan0 3
kill $drive
wait $drive
echo "guest: drive said: $(tail -n 1 /tmp/drive.log)"
