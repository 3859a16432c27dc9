"""End to end: `contour flash` against the simulated drive (`contour sim serve
--flash FILE`: the C bootloader of firmware/core/boot on the simulated flash
file) over the serial pseudo-terminal and over SLCAN (python-can's slcan
interface, ISO-TP from can-isotp).

- flashing from an empty drive and from a running application, progress bar,
  read-back CRC, reboot, and the new version confirmed with `contour info`;
- images that do not fit the drive refused before anything is erased (the
  flash file is byte-for-byte unchanged and the old application runs on);
- the host process killed at block boundaries and at random instants, and
  the drive reset (server killed or stopped, restarted on the same flash
  file) in the middle of the transfer: the drive always comes back in its
  bootloader or in the old or new valid application, and a second
  `contour flash` succeeds;
- python-can's transmit-buffer-full condition waited out with back-off.

Every server and host process started here is stopped by the test (context
managers, `finally`); every wait has a timeout.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import random
import re
import select
import signal
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest
from contour import image as img
from contour import protocol_gen as pg
from contour.errors import UserError
from contour.link import boot as fl
from contour.link import connect
from contour.link.transport import open_transport
from contour.sim.serve import spawn
from linkhelp import link_args, run_cli

FLASH_BASE = 0x08010000  # FLASH_SIM_DEFAULT_BASE (hal_flash_sim.h)
LOAD_ADDR = 0x08010200  # slot base + BOOT_IMAGE_HDR_AREA
SLOT_MAX = 228864  # payload capacity of the simulated drive's slot
PROC_TIMEOUT = 30.0
HOST_ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}


def make_image(size: int, version: str, seed: int, **kw) -> img.Image:
    payload = random.Random(seed).randbytes(size)
    return img.build(
        payload,
        board_id=kw.get("board", 1),
        fw_version=img.parse_version(version),
        load_addr=kw.get("load_addr", LOAD_ADDR),
    )


OLD = make_image(12000, "1.0.0", 1)
NEW = make_image(16001, "2.0.0", 2)
BY_VERSION = {OLD.header.fw_version: OLD, NEW.header.fw_version: NEW}


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("flash_e2e")
    out = {}
    for name, image in (("old", OLD), ("new", NEW)):
        out[name] = d / f"{name}.img"
        out[name].write_bytes(image.to_bytes())
    out["dir"] = d
    return out


def serve(flash: Path, window_ms: int = 0):
    return spawn(["--flash", str(flash), "--boot-window-ms", str(window_ms)])


def drive_state(server, timeout: float = 5.0) -> tuple[str, int]:
    """("bootloader", 0) or ("app", running version), by identify."""
    end = time.monotonic() + timeout
    while True:
        try:
            with connect(port=server.serial) as c:
                r = c.identify()
            return ("app", r["fw_version"]) if r["axes"] > 0 else ("bootloader", 0)
        except Exception:  # noqa: BLE001 - a drive that just reset: ask again
            if time.monotonic() > end:
                raise
            time.sleep(0.05)


def slot_payload(flash: Path, length: int) -> bytes:
    off = LOAD_ADDR - FLASH_BASE
    return flash.read_bytes()[off : off + length]


def assert_recoverable(server, flash: Path, allowed: set[int], alive: bool = True):
    """The drive as it is (when its server is alive), then after a power
    cycle (a new server process on the same flash file: the boot decision
    runs again): bootloader, or an allowed version whose payload in flash is
    exactly that image's.
    Returns (new server, state after the power cycle)."""
    if alive:
        mode, version = drive_state(server)
        assert mode == "bootloader" or version in allowed, (mode, version)
    server.stop()
    server = serve(flash)
    try:
        mode, version = drive_state(server)
        assert mode == "bootloader" or version in allowed, (mode, version)
        if mode == "app":
            image = BY_VERSION[version]
            assert slot_payload(flash, image.header.length) == image.payload
    except BaseException:
        server.stop()
        raise
    return server, (mode, version)


def flash_ok(server, path: Path, image: img.Image, capsys, transport="serial"):
    rc, _, err = run_cli(
        ["flash", str(path), *link_args(server, transport), "--no-progress"], capsys
    )
    assert rc == 0, err
    assert f"drive runs version {img.version_str(image.header.fw_version)}" in err
    assert drive_state(server) == ("app", image.header.fw_version)


# ---- the normal update, both transports ------------------------------------------


def test_flash_serial_and_slcan_then_info(files, capsys):
    flash = files["dir"] / "normal.flash"
    with serve(flash, window_ms=200) as server:  # the default connect window
        assert drive_state(server) == ("bootloader", 0)  # a new, empty drive
        # empty drive, over serial; stderr is no terminal here: no progress bar
        rc, _, err = run_cli(["flash", str(files["new"]), "--port", server.serial], capsys)
        assert rc == 0, err
        assert err == "flashed 16001 bytes; drive runs version 2.0.0\n", err
        rc, out, err = run_cli(["info", "--json", "--port", server.serial], capsys)
        assert rc == 0, err
        info = json.loads(out)
        assert info["firmware_version"] == "2.0.0" and info["axes"] == 3
        # the image's, from its header, in the byte order `image info` prints
        assert info["build_id"] == NEW.header.build_id[:4].hex()
        # running application -> boot_enter -> bootloader, over SLCAN
        rc, _, err = run_cli(["flash", str(files["old"]), *link_args(server, "slcan")], capsys)
        assert rc == 0, err
        assert "drive runs version 1.0.0" in err
        rc, out, err = run_cli(["info", "--json", *link_args(server, "slcan")], capsys)
        assert rc == 0, err
        assert json.loads(out)["firmware_version"] == "1.0.0"
        # --verify-only: matches the image in flash, refuses another one
        rc, _, err = run_cli(
            ["flash", str(files["old"]), "--port", server.serial, "--verify-only"], capsys
        )
        assert rc == 0 and "verified: drive holds version 1.0.0" in err, err
        rc, _, err = run_cli(
            ["flash", str(files["new"]), "--port", server.serial, "--verify-only"], capsys
        )
        assert rc == 1 and "drive does not hold this image" in err
    assert slot_payload(flash, OLD.header.length) == OLD.payload


def test_flash_file_of_wrong_size_refused(tmp_path):
    p = tmp_path / "short.flash"
    p.write_bytes(b"\xff" * 1000)
    with pytest.raises(UserError, match="1000 bytes; a simulated flash file is 262144 bytes"):
        serve(p).stop()
    assert p.read_bytes() == b"\xff" * 1000


# ---- images that do not fit: refused before anything is erased -------------------


@pytest.mark.parametrize("transport", ["serial", "slcan"])
def test_bad_images_refused_before_erase(files, transport, capsys):
    flash = files["dir"] / f"refuse-{transport}.flash"
    d = files["dir"]
    cases = {
        "board": (
            make_image(4096, "3.0.0", 3, board=2),
            "image is for board 2, the drive is board 1: refusing to flash",
        ),
        "load": (
            make_image(4096, "3.0.0", 4, load_addr=0x08020000),
            "image is linked for load address 0x08020000, the drive's application starts at "
            "0x08010200: refusing to flash",
        ),
        "oversize": (
            make_image(SLOT_MAX + 8, "3.0.0", 5),
            f"image payload is {SLOT_MAX + 8} bytes, the drive's application slot holds "
            f"{SLOT_MAX}: refusing to flash",
        ),
    }
    good = NEW.to_bytes()
    corrupt = bytearray(good)
    corrupt[300] ^= 0x01
    files_bad = {
        "crc": (bytes(corrupt), "image payload CRC mismatch"),
        "truncated": (good[:-100], "truncated image: header announces 16001 payload bytes"),
        "trailing": (good + b"\0", "image has 1 bytes after the 16001-byte payload"),
        "header": (b"\0" * 4 + good[4:], "not a contour firmware image"),
    }
    with serve(flash) as server:
        flash_ok(server, files["old"], OLD, capsys, transport)
        before = flash.read_bytes()
        for name, (image, message) in cases.items():
            p = d / f"{name}.img"
            p.write_bytes(image.to_bytes())
            rc, _, err = run_cli(["flash", str(p), *link_args(server, transport)], capsys)
            assert rc == 1 and message in err, (name, err)
            assert "Traceback" not in err
            assert flash.read_bytes() == before, name  # not one page erased
            assert drive_state(server) == ("app", OLD.header.fw_version), name
        for name, (data, message) in files_bad.items():
            p = d / f"bad-{name}.img"
            p.write_bytes(data)
            rc, _, err = run_cli(["flash", str(p), *link_args(server, transport)], capsys)
            assert rc == 1 and message in err, (name, err)
            assert flash.read_bytes() == before, name
        assert drive_state(server) == ("app", OLD.header.fw_version)


# ---- the host process killed ------------------------------------------------------

# Runs `contour flash` and SIGKILLs its own process at the chosen message:
# "before" it is sent, or just "after" (request on the wire, no host to
# read the reply).
RUNNER = r"""
import os, signal, sys, time
from contour import cli
from contour import protocol_gen as pg
from contour.link import boot as fl

