"""One client interface for the drive on either transport.

:class:`Client` opens a session (``session_open`` with a random nonce; every
message that arrives before the ``session_reply`` carrying that nonce is an
earlier session's and is discarded), sends requests and waits for their
replies (matched by sequence number *and* request: a reply of another type,
or an ack/error naming another request, is stale and dropped), retries a
request whose reply was lost with the *same* sequence number (the drive
answers a repeated request from its replay cache and does not execute it
twice), turns ``error`` replies into
:class:`DriveError` with a specific message, and queues unsolicited messages
(status, telemetry, heartbeat) for :meth:`Client.unsolicited`.
"""

from __future__ import annotations

import queue
import random
import threading
import time
from typing import Any, Optional

from contour import protocol_gen as pg
from contour.errors import UserError
from contour.link import codec
from contour.link.transport import LinkError, open_transport

AXIS_NAMES = "xyza"

_REPLY_NAMES = {m.reply for m in pg.MESSAGES if m.reply} | {"ack", "error"}
_SESSION_OPEN_ID = pg.MSG_BY_NAME["session_open"].id
# (id, message length) of the session_reply of a protocol-1 drive
_SESSION_REPLY_V1 = (bytes([pg.MSG_BY_NAME["session_reply"].id]), pg.MSG_HDR + 6)


def _answers(reply: codec.Decoded, request: pg.Message) -> bool:
    """True when `reply` (same seq) is an answer to `request`: its reply type,
    or an ack / error that names it."""
    if reply.name in ("ack", "error"):
        return reply.fields["req"] == request.id
    return reply.name == request.reply


class DriveError(UserError):
    """The drive refused a request (an ``error`` reply)."""

    def __init__(self, request: str, fields: dict, text: str) -> None:
        super().__init__(text)
        self.request = request
        self.code = pg.ErrorCode(fields["code"]) if fields["code"] in set(pg.ErrorCode) else None
        self.fields = fields


def _param_label(pid: int) -> str:
    for p in pg.PARAMS:
        n = pg.MAX_AXES if p.per_axis else 1
        if p.id <= pid < p.id + n:
            return f"{p.name}.{AXIS_NAMES[pid - p.id]}" if p.per_axis else p.name
    return f"0x{pid:04X}"


def describe_error(request: str, f: dict) -> str:
    try:
        code = pg.ErrorCode(f["code"])
        cname = code.name.lower()
    except ValueError:
        code, cname = None, f"code {f['code']}"
    arg = f["arg"]
    what = {
        pg.ErrorCode.UNKNOWN_MESSAGE: "message not handled by this drive firmware",
        pg.ErrorCode.BAD_LENGTH: f"payload of {arg} bytes, expected {f['lo']}..{f['hi']}",
        pg.ErrorCode.UNKNOWN_PARAM: f"no parameter with id 0x{arg:04X}",
        pg.ErrorCode.READ_ONLY: f"parameter {_param_label(arg)} is read-only",
        pg.ErrorCode.QUEUE_FULL: "planner queue full",
        pg.ErrorCode.BAD_STATE: f"not allowed in drive state {arg}",
        pg.ErrorCode.BAD_AXIS: f"axis {arg} does not exist on this drive",
        pg.ErrorCode.BAD_VALUE: f"invalid value in field {arg}",
        pg.ErrorCode.NOT_SUPPORTED: "not supported by this drive",
        pg.ErrorCode.INTERNAL: "drive application refused it",
        pg.ErrorCode.DISABLED: "the drive is not enabled",
        pg.ErrorCode.FAULTED: f"a fault is latched (bits 0x{arg:X}): reset it first",
        pg.ErrorCode.BUSY: "not allowed while moving",
        pg.ErrorCode.CAUSE_PRESENT: "the fault's cause is still present",
    }.get(code, cname)
    txn_reqs = ("param_stage", "param_commit")
    if code == pg.ErrorCode.TXN:
        what = _txn_text(arg, f["lo"], f["hi"])
    elif request in txn_reqs and code == pg.ErrorCode.BUSY:
        what = f"{_param_label(arg)} cannot change now: the drive is {_state_name(f['lo'])}"
    elif request in txn_reqs and code == pg.ErrorCode.BAD_VALUE:
        what = (
            f"{_param_label(arg)}: refused together with the other values "
            "(planner profile or servo parameters)"
        )
    elif request in txn_reqs and code == pg.ErrorCode.NOT_SUPPORTED:
        what = f"{_param_label(arg)}: not supported by this drive"
    if code == pg.ErrorCode.OUT_OF_RANGE:
        from contour.params import format_range, param_of_id

        found = param_of_id(arg) if request in ("param_set", "param_get", *txn_reqs) else None
        if found is not None:
            what = f"{_param_label(arg)} out of range {format_range(found[0], f['lo'], f['hi'])}"
        else:
            what = f"field {arg} out of range [{f['lo']}, {f['hi']}]"
    return f"drive refused {request}: {what} ({cname})"


