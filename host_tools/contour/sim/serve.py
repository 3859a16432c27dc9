"""`contour sim serve`: the simulated drive in real time on two pseudo-terminals.

Design (Python orchestrating the C simulator, no C program of its own): one
thread runs a loop every ~1 ms of wall time:

1. bytes arriving on the serial pty go to the simulated UART
   (``hal_sim_uart_inject``); SLCAN lines arriving on the SLCAN pty are
   parsed (the Lawicel ASCII protocol python-can's ``slcan`` interface and
   USB-CAN adapters speak) and their frames go to the simulated CAN
   controller (``hal_sim_can_inject``) through a simulated bus: each frame
   of either direction takes its exact bits (stuffing included,
   ``contour.link.canbits``) at the bitrate the SLCAN ``S`` command set
   (1 Mbit/s until one does), in the order sent;
2. the firmware's own host link runs (``proto_link_poll`` of
   firmware/core/proto_link.c: framing, ISO-TP, dispatcher, watchdog,
   telemetry), exactly as a drive's background loop would;
3. the simulator advances as many control ticks as the wall clock says
   (``sim_run``: drive_tick + drive_poll + the axis models), in chunks of at
   most 50 ms so a stall never turns into a runaway;
4. the link runs again and what the drive sent (``hal_sim_uart_drain``,
   ``hal_sim_can_drain``) goes to the ptys (CAN frames as SLCAN ``t`` lines).

The bootloader runs first, as on a drive (docs/bootloader.md, "contour sim
serve"): the flash is ``--flash FILE`` or a RAM flash holding an image of
this version; while the drive is in its bootloader every message goes to it
(``boot_sim_handle``) and the application does not tick; a reset
(``boot_enter``, a REBOOT, the end of the connect window) restarts the link
for the firmware the boot decision chose.

Everything the drive does is the firmware core's code through the sim HAL;
the protocol clock (watchdog, telemetry periods) is the simulated clock, which
tracks the wall clock. The process prints ``serial: PATH`` and ``slcan: PATH``
on their own lines (flushed) and runs until SIGINT/SIGTERM.
"""

from __future__ import annotations

import argparse
import collections
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
from contour.link.canbits import frame_bits

EFF = 0x80000000  # HAL_CAN_EFF (firmware/hal/hal.h): an extended id
BOARD_SIM = 1  # BOOT_BOARD_SIM in firmware/core/boot/boot.h
MAX_BACKLOG = 256 * 1024
FLASH_FILE_BYTES = 256 * 1024  # FLASH_SIM_DEFAULT_SIZE (firmware/ports/sim/hal_flash_sim.h)
DEFAULT_MACHINE = "tuned"  # hil_sim/machines/tuned.toml: the machine without --machine


def fw_version() -> int:
    parts = [int(x) for x in __version__.split(".")[:3]]
    parts += [0] * (3 - len(parts))
    return parts[0] << 16 | parts[1] << 8 | parts[2]


class SlcanParser:
    """The drive side of SLCAN (Lawicel ASCII): commands in, replies out.
    ``S0``..``S8`` set the CAN bitrate of the simulated bus (`bitrate`)."""

    BITRATES = {f"S{i}" for i in range(9)}
    # Lawicel's S0..S8
    BITRATE_OF = dict(
        zip(
            (f"S{i}" for i in range(9)),
            (10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000),
        )
    )

    def __init__(self) -> None:
        self.buf = bytearray()
        self.open = False
        self.frames_in = 0
        self.errors = 0
        self.bitrate = 1_000_000  # until an S command says otherwise

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
        if line in self.BITRATES:
            self.bitrate = self.BITRATE_OF[line]
            return None, b"\r"
        if c in "sYZMmX":
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
            if dlc > 8 or len(data) != dlc or cid > (0x7FF if c == "t" else 0x1FFFFFFF):
                self.errors += 1
                return None, b"\a"
            if not self.open:
                return None, b"\a"
            self.frames_in += 1
            if c == "T":  # 29-bit: the HAL's flag (HAL_CAN_EFF) marks it
                return (cid | EFF, data), b"Z\r"
            return (cid, data), b"z\r"
        if c in "rR":
            return None, b"z\r" if self.open else b"\a"
        self.errors += 1
        return None, b"\a"