name, nth, when = sys.argv[1], int(sys.argv[2]), sys.argv[3]
if nth <= 0:  # counted from the last block of the image being flashed
    from contour import image as img
    nth += -(-img.load(sys.argv[5]).header.length // 224)
seen = {}
orig = fl.TransportLink.exchange

def exchange(self, msg, timeout):
    m = pg.MSG_BY_ID[msg[0]].name
    seen[m] = seen.get(m, 0) + 1
    if m == name and seen[m] == nth:
        if when == "after":
            self.t.send(msg)
            time.sleep(0.05)  # let CAN's ISO-TP thread put it on the bus
        os.kill(os.getpid(), signal.SIGKILL)
    return orig(self, msg, timeout)

fl.TransportLink.exchange = exchange
sys.exit(cli.main(sys.argv[4:]))
"""

# (message, occurrence (0: the last block), before/after, transport).
KILL_POINTS = [
    ("boot_connect", 1, "before", "serial"),
    ("boot_erase", 1, "before", "serial"),
    ("boot_erase", 1, "after", "slcan"),
    ("boot_write", 1, "before", "serial"),
    ("boot_write", 37, "after", "slcan"),
    ("boot_write", 0, "after", "serial"),
    ("boot_crc", 1, "before", "slcan"),
    ("boot_finish", 1, "after", "serial"),
    ("boot_reboot", 1, "before", "slcan"),
]


def run_killed(argv: list[str]) -> int:
    p = subprocess.run(
        [sys.executable, "-c", RUNNER, *argv],
        capture_output=True,
        timeout=PROC_TIMEOUT,
        env=HOST_ENV,
    )
    return p.returncode


def test_host_killed_at_block_boundaries(files, capsys):
    """The flash alternates between OLD and NEW; at each point the host dies,
    the drive is checked as it is and after a power cycle, then flashed again."""
    flash = files["dir"] / "killed.flash"
    outcomes = []
    server = serve(flash)
    try:
        flash_ok(server, files["old"], OLD, capsys)
        current, other = OLD, NEW
        for name, nth, when, transport in KILL_POINTS:
            target = files["new"] if other is NEW else files["old"]
            rc = run_killed(
                [name, str(nth), when, "flash", str(target), *link_args(server, transport)]
            )
            assert rc == -signal.SIGKILL, (name, nth, when, rc)
            allowed = {current.header.fw_version, other.header.fw_version}
            server, state = assert_recoverable(server, flash, allowed)
            outcomes.append((name, nth, when, transport, state))
            flash_ok(server, target, other, capsys, transport)  # the second flash
            current, other = other, current
    finally:
        server.stop()
    with capsys.disabled():  # the figures of docs/bootloader.md (pytest -s)
        print("\nhost killed:", outcomes)
    expected = {
        ("boot_connect", "before"): "app",  # nothing happened yet
        ("boot_erase", "before"): "app",  # in the bootloader, old image intact
        ("boot_erase", "after"): "bootloader",
        ("boot_write", "before"): "bootloader",
        ("boot_crc", "before"): "bootloader",
        ("boot_finish", "after"): "app",  # finished: the new image is valid
        ("boot_reboot", "before"): "app",
    }
    for name, _nth, when, _t, (mode, _v) in outcomes:
        if (name, when) in expected:
            assert mode == expected[(name, when)], (name, when, mode)


def test_host_killed_at_random_instants(files, capsys):
    big = files["dir"] / "big.img"
    image = make_image(65536, "4.0.0", 7)
    big.write_bytes(image.to_bytes())
    BY_VERSION[image.header.fw_version] = image
    flash = files["dir"] / "random.flash"
    rng = random.Random(11)
    server = serve(flash)
    try:
        flash_ok(server, files["old"], OLD, capsys)
        for i, transport in enumerate(["serial", "slcan", "serial", "slcan"]):
            target_pct = rng.randint(2, 97)
            # stderr on a terminal (the bar is drawn on terminals only), 120 columns
            master, slave = os.openpty()
            fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 120, 0, 0))
            proc = subprocess.Popen(
                [sys.executable, "-m", "contour", "flash", str(big), *link_args(server, transport)],
                stdout=subprocess.DEVNULL,
                stderr=slave,
                env={**HOST_ENV, "TQDM_MININTERVAL": "0"},  # a progress line per block
            )
            os.close(slave)
            pct = -1
            try:
                # follow the progress bar; kill the host once it passes target_pct
                end = time.monotonic() + PROC_TIMEOUT
                seen = b""
                while pct < target_pct and proc.poll() is None:
                    assert time.monotonic() < end, "contour flash made no progress"
                    if select.select([master], [], [], 0.5)[0]:
                        with contextlib.suppress(OSError):  # EIO once the process is gone
                            seen = seen[-200:] + os.read(master, 65536)
                        pcts = re.findall(rb"(\d+)%\|", seen)
                        pct = int(pcts[-1]) if pcts else pct
                proc.kill()
            finally:
                proc.wait(timeout=PROC_TIMEOUT)
                os.close(master)
            assert proc.returncode == -signal.SIGKILL, "the flash ended before the kill"
            server, state = assert_recoverable(
                server, flash, {OLD.header.fw_version, image.header.fw_version}
            )
            with capsys.disabled():
                print(f"\nrandom kill {i} ({transport}) at {pct} %: {state}")
            assert state == ("bootloader", 0)  # killed after the erase, before the finish
            target, timg = (
                (files["old"], OLD) if state[1] == image.header.fw_version else (big, image)
            )
            flash_ok(server, target, timg, capsys, transport)
    finally:
        server.stop()


# ---- the drive reset in the middle of the transfer --------------------------------


class DriveReset(Exception):
    pass


class ResetAt:
    """Sends the n-th boot_write, then resets the drive (stops its server)."""

    def __init__(self, inner: fl.TransportLink, n: int, reset) -> None:
        self.inner, self.n, self.reset, self.writes = inner, n, reset, 0

    def exchange(self, msg: bytes, timeout: float):
        if msg[0] == pg.MSG_BY_NAME["boot_write"].id:
            self.writes += 1
            if self.writes == self.n:
                self.inner.t.send(msg)
                time.sleep(0.002)
                self.reset()
                raise DriveReset()
        return self.inner.exchange(msg, timeout)


# The host's SLCAN adapter vanishes with the server process: python-can's
# notifier thread then ends with "Could not read from serial device".
@pytest.mark.filterwarnings("ignore::pytest.PytestUnhandledThreadExceptionWarning")
@pytest.mark.parametrize(
    "transport,block,how",
    [("serial", 3, "kill"), ("slcan", 40, "kill"), ("serial", 71, "term")],
)
def test_drive_reset_mid_write(files, transport, block, how, capsys):
    flash = files["dir"] / f"reset-{transport}-{block}.flash"
    server = serve(flash)
    try:
        flash_ok(server, files["old"], OLD, capsys)

        def reset() -> None:
            if how == "kill":
                server.proc.kill()  # power lost: no chance to finish anything
            else:
                server.proc.send_signal(signal.SIGTERM)

        spec = (
            {"port": server.serial}
            if transport == "serial"
            else {"can": link_args(server, "slcan")[1]}
        )
        link = fl.TransportLink(open_transport(node=1, **spec))
        try:
            with pytest.raises(DriveReset):
                fl.flash(fl.BootClient(ResetAt(link, block, reset)), NEW, log=lambda s: None)
        finally:
            with contextlib.suppress(Exception):
                link.close()
        server.proc.wait(timeout=PROC_TIMEOUT)
        server, (mode, _) = assert_recoverable(server, flash, {OLD.header.fw_version}, False)
        assert mode == "bootloader"  # the erase made the old image invalid first
        flash_ok(server, files["new"], NEW, capsys, transport)
    finally:
        server.stop()


# ---- python-can: transmit buffer full ---------------------------------------------


def test_can_transmit_buffer_full_is_waited_out(files, capsys, monkeypatch):
    import can
    from can.interfaces.slcan import slcanBus

    calls = {"n": 0, "full": 0}
    real_send = slcanBus.send

    def send(self, msg, timeout=None):
        calls["n"] += 1
        if calls["n"] % 25 < 3:  # bursts of three refusals
            calls["full"] += 1
            raise can.CanOperationError("Transmit buffer full")
        return real_send(self, msg, timeout)

    flash = files["dir"] / "txfull.flash"
    with serve(flash) as server:
        monkeypatch.setattr(slcanBus, "send", send)
        t0 = time.monotonic()
        flash_ok(server, files["new"], NEW, capsys, "slcan")
        monkeypatch.undo()
        assert calls["full"] > 100  # every frame of the transfer went out in the end
        assert time.monotonic() - t0 < 20


def test_scan_and_info_find_a_drive_in_its_bootloader(tmp_path, capsys):
    """An erased flash keeps the drive in its bootloader, which sends a CAN
    heartbeat: the passive scan lists it with state bootloader."""
    with serve(tmp_path / "erased.bin") as server:
        assert drive_state(server) == ("bootloader", 0)
        rc, out, err = run_cli(
            ["scan", "--can", f"slcan:{server.slcan}@500000", "--time", "2.5", "--json"], capsys
        )
        assert rc == 0, err
        nodes = json.loads(out)
        assert [n["node"] for n in nodes] == [1]
        assert nodes[0]["state"] == "bootloader" and nodes[0]["axes"] == 0
        for transport in ("serial", "slcan"):
            rc, out, err = run_cli(["info", "--json", *link_args(server, transport)], capsys)
            assert rc == 0, err
            info = json.loads(out)
            assert info["state"] == "bootloader" and info["board_id"] == 1, info
