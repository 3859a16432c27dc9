"""Fault injection for the calibration link: drop or corrupt a fraction of the
frames in transit, in both directions (``contour calibrate --inject-loss P``,
tests, bench).

Serial frames (``0x00 COBS(...) 0x00``) are handled on the byte stream: each
complete frame is, with probability P, either dropped or has one random bit
flipped (half each); the receiver's frame check then throws the corrupted
frame away, exactly as a noisy line would make it. On CAN (no byte stream
here) a hit drops the whole message. Deterministic for a given seed.
"""

from __future__ import annotations

import random
import threading

from contour.errors import UserError
from contour.link import codec


class FrameFaults:
    def __init__(self, rate: float, seed: int = 1) -> None:
        if not 0.0 <= rate < 1.0:
            raise UserError(f"--inject-loss {rate}: must be in [0, 1)")
        self.rate = rate
        self.rng = random.Random(seed)
        self.frames = 0
        self.dropped = 0
        self.corrupted = 0
        self._lock = threading.Lock()

    def hit(self) -> str:
        """'' (pass), 'drop' or 'corrupt' for the next frame."""
        with self._lock:
            self.frames += 1
            if self.rate <= 0 or self.rng.random() >= self.rate:
                return ""
            if self.rng.random() < 0.5:
                self.dropped += 1
                return "drop"
            self.corrupted += 1
            return "corrupt"

    def mangle(self, frame: bytes) -> bytes:
        """Apply a hit to one whole frame (delimiters included)."""
        what = self.hit()
        if what == "drop":
            return b""
        if what == "corrupt":
            b = bytearray(frame)
            with self._lock:
                i = self.rng.randrange(1, len(b) - 1) if len(b) > 2 else 0
                b[i] ^= 1 << self.rng.randrange(8)
            return bytes(b)
        return frame

    def stats(self) -> dict:
        return {"frames": self.frames, "dropped": self.dropped, "corrupted": self.corrupted}


class StreamFaults:
    """Cuts a byte stream into frames at the 0x00 delimiters and mangles whole
    frames (partial frames wait for their end)."""

    def __init__(self, faults: FrameFaults) -> None:
        self.f = faults
        self.buf = bytearray()

    def feed(self, data: bytes) -> bytes:
        out = bytearray()
        for b in data:
            self.buf.append(b)
            if b == 0 and len(self.buf) > 1:
                out += self.f.mangle(b"\x00" + bytes(self.buf).lstrip(b"\x00"))
                self.buf.clear()
        return bytes(out)


class _DecoderShim:
    def __init__(self, inner, stream: StreamFaults) -> None:
        self.inner = inner
        self.stream = stream

    def feed(self, data: bytes):
        return self.inner.feed(self.stream.feed(data))

    @property
    def errors(self):
        return self.inner.errors


def make_lossy(transport, faults: FrameFaults):
    """Wrap an open transport of contour.link (serial or CAN) so that frames
    in both directions suffer `faults`. Returns the same object."""
    if faults.rate <= 0:
        return transport
    if getattr(transport, "kind", "") == "serial":
        transport.decoder = _DecoderShim(transport.decoder, StreamFaults(faults))
        ser, lock = transport.ser, transport._wlock

        def send(message: bytes) -> None:
            data = faults.mangle(codec.frame(message))
            with lock:
                if data:
                    ser.write(data)
                transport.tx_frames += 1

        transport.send = send
        return transport
    inner_send, inner_start = transport.send, transport.start

    def send_can(message: bytes) -> None:
        if faults.hit() == "":
            inner_send(message)

    def start(on_message) -> None:
        def on(data: bytes, ts: float) -> None:
            if faults.hit() == "":
                on_message(data, ts)

        inner_start(on)

    transport.send = send_can
    transport.start = start
    return transport