def _state_name(v: int) -> str:
    try:
        return pg.State(v).name.lower()
    except ValueError:
        return f"in state {v}"


_TXN_TEXT = {
    pg.TxnStatus.NOT_OPEN: "parameter transaction {id} is not open (committed or aborted)",
    pg.TxnStatus.NEW_SESSION: "parameter transaction {id} lost: another session opened "
    "(session_open), nothing applied",
    pg.TxnStatus.LINK_TIMEOUT: "parameter transaction {id} lost: link timeout "
    "(comm_timeout_ms without a request of it), nothing applied",
    pg.TxnStatus.SUPERSEDED: "parameter transaction {id} lost: another session began one, "
    "nothing applied",
    pg.TxnStatus.FULL: "parameter transaction {id}: more values than the drive stages ({hi})",
}


def _txn_text(arg: int, lo: int, hi: int) -> str:
    try:
        return _TXN_TEXT[pg.TxnStatus(arg)].format(id=lo, hi=hi)
    except ValueError:
        return f"parameter transaction {lo}: status {arg}"


def parse_param(name: str) -> tuple[pg.Param, int]:
    """``name`` or ``name.AXIS`` (x/y/z/a or 0..3) -> (param, id)."""
    base, _, axis = name.partition(".")
    p = pg.PARAM_BY_NAME.get(base)
    if p is None:
        known = ", ".join(x.name + (".AXIS" if x.per_axis else "") for x in pg.PARAMS)
        raise UserError(f"unknown parameter {name!r}; known: {known}")
    if p.per_axis:
        if not axis:
            raise UserError(f"parameter {base} is per axis: use {base}.x (x, y, z, a or 0..3)")
        a = AXIS_NAMES.find(axis.lower()) if not axis.isdigit() else int(axis)
        if not 0 <= a < pg.MAX_AXES:
            raise UserError(f"{name!r}: axis must be x, y, z, a or 0..3")
        return p, p.id + a
    if axis:
        raise UserError(f"parameter {base} is not per axis")
    return p, p.id


def parse_value(p: pg.Param, text: str) -> int:
    """User text (user units, enum names, unit suffixes) -> raw value."""
    from contour.params import parse_value as _parse

    return _parse(p, text)


