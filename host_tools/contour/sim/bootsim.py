"""The simulated drive's bootloader in this process (tests, bench): the
firmware's own boot code (libcontour.so, firmware/ports/sim/boot_sim.c)
behind the :class:`contour.link.boot.Link` interface, with fault hooks."""

from __future__ import annotations

import ctypes
from typing import Callable, Optional

from contour.errors import UserError


class SimDriveLink:
    """The simulated drive's bootloader in this process (libcontour.so,
    firmware/ports/sim/boot_sim.c), reached without a transport: each
    exchange hands the message to boot_sim_drive_handle. Fault hooks:
    `before(n, msg)` may return "drop" (request lost), "reset" (drive reset
    before delivery), or raise (host killed); `after(n, reply)` may return
    "drop" (reply lost) or a replacement reply."""

    def __init__(self, flash_path: Optional[str] = None, window_us: int = 0, node: int = 1):
        from contour import native

        self.lib = native.load()
        lib = self.lib
        path = flash_path.encode() if flash_path else None
        if not lib.boot_sim_init(path, node, window_us):
            raise UserError(f"simulated flash {flash_path}: cannot open")
        self.count = 0
        self.before: Optional[Callable[[int, bytes], Optional[str]]] = None
        self.after: Optional[Callable[[int, bytes], object]] = None

    def reset(self) -> int:
        """Simulated reset (power back on, boot decision re-run); returns the mode."""
        return self.lib.boot_sim_reset()

    def mode(self) -> str:
        return "app" if self.lib.boot_sim_mode() == 1 else "bootloader"

    def reason(self) -> int:
        return self.lib.boot_sim_reason()

    def power_cut_after(self, n: int) -> None:
        self.lib.flash_sim_power_cut_after(n)

    def exchange(self, msg: bytes, timeout: float) -> Optional[bytes]:
        self.count += 1
        if self.before is not None:
            act = self.before(self.count, msg)
            if act == "drop":
                return None
            if act == "reset":
                self.reset()
        if not self.lib.flash_sim_powered():
            return None  # drive dead until reset
        out = ctypes.create_string_buffer(256)
        n = self.lib.boot_sim_drive_handle(msg, len(msg), out, 256)
        self.lib.boot_sim_poll()
        reply = out.raw[:n] if n else None
        if self.after is not None and reply is not None:
            act = self.after(self.count, reply)
            if act == "drop":
                return None
            if isinstance(act, bytes):
                reply = act
        return reply
