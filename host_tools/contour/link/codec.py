"""Message codec and serial framing of the contour protocol (host side).

The tables come from :mod:`contour.protocol_gen` (generated from
``protocol/contour.toml``); this module only knows the rules of
``protocol/README.md``:

- a message is ``msg_id | seq | payload``, fields little-endian at fixed
  offsets, ``i48`` a sign-extended 6-byte integer, a ``bytes`` tail last;
- a serial frame is ``0x00 COBS(message | crc16_be) 0x00`` with
  CRC-16/CCITT-FALSE.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Optional

from contour import protocol_gen as pg
from contour.errors import UserError

FRAME_BODY_MAX = pg.MSG_HDR + pg.MAX_PAYLOAD + 2
FRAME_ENC_MAX = FRAME_BODY_MAX + 1


class ProtocolError(UserError):
    """A message that does not fit the protocol definition."""


class Decoded(NamedTuple):
    name: str
    id: int
    seq: int
    fields: dict


def crc16(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE, as crc16_update in firmware/core/crc.c."""
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def _int(raw: bytes, ftype: str) -> int:
    return int.from_bytes(raw, "little", signed=ftype.startswith("i"))


def encode_payload(msg: pg.Message, fields: dict) -> bytes:
    out = bytearray()
    names = {f.name for f in msg.fields}
    extra = set(fields) - names
    if extra:
        raise ProtocolError(f"{msg.name}: unknown field(s) {', '.join(sorted(extra))}")
    for f in msg.fields:
        default: Any = b"" if f.type == "bytes" else ([0] * f.count if f.count > 1 else 0)
        value: Any = fields.get(f.name, default)
        if f.type == "bytes":
            data = bytes(value)
            if len(data) > f.max:
                raise ProtocolError(f"{msg.name}.{f.name}: {len(data)} bytes > max {f.max}")
            out += data
            continue
        if f.count > 1 and not isinstance(value, (list, tuple)):
            raise ProtocolError(f"{msg.name}.{f.name}: expected a list of {f.count} values")
        values = list(value) if f.count > 1 else [value]
        if f.count > 1 and len(values) < f.count:
            values += [0] * (f.count - len(values))
        if len(values) != f.count:
            raise ProtocolError(f"{msg.name}.{f.name}: expected {f.count} values")
        for v in values:
            try:
                out += int(v).to_bytes(f.size, "little", signed=f.type.startswith("i"))
            except OverflowError:
                raise ProtocolError(
                    f"{msg.name}.{f.name}: {v} does not fit type {f.type}"
                ) from None
    return bytes(out)


def decode_payload(msg: pg.Message, payload: bytes) -> dict:
    if len(payload) < msg.fixed_len or len(payload) > msg.max_len:
        raise ProtocolError(
            f"{msg.name}: payload of {len(payload)} bytes, expected "
            + (
                f"{msg.fixed_len}"
                if msg.fixed_len == msg.max_len
                else f"{msg.fixed_len}..{msg.max_len}"
            )
        )
    out: dict = {}
    for f in msg.fields:
        if f.type == "bytes":
            out[f.name] = bytes(payload[f.offset :])
            continue
        vals = [
            _int(payload[f.offset + k * f.size : f.offset + (k + 1) * f.size], f.type)
            for k in range(f.count)
        ]
        out[f.name] = vals if f.count > 1 else vals[0]
    return out


def encode(name: str, msg_seq: int = 0, /, **fields: Any) -> bytes:
    """Message bytes ``msg_id | seq | payload`` of message `name` (msg_seq is
    the header sequence number; a field may itself be called ``seq``)."""
    msg = pg.MSG_BY_NAME.get(name)
    if msg is None:
        raise ProtocolError(f"unknown message {name!r}")
    return bytes([msg.id, msg_seq & 0xFF]) + encode_payload(msg, fields)


def decode(data: bytes) -> Decoded:
    if len(data) < pg.MSG_HDR:
        raise ProtocolError(f"message of {len(data)} bytes is shorter than its header")
    msg = pg.MSG_BY_ID.get(data[0])
    if msg is None:
        raise ProtocolError(f"unknown message id 0x{data[0]:02X}")
    return Decoded(msg.name, msg.id, data[1], decode_payload(msg, data[pg.MSG_HDR :]))


def decode_cyclic(func: int, payload: bytes) -> Optional[Decoded]:
    """A raw cyclic CAN frame (function code `func`) as a message, or None."""
    msg = CYCLIC_BY_FUNC.get(func)
    if msg is None:
        return None
    return Decoded(msg.name, msg.id, 0, decode_payload(msg, payload))


CYCLIC_BY_FUNC = {m.can_func: m for m in pg.MESSAGES if m.can_func is not None}


# ---- serial framing -------------------------------------------------------------


def cobs_encode(body: bytes) -> bytes:
    out = bytearray([0])
    code_at, code = 0, 1
    for i, b in enumerate(body):
        if b == 0:
            out[code_at] = code
            code_at, code = len(out), 1
            out.append(0)
        else:
            out.append(b)
            code += 1
            if code == 0xFF and i + 1 < len(body):
                out[code_at] = code
                code_at, code = len(out), 1
                out.append(0)
    out[code_at] = code
    return bytes(out)


def cobs_decode(data: bytes) -> Optional[bytes]:
    out = bytearray()
    i = 0
    n = len(data)
    while i < n:
        code = data[i]
        if code == 0 or i + code > n:
            return None
        out += data[i + 1 : i + code]
        i += code
        if code != 0xFF and i < n:
            out.append(0)
    return bytes(out)


def frame(message: bytes) -> bytes:
    """Serial frame of a message (both delimiters included)."""
    if not pg.MSG_HDR <= len(message) <= pg.MSG_HDR + pg.MAX_PAYLOAD:
        raise ProtocolError(f"message of {len(message)} bytes cannot be framed")
    crc = crc16(message)
    return b"\x00" + cobs_encode(message + bytes([crc >> 8, crc & 0xFF])) + b"\x00"


class FrameDecoder:
    """Byte stream to messages, with the drive's rules and counters."""

    def __init__(self) -> None:
        self.buf = bytearray()
        self.discarding = False
        self.frames = 0
        self.errors = {"oversized": 0, "short": 0, "cobs": 0, "crc": 0}

    def feed(self, data: bytes) -> list[bytes]:
        out = []
        for b in data:
            if b:
                if self.discarding:
                    continue
                if len(self.buf) >= FRAME_ENC_MAX:
                    self.discarding = True
                    self.errors["oversized"] += 1
                    self.buf.clear()
                    continue
                self.buf.append(b)
                continue
            if self.discarding:
                self.discarding = False
            elif self.buf:
                m = self._complete(bytes(self.buf))
                if m is not None:
                    out.append(m)
            self.buf.clear()
        return out

    def _complete(self, enc: bytes) -> Optional[bytes]:
        body = cobs_decode(enc)
        if body is None:
            self.errors["cobs"] += 1
            return None
        if len(body) < pg.MSG_HDR + 2:
            self.errors["short"] += 1
            return None
        msg, c = body[:-2], body[-2:]
        if crc16(msg) != (c[0] << 8 | c[1]):
            self.errors["crc"] += 1
            return None
        self.frames += 1
        return msg