def slcan_line(cid: int, data: bytes) -> bytes:
    """A frame as SLCAN sends it: ``T`` + 8 hex digits for an id carrying
    EFF (29-bit), ``t`` + 3 for an 11-bit one."""
    if cid & EFF:
        return f"T{cid & 0x1FFFFFFF:08X}{len(data)}{data.hex().upper()}\r".encode()
    return f"t{cid:03X}{len(data)}{data.hex().upper()}\r".encode()


def bus_bits(cid: int, data: bytes) -> int:
    """Bits of a frame on the simulated bus (canbits.frame_bits)."""
    return frame_bits(cid & 0x1FFFFFFF, data, extended=bool(cid & EFF))


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


class SimDrive:
    """One simulated drive: its own instance of the library (firmware
    state, simulator, clock), bootloader first as on a drive."""

    def __init__(
        self,
        lib: ctypes.CDLL,
        node: int,
        tick_hz: Optional[int],
        axes: Optional[int],
        machine: Optional[str],
        feedforward: Optional[str],
        flash: Optional[str],
        boot_window_ms: int,
        encoder_model: Optional[str],
        build_id: int,
    ) -> None:
        from contour import native
        from contour.sim import machine as mach

        self.lib = lib
        self.node = node
        # the bootloader runs first (flash attached before the application
        # reads its stores from it); docs/bootloader.md "Simulated drive"
        if not lib.boot_sim_init(flash.encode() if flash else None, node, boot_window_ms * 1000):
            raise UserError(f"--flash {flash}: cannot open or create it")
        if not flash:
            _install_factory_image(lib)
        # the application and its link are built by the firmware's composition
        # root (app_init, firmware/core/app.h) at every sim_start
        link = mach.SimLink(
            node=node, serial=True, can=True, fw_version=fw_version(), build_id=build_id, boot=True
        )
        # a machine file (axes, tick, model options, limits, gains, feed-forward);
        # without --machine hil_sim/machines/tuned.toml (docs/simulator.md,
        # "The default machine")
        m = mach.load(DEFAULT_MACHINE if machine is None else machine)
        if axes is not None:
            if not 1 <= axes <= m.axes:
                raise UserError(f"--axes {axes}: machine {m.name} has {m.axes} axes")
            m.axes = axes
        with native.instance(lib):
            mach.apply(
                m, tick_hz=tick_hz, feedforward=feedforward, link=link, encoder_model=encoder_model
            )
        lib.co_drive_sync_tick.restype = ctypes.c_uint64
        lib.co_drive_sync_count.restype = ctypes.c_uint32
        lib.co_drive_csp_missed.restype = ctypes.c_uint32
        self.tick_hz = int(lib.sim_tick_hz())
        self.period_ns = round(1e9 / self.tick_hz)
        self.app_running = False
        self._boot_state: Optional[tuple[int, int]] = None
        self._sim_fresh = True  # sim_start just ran: the first application start needs none
        self._sync_boot()
        self._cdata = ctypes.create_string_buffer(8)
        self._cid = ctypes.c_uint32()
        self._clen = ctypes.c_uint8()

    def _sync_boot(self) -> None:
        """After a reset or a jump: start the firmware the bootloader chose
        (the application: app_init again through sim_start; the bootloader:
        its own link, boot_sim_serve_link)."""
        state = (self.lib.boot_sim_resets(), self.lib.boot_sim_mode())
        if state == self._boot_state:
            return
        self._boot_state = state
        self.app_running = state[1] == 1  # BOOT_SIM_APP
        if self.app_running:
            if not self._sim_fresh and self.lib.sim_start() != 0:
                raise UserError("simulator refused to restart the application")
        elif not self.lib.boot_sim_serve_link():
            raise UserError("the simulated bootloader refused its link")
        self._sim_fresh = False

    def run(self, ticks: int) -> None:
        """The link, `ticks` control ticks (only the clock in the
        bootloader), the link again, then the boot decision."""
        self.lib.proto_link_poll()
        if ticks > 0:
            if self.app_running:
                self.lib.sim_run(ticks, None, 0, 0)
            else:
                self.lib.hal_sim_set_time_ns(self.lib.hal_sim_time_ns() + ticks * self.period_ns)
        self.lib.proto_link_poll()

    def after(self) -> None:
        if self.lib.hal_sim_take_reset_request():  # the application reset the processor
            self.lib.boot_sim_reset()
        self.lib.boot_sim_poll()  # ends the connect window, performs a REBOOT
        self._sync_boot()

    def drain(self) -> list[tuple[int, bytes]]:
        out = []
        while self.lib.hal_sim_can_drain(
            ctypes.byref(self._cid), self._cdata, ctypes.byref(self._clen)
        ):
            out.append((self._cid.value, self._cdata.raw[: self._clen.value]))
        return out

    def inject(self, cid: int, data: bytes) -> None:
        self.lib.hal_sim_can_inject(cid, data, len(data))

    def sync_info(self) -> tuple[int, int, int]:
        """(SYNCs sampled, tick of the last sample, CSP targets refused)."""
        return (
            int(self.lib.co_drive_sync_count()),
            int(self.lib.co_drive_sync_tick()),
            int(self.lib.co_drive_csp_missed()),
        )


