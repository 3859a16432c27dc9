"""The simulated drive inside this process, as fast as the CPU allows.

The C simulator of build/host/libcontour.so (hil_sim/sim.c with the drive
application) plus the firmware's own host link (proto_link: serial framing,
dispatcher, the calibration handler as extension), reached through a
transport with the same interface as contour.link's serial and CAN
transports. Simulated time advances only when the caller waits
(:meth:`SimDrive.advance`), so a calibration that takes a minute on a real
drive takes a second here, with the same messages, frames and firmware code
as over `contour sim serve`.
"""

from __future__ import annotations

import ctypes
from typing import Callable, Optional

from contour.calibration.faults import FrameFaults, StreamFaults
from contour.errors import UserError
from contour.link import codec


def erase_flash() -> None:
    """Erase the simulated flash (default geometry): no stored tables."""
    from contour import native

    lib = native.load()
    if not lib.flash_sim_configure(0x08010000, 256 * 1024, 2048, 8):
        raise UserError("simulated flash refused its default geometry")


class SimDrive:
    """One simulated drive (the simulator is one per process)."""

    def __init__(
        self,
        machine: str = "lacerda_y_calibration",
        feedforward: str = "full",
        node: int = 1,
        keep_flash: bool = True,
    ) -> None:
        from contour import native
        from contour.sim import core
        from contour.sim import machine as mach
        from contour.sim import serve as simserve

        lib = native.load()
        self.lib = lib
        if not keep_flash:
            erase_flash()
        self.machine = mach.load(machine)
        # the drive and its serial link as every target builds them
        # (firmware/core/app.h), at sim_start
        link = mach.SimLink(node=node, serial=True, can=False, fw_version=simserve.fw_version())
        mach.apply(self.machine, feedforward=feedforward, link=link)
        self.tick_hz = int(lib.sim_tick_hz())
        self._core = core
        self._buf = ctypes.create_string_buffer(8192)
        self.seconds = 0.0

    def poll(self) -> bytes:
        """Run the drive's link once; return what it sent on the UART."""
        self.lib.proto_link_poll()
        out = bytearray()
        n = self.lib.hal_sim_uart_drain(self._buf, len(self._buf))
        while n:
            out += self._buf.raw[:n]
            n = self.lib.hal_sim_uart_drain(self._buf, len(self._buf))
        return bytes(out)

    def advance(self, seconds: float, chunk_ticks: int = 10) -> bytes:
        """Simulate `seconds` (control ticks, the link polled between chunks
        of chunk_ticks as a drive's background loop would)."""
        ticks = max(1, int(round(seconds * self.tick_hz)))
        out = bytearray()
        done = 0
        while done < ticks:
            n = min(chunk_ticks, ticks - done)
            self.lib.sim_run(n, None, 0, 0)
            done += n
            out += self.poll()
        self.seconds += ticks / self.tick_hz
        return bytes(out)

    def transport(self, faults: Optional[FrameFaults] = None) -> SimTransport:
        return SimTransport(self, faults)

    def table_pos(self, axis: int) -> float:
        return float(self.lib.sim_table_pos(axis))


class SimTransport:
    """contour.link transport interface (start / send / close) to a SimDrive
    over the drive's serial framing; replies are delivered inside send()."""

    kind = "sim"

    def __init__(self, drive: SimDrive, faults: Optional[FrameFaults] = None) -> None:
        self.drive = drive
        self.faults = faults
        self.decoder = codec.FrameDecoder()
        self._in = StreamFaults(faults) if faults else None
        self._on: Optional[Callable[[bytes, float], None]] = None
        self.tx_frames = 0

    def start(self, on_message) -> None:
        self._on = on_message

    def _deliver(self, data: bytes) -> None:
        if self._in is not None:
            data = self._in.feed(data)
        for m in self.decoder.feed(data):
            if self._on is not None:
                self._on(m, self.drive.seconds)

    def send(self, message: bytes) -> None:
        data = codec.frame(message)
        if self.faults is not None:
            data = self.faults.mangle(data)
        self.tx_frames += 1
        if data:
            self.drive.lib.hal_sim_uart_inject(data, len(data))
        self._deliver(self.drive.poll())

    def wait(self, seconds: float) -> None:
        """The calibration's clock: simulated time passes."""
        self._deliver(self.drive.advance(seconds))

    def rx_errors(self) -> int:
        return sum(self.decoder.errors.values())

    def close(self) -> None:
        self._on = None