class Client:
    def __init__(self, transport, timeout: float = 0.5, retries: int = 3) -> None:
        self.t = transport
        self.timeout = timeout
        self.retries = retries
        self._seq = random.randrange(256)
        self._lock = threading.Lock()
        self._pending: dict[int, tuple[threading.Event, list]] = {}
        self._unsol: queue.Queue = queue.Queue(maxsize=200000)
        self.unsolicited_dropped = 0
        self.bad_messages = 0
        self.retried = 0
        self.stale_replies = 0  # replies of an earlier session or request, dropped
        self.session: Optional[int] = None  # the nonce of the open session
        self.drive_protocol = pg.PROTOCOL_VERSION  # from session_reply
        self._opening: Optional[tuple[int, int, threading.Event, list]] = None
        self._synced = False
        self.t.start(self._on_message)

    # ---- plumbing -------------------------------------------------------------

    def _on_message(self, data: bytes, ts: float) -> None:
        try:
            m = codec.decode(data)
        except codec.ProtocolError:
            if data[:1] == _SESSION_REPLY_V1[0] and len(data) == _SESSION_REPLY_V1[1]:
                # a drive of protocol 1: its session_reply has no version
                m = codec.Decoded(
                    "session_reply",
                    data[0],
                    data[1],
                    {
                        "nonce": int.from_bytes(data[2:6], "little"),
                        "sessions": int.from_bytes(data[6:8], "little"),
                        "protocol_version": 1,
                    },
                )
            else:
                self.bad_messages += 1
                return
        with self._lock:
            opening = self._opening
            slot = self._pending.get(m.seq) if opening is None else None
        if opening is not None:  # before our session_reply: an earlier session's
            nonce, seq, ev, box = opening
            if (m.name == "session_reply" and m.fields["nonce"] == nonce) or (
                m.name == "error" and m.seq == seq and m.fields["req"] == _SESSION_OPEN_ID
            ):
                box.append(m)
                ev.set()
            elif m.name in _REPLY_NAMES:
                self.stale_replies += 1
            return
        if m.name in _REPLY_NAMES:
            if slot is not None and _answers(m, slot[2]):
                slot[1].append(m)
                slot[0].set()
            else:
                self.stale_replies += 1
            return
        try:
            self._unsol.put_nowait((ts, m))
        except queue.Full:
            self.unsolicited_dropped += 1

    def request(
        self, name: str, timeout: Optional[float] = None, retries: Optional[int] = None, **fields
    ) -> codec.Decoded:
        return self.submit(name, **fields).result(timeout, retries)

    def submit(self, name: str, **fields) -> Pending:
        """Send request `name` now and return at once; :meth:`Pending.result`
        waits for its reply (sending the same bytes again on a timeout, as
        :meth:`request` does). Several may be in flight: replies are matched
        by sequence number."""
        msg = pg.MSG_BY_NAME.get(name)
        if msg is None or msg.dir != "h2d":
            raise UserError(f"{name!r} is not a request")
        if not self._synced:
            self._synced = True
            self._open_session(None, None)
        with self._lock:
            self._seq = (self._seq + 1) & 0xFF
            seq = self._seq
            if seq in self._pending:
                raise UserError(f"{name}: more than 255 requests in flight")
            ev: threading.Event = threading.Event()
            box: list = []
            self._pending[seq] = (ev, box, msg)
        data = codec.encode(name, seq, **fields)
        try:
            self.t.send(data)
        except BaseException:
            with self._lock:
                self._pending.pop(seq, None)
            raise
        return Pending(self, name, msg, seq, data, ev, box)

    def _exchange(
        self,
        name: str,
        data: bytes,
        ev: threading.Event,
        timeout: Optional[float],
        retries: Optional[int],
        sent: bool = False,
    ) -> None:
        """Send `data` until `ev` is set (the reply arrived), the same bytes
        each try (the drive answers a repeat from its replay cache); `sent`:
        the first try was sent already."""
        tries = 1 + (self.retries if retries is None else retries)
        wait = self.timeout if timeout is None else timeout
        for attempt in range(tries):
            if attempt:
                self.retried += 1
            if attempt or not sent:
                self.t.send(data)
            if ev.wait(wait):
                return
        raise LinkError(
            f"no reply from the drive to {name} after {tries} tries "
            f"({wait:g} s each): is it connected and powered?"
        )

    def _open_session(self, timeout: Optional[float], retries: Optional[int]) -> None:
        """session_open with a fresh nonce; until its reply arrives every
        message is an earlier session's (dropped, also unsolicited ones)."""
        nonce = random.getrandbits(32)
        with self._lock:
            self._seq = (self._seq + 1) & 0xFF
            seq = self._seq
            ev: threading.Event = threading.Event()
            box: list = []
            self._opening = (nonce, seq, ev, box)
        data = codec.encode("session_open", seq, nonce=nonce, protocol_version=pg.PROTOCOL_VERSION)
        reply = self._open_exchange(data, ev, box, timeout, retries)
        if reply.name == "error" and reply.fields["code"] == pg.ErrorCode.BAD_LENGTH:
            # a drive of protocol 1 (its session_open has no version): open
            # its way; what needs protocol 2 refuses it (require_protocol)
            with self._lock:
                self._seq = (self._seq + 1) & 0xFF
                seq = self._seq
                ev, box = threading.Event(), []
                self._opening = (nonce, seq, ev, box)
            data = codec.encode("session_open", seq, nonce=nonce, protocol_version=0)[:-2]
            reply = self._open_exchange(data, ev, box, timeout, retries)
            self.drive_protocol = 1
        if reply.name == "error":
            code = reply.fields["code"]
            if code == pg.ErrorCode.NOT_SUPPORTED:
                raise DriveError(
                    "session_open",
                    reply.fields,
                    f"the drive speaks protocol version {reply.fields['arg']}, this contour "
                    f"speaks {pg.PROTOCOL_VERSION}: use a contour of the drive's version, or "
                    "update the drive's firmware from its bootloader (contour flash)",
                )
            if code != pg.ErrorCode.UNKNOWN_MESSAGE:
                raise DriveError(
                    "session_open", reply.fields, describe_error("session_open", reply.fields)
                )
            # firmware older than sessions: at least no command of this
            # session can be taken for a replay of the last one
            self.drive_protocol = 1
            self.request("status_get", timeout=timeout, retries=retries)
            return
        self.drive_protocol = reply.fields.get("protocol_version", 1)
        self.session = nonce

    def _open_exchange(self, data: bytes, ev, box: list, timeout, retries) -> codec.Decoded:
        try:
            self._exchange("session_open", data, ev, timeout, retries)
        finally:
            with self._lock:
                self._opening = None
        self.drain_unsolicited()  # queued before the session: none of ours
        return box[0]

    def require_protocol(self, what: str, version: int = pg.PROTOCOL_VERSION) -> None:
        """Refuse a drive whose protocol is older than `version` for `what`."""
        if not self._synced:
            self.request("status_get")
        if self.drive_protocol < version:
            raise UserError(
                f"{what} needs a drive of protocol version {version}; this drive speaks "
                f"version {self.drive_protocol}: update its firmware (contour flash)"
            )

    def unsolicited(self, timeout: float = 0.0):
        """Next (timestamp, Decoded) status/telemetry message, or None."""
        try:
            return self._unsol.get(timeout=timeout) if timeout > 0 else self._unsol.get_nowait()
        except queue.Empty:
            return None

    def drain_unsolicited(self) -> None:
        while self.unsolicited() is not None:
            pass

    def close(self) -> None:
        self.t.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ---- conveniences -----------------------------------------------------------

    def identify(self) -> dict:
        return self.request("identify").fields

    def status(self) -> dict:
        return self.request("status_get").fields

    def get_param(self, name: str) -> int:
        _, pid = parse_param(name)
        return self.request("param_get", param=pid).fields["value"]

    def set_param(self, name: str, value: int) -> int:
        _, pid = parse_param(name)
        return self.request("param_set", param=pid, value=int(value)).fields["value"]

    def enable(self, on: bool = True, axes: Optional[int] = None) -> None:
        if axes is None:
            axes = self.identify()["axes"]
        self.request("enable", axis_mask=(1 << axes) - 1, on=int(on))