class SimBus:
    """The simulated CAN bus: frames of every side (the SLCAN host, each
    drive) in the order they were sent, each taking its exact bits
    (canbits.frame_bits, extended frames included) at `bitrate`; a frame
    reaches every other side when its last bit has passed on the simulated
    clock (`now_ns`, the first drive's)."""

    HOST = -1

    def __init__(self, drives: list[SimDrive]) -> None:
        self.drives = drives
        self.bitrate = 1_000_000
        self._q: collections.deque = collections.deque()  # (t_ns, source, id, data, bits)
        self._free_ns = 0
        self._now_ns = 0
        self.bits = 0
        self.frames = 0

    def now_ns(self) -> int:
        return int(self.drives[0].lib.hal_sim_time_ns())

    def send(self, source: int, cid: int, data: bytes, t_ns: Optional[int] = None) -> None:
        t = self.now_ns() if t_ns is None else t_ns
        self._q.append((t, source, cid, data, bus_bits(cid, data)))

    def deliver(self, to_host) -> None:
        """Frames whose last bit has passed: to every drive but their
        source, and to_host(cid, data) for the drives' frames."""
        now = self.now_ns()
        if now < self._now_ns:  # the clock restarted (a reset): frames on their way go on
            self._q = collections.deque((now,) + f[1:] for f in self._q)
            self._free_ns = now
        self._now_ns = now
        while self._q:
            t, source, cid, payload, bits = self._q[0]
            end = max(self._free_ns, t) + bits * 1_000_000_000 // self.bitrate
            if end > now:
                break
            self._q.popleft()
            self._free_ns = end
            self.bits += bits
            self.frames += 1
            for i, d in enumerate(self.drives):
                if i != source:
                    d.inject(cid, payload)
            if source != self.HOST:
                to_host(cid, payload)

    def pending(self) -> int:
        return len(self._q)


