"""`contour sim serve`: the simulated drive in real time on two pseudo-terminals.

Design (Python orchestrating the C simulator, no C program of its own): one
thread runs a loop every ~1 ms of wall time:

1. bytes arriving on the serial pty go to the simulated UART
   (``hal_sim_uart_inject``); SLCAN lines arriving on the SLCAN pty are
   parsed (the Lawicel ASCII protocol python-can's ``slcan`` interface and
   USB-CAN adapters speak) and their frames go to the simulated CAN
   controller (``hal_sim_can_inject``);
2. the firmware's own host link runs (``proto_link_poll`` of
   firmware/core/proto_link.c: framing, ISO-TP, dispatcher, watchdog,
   telemetry), exactly as a drive's background loop would;
3. the simulator advances as many control ticks as the wall clock says
   (``sim_run``: drive_tick + drive_poll + the axis models), in chunks of at
   most 50 ms so a stall never turns into a runaway;
4. the link runs again and what the drive sent (``hal_sim_uart_drain``,
   ``hal_sim_can_drain``) goes to the ptys (CAN frames as SLCAN ``t`` lines).

Everything the drive does is the firmware core's code through the sim HAL;
the protocol clock (watchdog, telemetry periods) is the simulated clock, which
tracks the wall clock. The process prints ``serial: PATH`` and ``slcan: PATH``
on their own lines (flushed) and runs until SIGINT/SIGTERM.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import os
import select
import signal
import subprocess
import sys
import threading
import time
import tty
import zlib
from typing import Optional

from contour import __version__
from contour import protocol_gen as pg
from contour.errors import UserError

BOARD_SIM = 1  # BOOT_BOARD_SIM in firmware/core/boot/boot.h
MAX_BACKLOG = 256 * 1024


class Identity(ctypes.Structure):
    """proto_identity_t of firmware/core/proto_dispatch.h."""

    _fields_ = [
        ("fw_version", ctypes.c_uint32),
        ("build_id", ctypes.c_uint32),
        ("capabilities", ctypes.c_uint32),
        ("tick_hz", ctypes.c_uint32),
        ("board_id", ctypes.c_uint32),
        ("planner_slots", ctypes.c_uint16),
        ("node_id", ctypes.c_uint8),
        ("axes", ctypes.c_uint8),
    ]


def fw_version() -> int:
    parts = [int(x) for x in __version__.split(".")[:3]]
    parts += [0] * (3 - len(parts))
    return parts[0] << 16 | parts[1] << 8 | parts[2]


def _bind(lib: ctypes.CDLL) -> None:
    c = ctypes
    sig = {
        "sim_setup": (c.c_int, [c.c_double, c.c_uint]),
        "sim_start": (c.c_int, []),
        "sim_run": (c.c_long, [c.c_uint64, c.c_void_p, c.c_size_t, c.c_uint]),
        "proto_link_init": (c.c_bool, [c.POINTER(Identity), c.c_bool, c.c_bool]),
        "proto_link_poll": (None, []),
        "hal_sim_uart_inject": (c.c_size_t, [c.c_char_p, c.c_size_t]),
        "hal_sim_uart_drain": (c.c_size_t, [c.c_char_p, c.c_size_t]),
        "hal_sim_can_inject": (c.c_bool, [c.c_uint32, c.c_char_p, c.c_uint8]),
        "hal_sim_can_drain": (
            c.c_bool,
            [c.POINTER(c.c_uint32), c.c_char_p, c.POINTER(c.c_uint8)],
        ),
    }
    for name, (res, args) in sig.items():
        fn = getattr(lib, name)
        fn.restype = res
        fn.argtypes = args


class SlcanParser:
    """The drive side of SLCAN (Lawicel ASCII): commands in, replies out."""

    BITRATES = {f"S{i}" for i in range(9)}

    def __init__(self) -> None:
        self.buf = bytearray()
        self.open = False
        self.frames_in = 0
        self.errors = 0

    def feed(self, data: bytes) -> tuple[list[tuple[int, bytes]], bytes]:
        """Returns (frames to put on the bus, bytes to answer)."""
        frames, reply = [], bytearray()
        self.buf += data
        while True:
            i = self.buf.find(b"\r")
            if i < 0:
                if len(self.buf) > 64:  # garbage with no terminator
                    self.buf.clear()
                    self.errors += 1
                break
            line = bytes(self.buf[:i]).decode("ascii", "replace").strip("\n")
            del self.buf[: i + 1]
            f, r = self._command(line)
            if f is not None:
                frames.append(f)
            reply += r
        return frames, bytes(reply)

    def _command(self, line: str) -> tuple[Optional[tuple[int, bytes]], bytes]:
        if not line:
            return None, b"\r"
        c = line[0]
        if c in "OL":
            self.open = True
            return None, b"\r"
        if c == "C":
            self.open = False
            return None, b"\r"
        if line in self.BITRATES or c in "sYZMmX":
            return None, b"\r"
        if c == "V":
            return None, b"V1013\r"
        if c == "v":
            return None, b"v0100\r"
        if c == "N":
            return None, b"NSIM1\r"
        if c == "F":
            return None, b"F00\r"
        if c in "tT":
            n = 3 if c == "t" else 8
            try:
                cid = int(line[1 : 1 + n], 16)
                dlc = int(line[1 + n])
                data = bytes.fromhex(line[2 + n : 2 + n + 2 * dlc])
            except (ValueError, IndexError):
                self.errors += 1
                return None, b"\a"
            if dlc > 8 or len(data) != dlc:
                self.errors += 1
                return None, b"\a"
            if not self.open:
                return None, b"\a"
            if c == "T":  # the drive uses 11-bit ids only: accepted, not for us
                return None, b"Z\r"
            self.frames_in += 1
            return (cid, data), b"z\r"
        if c in "rR":
            return None, b"z\r" if self.open else b"\a"
        self.errors += 1
        return None, b"\a"


def slcan_line(cid: int, data: bytes) -> bytes:
    return f"t{cid:03X}{len(data)}{data.hex().upper()}\r".encode()


class Pty:
    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        tty.setraw(self.master)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self.backlog = bytearray()
        self.dropped = 0

    def read(self) -> bytes:
        try:
            return os.read(self.master, 65536)
        except (BlockingIOError, OSError):
            return b""

    def write(self, data: bytes) -> None:
        self.backlog += data
        if len(self.backlog) > MAX_BACKLOG:  # nobody reads: keep the newest
            cut = len(self.backlog) - MAX_BACKLOG
            self.dropped += cut
            del self.backlog[:cut]
        while self.backlog:
            try:
                n = os.write(self.master, self.backlog)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                self.backlog.clear()
                return
            del self.backlog[:n]

    def close(self) -> None:
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)


class SimServer:
    """The simulated drive served on a serial pty and an SLCAN pty."""

    def __init__(self, node: int = 1, tick_hz: int = 10000, axes: int = 3) -> None:
        from contour import native

        if not 1 <= node <= pg.CAN_NODE_MAX:
            raise UserError(f"--node {node}: must be 1..{pg.CAN_NODE_MAX}")
        if not 1000 <= tick_hz <= 100000:
            raise UserError(f"--tick-hz {tick_hz}: must be 1000..100000")
        lib = native.load()
        _bind(lib)
        self.lib = lib
        self.tick_hz = tick_hz
        if lib.sim_setup(float(tick_hz), axes) != 0 or lib.sim_start() != 0:
            raise UserError(f"simulator refused tick {tick_hz} Hz with {axes} axes")
        try:
            build_id = zlib.crc32(native.library_path().read_bytes())
        except OSError:
            build_id = 0
        caps = 0
        for cap in ("SERIAL", "CAN", "TELEMETRY", "JOG", "SIMULATED"):
            caps |= 1 << pg.Capability[cap]
        self.ident = Identity(
            fw_version=fw_version(),
            build_id=build_id,
            capabilities=caps,
            tick_hz=tick_hz,
            board_id=BOARD_SIM,
            planner_slots=0,  # the dispatcher reads it from the drive
            node_id=node,
            axes=axes,
        )
        if not lib.proto_link_init(ctypes.byref(self.ident), True, True):
            raise UserError("proto_link_init refused the drive identity")
        self.serial = Pty()
        self.slcan = Pty()
        self.parser = SlcanParser()
        self._stop = threading.Event()
        self.ticks = 0
        self.late = 0
        self._ubuf = ctypes.create_string_buffer(8192)
        self._cdata = ctypes.create_string_buffer(8)
        self._cid = ctypes.c_uint32()
        self._clen = ctypes.c_uint8()

    def _pump_in(self) -> None:
        data = self.serial.read()
        if data:
            self.lib.hal_sim_uart_inject(data, len(data))
        data = self.slcan.read()
        if data:
            frames, reply = self.parser.feed(data)
            for cid, payload in frames:
                self.lib.hal_sim_can_inject(cid, payload, len(payload))
            if reply:
                self.slcan.write(reply)

    def _pump_out(self) -> None:
        n = self.lib.hal_sim_uart_drain(self._ubuf, len(self._ubuf))
        while n:
            self.serial.write(self._ubuf.raw[:n])
            n = self.lib.hal_sim_uart_drain(self._ubuf, len(self._ubuf))
        out = bytearray()
        while self.lib.hal_sim_can_drain(
            ctypes.byref(self._cid), self._cdata, ctypes.byref(self._clen)
        ):
            if self.parser.open:
                out += slcan_line(self._cid.value, self._cdata.raw[: self._clen.value])
        if out:
            self.slcan.write(out)

    def step(self, ticks: int) -> None:
        self._pump_in()
        self.lib.proto_link_poll()
        if ticks > 0:
            self.lib.sim_run(ticks, None, 0, 0)
            self.ticks += ticks
        self.lib.proto_link_poll()
        self._pump_out()

    def run(self, period: float = 0.001) -> None:
        t0 = time.monotonic()
        max_chunk = self.tick_hz // 20
        fds = [self.serial.master, self.slcan.master]
        while not self._stop.is_set():
            due = int((time.monotonic() - t0) * self.tick_hz)
            n = due - self.ticks
            if n > max_chunk:  # fell behind (stall): do not run away
                self.late += 1
                t0 += (n - max_chunk) / self.tick_hz
                n = max_chunk
            self.step(n)
            try:
                select.select(fds, [], [], period)
            except (OSError, ValueError):
                time.sleep(period)

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        self.serial.close()
        self.slcan.close()


class Spawned:
    """A `sim serve` child process (see :func:`spawn`)."""

    def __init__(self, proc, serial: str, slcan: str) -> None:
        self.proc = proc
        self.serial = serial
        self.slcan = slcan

    def stop(self, timeout: float = 5.0) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=timeout)
        for f in (self.proc.stdout, self.proc.stderr):
            if f is not None:
                f.close()

    def __enter__(self) -> Spawned:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


def spawn(extra_args=(), timeout: float = 20.0, env=None) -> Spawned:
    """Start `sim serve` as a child process and wait for its two paths.

    For tests, benches and scripts: ``with spawn() as s: connect(port=s.serial)``.
    The child is stopped (SIGTERM, then SIGKILL) on exit of the context.
    """
    cmd = [sys.executable, "-m", "contour.simserve", *map(str, extra_args)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    paths: dict = {}
    buf = b""
    end = time.monotonic() + timeout
    try:
        while len(paths) < 2:
            left = end - time.monotonic()
            if left <= 0 or proc.poll() is not None:
                err = proc.stderr.read().decode(errors="replace") if proc.poll() is not None else ""
                raise UserError(f"sim serve did not start: {err.strip()[-500:]}")
            ready, _, _ = select.select([proc.stdout], [], [], min(left, 0.2))
            if not ready:
                continue
            chunk = os.read(proc.stdout.fileno(), 4096)
            buf += chunk
            for line in buf.decode(errors="replace").splitlines():
                key, _, value = line.strip().partition(": ")
                if key in ("serial", "slcan"):
                    paths[key] = value
    except BaseException:
        Spawned(proc, "", "").stop()
        raise
    return Spawned(proc, paths["serial"], paths["slcan"])


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--node", type=int, default=1, help="CAN node id (default 1)")
    parser.add_argument(
        "--tick-hz", type=int, default=10000, help="control tick rate, Hz (default 10000)"
    )
    parser.add_argument("--axes", type=int, default=3, choices=(1, 2, 3), help="axes (default 3)")


def main(args: argparse.Namespace) -> int:
    server = SimServer(node=args.node, tick_hz=args.tick_hz, axes=args.axes)

    def _stop(signum, frame) -> None:  # noqa: ARG001
        server.stop()

    old = {s: signal.signal(s, _stop) for s in (signal.SIGINT, signal.SIGTERM)}
    print(f"serial: {server.serial.path}", flush=True)
    print(f"slcan: {server.slcan.path}", flush=True)
    print(f"node: {args.node}", flush=True)
    try:
        server.run()
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        server.close()
    print(
        f"sim serve: stopped after {server.ticks / server.tick_hz:.3f} s simulated", file=sys.stderr
    )
    return 0


if __name__ == "__main__":  # python -m contour.simserve (same as `contour sim serve`)
    _p = argparse.ArgumentParser(prog="contour sim serve", description=__doc__.splitlines()[0])
    add_arguments(_p)
    try:
        raise SystemExit(main(_p.parse_args()))
    except UserError as _exc:
        print(f"contour: error: {_exc}", file=sys.stderr)
        raise SystemExit(2) from None