class Pending:
    """A request in flight (:meth:`Client.submit`)."""

    def __init__(self, client, name, msg, seq, data, ev, box) -> None:
        self.c, self.name, self.msg, self.seq = client, name, msg, seq
        self._data, self._ev, self._box = data, ev, box

    def cancel(self) -> None:
        """Forget it (its reply, if any, is dropped as stale)."""
        with self.c._lock:
            self.c._pending.pop(self.seq, None)

    def result(
        self, timeout: Optional[float] = None, retries: Optional[int] = None
    ) -> codec.Decoded:
        c = self.c
        try:
            c._exchange(self.name, self._data, self._ev, timeout, retries, sent=True)
        finally:
            with c._lock:
                c._pending.pop(self.seq, None)
        reply = self._box[0]
        if reply.name == "error":
            raise DriveError(self.name, reply.fields, describe_error(self.name, reply.fields))
        if self.msg.reply and reply.name != self.msg.reply:
            raise codec.ProtocolError(
                f"{self.name}: drive answered {reply.name}, expected {self.msg.reply}"
            )
        return reply


def connect(
    port: Optional[str] = None,
    can: Optional[str] = None,
    node: int = 1,
    timeout: float = 0.5,
    retries: int = 3,
    **kw: Any,
) -> Client:
    return Client(open_transport(port=port, can=can, node=node, **kw), timeout, retries)


def add_link_arguments(parser) -> None:
    """The shared drive-link options (contour.link.options) on a sub-command;
    new commands take them with ``parents=[link_options()]``."""
    from contour.link.options import add_link_options

    add_link_options(parser)


def connect_from_args(args, **kw: Any) -> Client:
    """A client on the drive the link options name (contour.link.options)."""
    from contour.link.options import connect_from_args as connect_with_options

    return connect_with_options(args, **kw)


def wait_until(pred, timeout: float, poll: float = 0.01) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(poll)
    return pred()