class SimServer:
    """Simulated drives on one CAN bus, served on an SLCAN pty, and the
    first drive's serial link on a serial pty (the others' on their own:
    `serials`)."""

    def __init__(
        self,
        node: int = 1,
        tick_hz: Optional[int] = None,
        axes: Optional[int] = None,
        machine: Optional[str] = None,
        feedforward: Optional[str] = None,
        flash: Optional[str] = None,
        boot_window_ms: Optional[int] = None,
        encoder_model: Optional[str] = None,
        drives: int = 1,
        ptys: bool = True,
    ) -> None:
        from contour import native

        if not 1 <= drives <= 16:
            raise UserError(f"--drives {drives}: must be 1..16")
        if not 1 <= node <= pg.CAN_NODE_MAX - drives + 1:
            raise UserError(f"--node {node}: must be 1..{pg.CAN_NODE_MAX - drives + 1}")
        if drives > 1 and flash:
            raise UserError("--flash serves one drive: leave it out with --drives")
        if tick_hz is not None and not 1000 <= tick_hz <= 100000:
            raise UserError(f"--tick-hz {tick_hz}: must be 1000..100000")
        if boot_window_ms is None:  # a RAM flash starts its factory image at once
            boot_window_ms = 200 if flash else 0
        if not 0 <= boot_window_ms <= 60000:
            raise UserError(f"--boot-window-ms {boot_window_ms}: must be 0..60000")
        if flash and os.path.exists(flash) and os.path.getsize(flash) != FLASH_FILE_BYTES:
            raise UserError(
                f"--flash {flash}: {os.path.getsize(flash)} bytes; a simulated flash file is "
                f"{FLASH_FILE_BYTES} bytes (give a new path to start with an erased one)"
            )
        try:
            build_id = zlib.crc32(native.library_path().read_bytes())
        except OSError:
            build_id = 0
        self.drives = [
            SimDrive(
                native.load_instance(i),
                node + i,
                tick_hz,
                axes,
                machine,
                feedforward,
                flash,
                boot_window_ms,
                encoder_model,
                build_id,
            )
            for i in range(drives)
        ]
        self.lib = self.drives[0].lib
        self.tick_hz = self.drives[0].tick_hz
        self.period_ns = self.drives[0].period_ns
        self.bus = SimBus(self.drives)
        self.parser = SlcanParser()
        self.serials = [Pty() for _ in self.drives] if ptys else []
        self.serial = self.serials[0] if ptys else None
        self.slcan = Pty() if ptys else None
        self._stop = threading.Event()
        self.ticks = 0
        self.late = 0
        self._ubuf = ctypes.create_string_buffer(8192)

    @property
    def app_running(self) -> bool:
        return self.drives[0].app_running

    @property
    def bus_bits(self) -> int:
        return self.bus.bits

    def _to_host(self, cid: int, data: bytes) -> None:
        if self.slcan is not None and self.parser.open:
            self._host_out += slcan_line(cid, data)

    def _deliver(self) -> None:
        self._host_out = bytearray()
        self.bus.bitrate = self.parser.bitrate
        self.bus.deliver(self._to_host)
        if self._host_out:
            self.slcan.write(bytes(self._host_out))

    def _pump_in(self) -> None:
        for d, pty in zip(self.drives, self.serials):
            data = pty.read()
            if data:
                d.lib.hal_sim_uart_inject(data, len(data))
        if self.slcan is not None:
            data = self.slcan.read()
            if data:
                frames, reply = self.parser.feed(data)
                for cid, payload in frames:
                    self.bus.send(SimBus.HOST, cid, payload)
                if reply:
                    self.slcan.write(reply)
        self._deliver()

    def _pump_out(self) -> None:
        for i, d in enumerate(self.drives):
            if self.serials:
                n = d.lib.hal_sim_uart_drain(self._ubuf, len(self._ubuf))
                while n:
                    self.serials[i].write(self._ubuf.raw[:n])
                    n = d.lib.hal_sim_uart_drain(self._ubuf, len(self._ubuf))
            for cid, payload in d.drain():
                self.bus.send(i, cid, payload)
        self._deliver()

    def step(self, ticks: int) -> None:
        """Every drive by the same ticks (lockstep: one simulated clock)."""
        self._pump_in()
        for d in self.drives:
            d.run(ticks)
        if ticks > 0:
            self.ticks += ticks
        self._pump_out()
        for d in self.drives:
            d.after()

    def run(self, period: float = 0.001) -> None:
        t0 = time.monotonic()
        max_chunk = self.tick_hz // 20
        fds = [p.master for p in self.serials] + [self.slcan.master]
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
        for p in self.serials:
            p.close()
        if self.slcan is not None:
            self.slcan.close()


