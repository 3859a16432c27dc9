"""The boot client: update a drive's firmware so that the worst case is "try again".

Procedure (docs/bootloader.md): reach the bootloader (`boot_connect`, or
`boot_enter` to the running application, then reconnect); check the image
header against the drive's board id, load address and slot size BEFORE
anything is erased; erase; write blocks (address echo checked, failed
blocks retried with exponential back-off under the same sequence number, so
the drive answers a repeat from its reply cache instead of executing it
twice; python-can's transmit-buffer-full is waited out); verify the whole
payload by a read-back CRC; `boot_finish` (the drive checks the CRC itself
and only then marks the image valid); reboot; confirm the running
application's version with `identify`. If the drive lost the session (it was
reset), the whole session is repeated, up to `attempts` times.

Library code: `contour flash` (contour.commands.flash) parses the command
line and calls :func:`flash`; the simulated bootloader in this process is
contour.sim.bootsim.SimDriveLink.
"""

from __future__ import annotations

import contextlib
import sys
import time
from dataclasses import dataclass, field
from typing import Callable, Optional, Protocol

from contour import image as img
from contour import protocol_gen as pg
from contour.errors import UserError
from contour.link import codec
from contour.link.transport import LinkError, tx_buffer_full  # transmit buffer full
from contour.progress import Bar

# ---- link and client ------------------------------------------------------------


class Link(Protocol):
    """One request/reply exchange of whole messages (msg_id | seq | payload).
    Returns the reply, or None when none came within `timeout` seconds."""

    def exchange(self, msg: bytes, timeout: float) -> Optional[bytes]: ...


class LinkLost(LinkError):
    """No reply after every retry."""


class Refused(UserError):
    """The drive answered `error`."""

    kind = "drive"

    def __init__(self, msg: str, code: int, arg: int, lo: int):
        super().__init__(msg)
        self.code = code
        self.arg = arg
        self.lo = lo


def _status_name(arg: int) -> str:
    try:
        return pg.BootStatus(arg).name.lower().replace("_", " ")
    except ValueError:
        return f"status {arg}"


def _reason_name(arg: int) -> str:
    try:
        return pg.BootReason(arg).name.lower().replace("_", " ")
    except ValueError:
        return f"reason {arg}"


@dataclass
class Stats:
    requests: int = 0
    retries: int = 0
    timeouts: int = 0
    tx_full_waits: int = 0
    sessions: int = 0


@dataclass
class BootClient:
    link: Link
    timeout: float = 0.5
    retries: int = 6
    backoff: float = 0.02
    backoff_max: float = 1.0
    sleep: Callable[[float], None] = time.sleep
    stats: Stats = field(default_factory=Stats)
    seq: int = 0

    def request(
        self,
        name: str,
        fields: Optional[dict] = None,
        timeout: Optional[float] = None,
        retries: Optional[int] = None,
    ) -> tuple[str, dict]:
        import can  # python-can: its CanOperationError is the transmit-buffer-full carrier

        m = pg.MSG_BY_NAME[name]
        self.seq = (self.seq + 1) & 0xFF
        msg = codec.encode(name, self.seq, **(fields or {}))
        delay = self.backoff
        tries = self.retries if retries is None else retries
        attempt = 0
        full_waits = 0
        self.stats.requests += 1
        while True:
            try:
                reply = self.link.exchange(msg, timeout or self.timeout)
            except (can.CanOperationError, OSError, UserError) as exc:
                if not tx_buffer_full(exc) or full_waits >= 200:
                    raise LinkLost(f"{name}: link error: {exc}") from None
                full_waits += 1
                self.stats.tx_full_waits += 1
                self.sleep(min(0.001 * (1 << min(full_waits, 6)), 0.05))
                continue
            if reply is not None:
                try:
                    d = codec.decode(reply)
                    rname, rseq, rf = d.name, d.seq, d.fields
                except UserError:
                    rname, rseq, rf = "", -1, {}
                if rseq == self.seq and rname in (m.reply, "error"):
                    if rname == "error":
                        raise self._refusal(name, rf)
                    return rname, rf
            self.stats.timeouts += 1
            if attempt >= tries:
                raise LinkLost(f"{name}: no reply from the drive after {attempt + 1} attempts")
            attempt += 1
            self.stats.retries += 1
            self.sleep(delay)
            delay = min(delay * 2, self.backoff_max)

    @staticmethod
    def _refusal(name: str, rf: dict) -> Refused:
        code, arg, lo = rf["code"], rf["arg"], rf["lo"]
        if code == pg.ErrorCode.BOOT:
            text = f"{name} refused by the drive: {_status_name(arg)}"
            if arg == pg.BootStatus.PAYLOAD_CRC:
                text += f" (CRC in flash 0x{lo & 0xFFFFFFFF:08X})"
        else:
            try:
                cname = pg.ErrorCode(code).name.lower().replace("_", " ")
            except ValueError:
                cname = f"code {code}"
            text = f"{name} refused by the drive: {cname}"
        return Refused(text, code, arg, lo)