def _install_factory_image(lib: ctypes.CDLL) -> None:
    """A RAM flash (no --flash) gets a valid image of this version, written
    by the simulated drive's own bootloader, so the drive starts its
    application as before the bootloader existed (and can be flashed)."""
    from contour import image as img
    from contour.link import codec

    out = ctypes.create_string_buffer(256)

    def req(seq: int, name: str, **fields) -> dict:
        msg = codec.encode(name, seq, **fields)
        n = lib.boot_sim_handle(msg, len(msg), out, 256)
        d = codec.decode(out.raw[:n])
        if d.name == "error":
            raise UserError(f"factory image: {name} refused by the bootloader: {d.fields}")
        return d.fields

    info = req(1, "boot_connect")
    image = img.build(
        f"contour simulated drive {__version__}".encode().ljust(192, b"\0"),
        board_id=info["board_id"],
        fw_version=fw_version(),
        load_addr=info["load_addr"],
    )
    req(2, "boot_erase", header=list(image.header.encode()))
    req(3, "boot_write", addr=image.header.load_addr, data=image.payload)
    req(4, "boot_finish")
    lib.boot_sim_reset()


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
    cmd = [sys.executable, "-m", "contour.sim.serve", *map(str, extra_args)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    paths: dict = {}
    buf = b""
    end = time.monotonic() + timeout
    try:
        while "slcan" not in paths or "serial" not in paths:
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
                if key in ("serial", "slcan") or key.startswith("serial "):
                    paths[key] = value
    except BaseException:
        Spawned(proc, "", "").stop()
        raise
    sp = Spawned(proc, paths["serial"], paths["slcan"])
    sp.serials = {int(k.split()[1]): v for k, v in paths.items() if k.startswith("serial ")}
    return sp


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--node", type=int, default=1, help="CAN node id (default 1; the first with --drives)"
    )
    parser.add_argument(
        "--drives",
        type=int,
        default=1,
        help="simulated drives on the one CAN bus (default 1), node ids --node, --node + 1, ..; "
        "each has its own axes and serial pty (printed as 'serial NODE: PATH')",
    )
    parser.add_argument(
        "--tick-hz",
        type=int,
        default=None,
        help="control tick rate, Hz (default: the machine file's)",
    )
    parser.add_argument(
        "--axes", type=int, default=None, choices=(1, 2, 3), help="axes (default: the machine's)"
    )
    parser.add_argument(
        "--flash",
        metavar="FILE",
        help="simulated flash file (created erased: the drive starts in its bootloader; "
        "default: a RAM flash holding an image of this version)",
    )
    parser.add_argument(
        "--boot-window-ms",
        type=int,
        default=None,
        help="bootloader connect window before starting the application "
        "(default 200 with --flash, else 0)",
    )
    parser.add_argument(
        "--machine",
        metavar="NAME|FILE.toml",
        help="machine file (hil_sim/machines/NAME.toml): model options, axes, tick, limits, "
        f"gains, feed-forward (default {DEFAULT_MACHINE})",
    )
    parser.add_argument(
        "--feedforward",
        choices=("none", "velocity", "full"),
        default=None,
        help="feed-forward of the axis loops (default: the machine file's, none if it says none)",
    )
    from contour.sim import machine as mach

    mach.add_encoder_model_argument(parser)


def main(args: argparse.Namespace) -> int:
    server = SimServer(
        drives=getattr(args, "drives", 1),
        node=args.node,
        tick_hz=args.tick_hz,
        axes=args.axes,
        machine=getattr(args, "machine", None),
        feedforward=getattr(args, "feedforward", None),
        flash=getattr(args, "flash", None),
        boot_window_ms=getattr(args, "boot_window_ms", None),
        encoder_model=getattr(args, "encoder_model", None),
    )

    def _stop(signum, frame) -> None:  # noqa: ARG001
        server.stop()

    old = {s: signal.signal(s, _stop) for s in (signal.SIGINT, signal.SIGTERM)}
    print(f"serial: {server.serial.path}", flush=True)
    for d, pty in zip(server.drives[1:], server.serials[1:]):
        print(f"serial {d.node}: {pty.path}", flush=True)
    print(f"slcan: {server.slcan.path}", flush=True)  # last: spawn() waits for it
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


if __name__ == "__main__":  # python -m contour.sim.serve (same as `contour sim serve`)
    _p = argparse.ArgumentParser(prog="contour sim serve", description=__doc__.splitlines()[0])
    add_arguments(_p)
    try:
        raise SystemExit(main(_p.parse_args()))
    except UserError as _exc:
        print(f"contour: error: {_exc}", file=sys.stderr)
        raise SystemExit(2) from None