# ---- the procedure ---------------------------------------------------------------


class SessionLost(Exception):
    """The drive no longer holds our session (it was reset): start over."""


def enter_bootloader(client: BootClient, wait: float = 5.0) -> dict:
    """boot_info of the drive, asking a running application to reset into its
    bootloader (boot_enter) whenever it answers as an application."""
    deadline = time.monotonic() + wait
    answered = False
    while True:
        try:
            return client.request("boot_connect", retries=2)[1]
        except Refused:
            # an application answers boot_connect with an error: ask it to reset
            answered = True
            with contextlib.suppress(Refused, LinkLost):
                client.request("boot_enter", retries=2)
        except LinkLost:
            pass
        if time.monotonic() > deadline:
            if not answered:
                raise LinkLost(
                    f"no reply from the drive in {wait:g} s: is it connected and powered, "
                    "and is --node right?"
                )
            raise LinkLost("the drive did not come back in its bootloader")
        client.sleep(0.05)


def check_running_application(client: BootClient, hdr: img.Header) -> None:
    """A running application is asked who it is before it is sent to its
    bootloader: an image for another board is refused while the drive keeps
    running (and its position). A drive already in its bootloader (no axes)
    or that does not answer is checked there."""
    try:
        _, r = client.request("identify", retries=1)
    except (Refused, LinkLost):
        return
    if r["axes"] > 0 and r["board_id"] != hdr.board_id:
        raise img.ImageError(
            f"image is for board {hdr.board_id}, the drive is board {r['board_id']}: "
            "refusing to flash (the drive keeps running its application)"
        )


def _blocks(length: int, block: int):
    for off in range(0, length, block):
        yield off, min(block, length - off)


def transfer(client: BootClient, info: dict, image: img.Image, progress=None) -> None:
    hdr = image.header
    ws = max(1, info["write_size"])
    block = min(info["block_max"], 224) // ws * ws
    if block <= 0:
        raise UserError(f"drive reports block size {info['block_max']} < write unit {ws}")
    client.request("boot_erase", {"header": list(hdr.encode())}, timeout=10.0)
    if progress is not None:
        progress.reset(total=hdr.length)
    for off, n in _blocks(hdr.length, block):
        addr = hdr.load_addr + off
        try:
            _, r = client.request(
                "boot_write", {"addr": addr, "data": image.payload[off : off + n]}
            )
        except Refused as exc:
            if exc.code == pg.ErrorCode.BOOT and exc.arg == pg.BootStatus.BAD_STATE:
                raise SessionLost() from None
            raise
        if r["addr"] != addr or r["len"] != n:
            raise UserError(
                f"drive echoed block 0x{r['addr']:08X}+{r['len']}, sent 0x{addr:08X}+{n}"
            )
        if progress is not None:
            progress.update(n)
    _, r = client.request("boot_crc", {"addr": hdr.load_addr, "len": hdr.length}, timeout=5.0)
    if r["crc"] != hdr.payload_crc:
        raise SessionLost()  # corrupted in transit or lost blocks: erase and write again
    try:
        _, r = client.request("boot_finish", timeout=5.0)
    except Refused as exc:
        if exc.code == pg.ErrorCode.BOOT and exc.arg in (
            pg.BootStatus.BAD_STATE,
            pg.BootStatus.PAYLOAD_CRC,
        ):
            raise SessionLost() from None
        raise


def confirm_application(client: BootClient, version: int, wait: float) -> dict:
    deadline = time.monotonic() + wait
    last = None
    while time.monotonic() <= deadline:
        try:
            _, r = client.request("identify", retries=1)
        except LinkLost:
            client.sleep(0.05)
            continue
        last = r
        if r["axes"] > 0:  # an application (the bootloader reports no axes)
            if r["fw_version"] != version:
                raise UserError(
                    f"drive runs version {img.version_str(r['fw_version'])} after the update, "
                    f"expected {img.version_str(version)}"
                )
            return r
        client.sleep(0.05)
    reason = ""
    with contextlib.suppress(UserError):
        reason = _reason_name(client.request("boot_connect", retries=1)[1]["app_state"])
    raise UserError(
        f"drive did not start the new application (still in its bootloader: {reason or last})"
    )


def flash(
    client: BootClient,
    image: img.Image,
    *,
    verify_only: bool = False,
    attempts: int = 3,
    progress: bool = False,
    confirm_wait: float = 5.0,
    enter_wait: float = 5.0,
    log: Callable[[str], None] = lambda s: print(s, file=sys.stderr),
) -> dict:
    """Flash (or verify) `image`; returns a summary dict."""
    hdr = image.header
    check_running_application(client, hdr)
    info = enter_bootloader(client, enter_wait)
    try:
        img.check_target(
            hdr,
            board_id=info["board_id"],
            load_addr=info["load_addr"],
            max_length=info["max_length"],
        )
    except img.ImageError:
        # nothing was erased; a drive with a valid application goes back to it
        if info["app_state"] == pg.BootReason.APP_OK:
            with contextlib.suppress(UserError):
                client.request("boot_reboot", retries=1)
        raise
    if verify_only:
        _, r = client.request("boot_crc", {"addr": hdr.load_addr, "len": hdr.length}, timeout=5.0)
        ok = (
            r["crc"] == hdr.payload_crc
            and info["app_state"] == pg.BootReason.APP_OK
            and info["app_version"] == hdr.fw_version
            and info["app_length"] == hdr.length
        )
        if not ok:
            raise UserError(
                f"drive does not hold this image (flash CRC 0x{r['crc']:08X}, image "
                f"0x{hdr.payload_crc:08X}; slot: {_reason_name(info['app_state'])}, version "
                f"{img.version_str(info['app_version'])})"
            )
        log(f"verified: drive holds version {img.version_str(hdr.fw_version)}")
        return {"verified": True, "version": img.version_str(hdr.fw_version)}
    bar = Bar(total=hdr.length, unit="B", desc="flash", enabled=progress, unit_scale=True)
    try:
        for attempt in range(1, attempts + 1):
            client.stats.sessions += 1
            try:
                transfer(client, info, image, bar)
                break
            except SessionLost:
                if attempt == attempts:
                    raise UserError(
                        f"flashing failed {attempts} times (drive reset or data corrupted); "
                        "the drive stays in its bootloader: run contour flash again"
                    ) from None
                log(f"session lost (attempt {attempt}); starting over")
                info = enter_bootloader(client, enter_wait)
    finally:
        bar.close()
    try:
        client.request("boot_reboot")
    except Refused as exc:
        # its reply was lost and the retry reached the new application, which
        # refuses bootloader requests: confirm_application says what runs
        if not (exc.code == pg.ErrorCode.BOOT and exc.arg == pg.BootStatus.BAD_STATE):
            raise
    r = confirm_application(client, hdr.fw_version, confirm_wait)
    log(f"flashed {hdr.length} bytes; drive runs version {img.version_str(r['fw_version'])}")
    return {"verified": True, "version": img.version_str(r["fw_version"]), "stats": client.stats}


# ---- over a transport ------------------------------------------------------------------


class TransportLink:
    """Exchange over the protocol's transports (contour.link.transport: serial
    framing or CAN ISO-TP); replies are matched by id-echo and sequence number."""

    def __init__(self, transport) -> None:
        import queue

        self.t = transport
        self.q: queue.Queue = queue.Queue()
        self.t.start(self._on)

    def _on(self, data: bytes, ts: float) -> None:
        self.q.put(bytes(data))

    def exchange(self, msg: bytes, timeout: float) -> Optional[bytes]:
        import queue

        while not self.q.empty():  # late replies of earlier attempts
            self.q.get_nowait()
        self.t.send(msg)
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            try:
                data = self.q.get(timeout=left)
            except queue.Empty:
                return None
            if len(data) >= 2 and data[1] == msg[1] and data[0] >= 0x40:
                return data

    def close(self) -> None:
        self.t.close()
