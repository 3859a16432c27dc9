"""Transports of the host link: a serial port (pyserial) or a CAN bus
(python-can, ISO-TP through the `can-isotp` package).

Both deliver whole messages (``msg_id | seq | payload``) to one callback,
``on_message(data: bytes, timestamp: float)``, from their reader thread; raw
cyclic CAN frames arrive there as messages too (id from the CAN function,
seq 0), so the client above does not know which transport it runs on.

Selection strings (see :func:`open_transport`):

- ``--port PATH`` : a device or any pyserial URL (``/dev/ttyUSB0``,
  ``/dev/pts/3``, ``socket://host:port``, ``loop://``);
- a CAN bus named as python-can names it (:class:`CanBus`: interface,
  channel, bitrate; completed from python-can's environment and config
  file) with ``--node N``; the short form ``INTERFACE:CHANNEL``
  (``slcan:/dev/pts/4``, ``socketcan:can0``, ``virtual:bus0``).
  contour.link.options turns the command-line options into these.
"""

from __future__ import annotations

import contextlib
import errno
import threading
import time
from dataclasses import dataclass
from typing import Callable, Optional

from contour import protocol_gen as pg
from contour.errors import UsageError, UserError
from contour.link import codec

OnMessage = Callable[[bytes, float], None]


class LinkError(UserError):
    """The link cannot be opened or failed."""


class SerialTransport:
    kind = "serial"

    def __init__(self, url: str, baudrate: int = 115200) -> None:
        import serial

        self.url = url
        try:
            # exclusive: a second contour command on the same port is told
            # that it is busy instead of stealing half of the replies
            self.ser = serial.serial_for_url(url, baudrate=baudrate, timeout=0.005, exclusive=True)
        except (serial.SerialException, ValueError, OSError) as exc:
            if "exclusively lock" in str(exc):
                raise LinkError(
                    f"serial port {url} is busy: another process holds it "
                    "(another contour command, or a terminal program)"
                ) from None
            raise LinkError(f"cannot open serial port {url}: {exc}") from None
        self.decoder = codec.FrameDecoder()
        self._on: Optional[OnMessage] = None
        self._run = False
        self._thread: Optional[threading.Thread] = None
        self._wlock = threading.Lock()
        self.tx_frames = 0

    def start(self, on_message: OnMessage) -> None:
        self._on = on_message
        self._run = True
        self._thread = threading.Thread(target=self._reader, name="contour-serial", daemon=True)
        self._thread.start()

    def _reader(self) -> None:
        import serial

        while self._run:
            try:
                data = self.ser.read(max(1, self.ser.in_waiting))
            except (serial.SerialException, OSError, TypeError):
                if self._run:
                    time.sleep(0.01)
                continue
            if not data:
                continue
            now = time.time()
            for m in self.decoder.feed(data):
                if self._on is not None:
                    self._on(m, now)

    def send(self, message: bytes) -> None:
        import serial

        with self._wlock:
            try:
                self.ser.write(codec.frame(message))
            except (serial.SerialException, OSError) as exc:
                raise LinkError(f"serial write to {self.url} failed: {exc}") from None
            self.tx_frames += 1

    def rx_errors(self) -> int:
        return sum(self.decoder.errors.values())

    def close(self) -> None:
        self._run = False
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        with contextlib.suppress(Exception):  # closing a dead port
            self.ser.close()


def tx_buffer_full(exc: BaseException) -> bool:
    """python-can's "transmit buffer full": ENOBUFS from SocketCAN, or the
    message text adapters use ("Transmit buffer full", "... overflow", "No
    buffer space available"). The frame was not sent: wait and send again."""
    if errno.ENOBUFS in (getattr(exc, "error_code", None), getattr(exc, "errno", None)):
        return True
    text = str(exc).lower()
    return "buffer" in text and any(w in text for w in ("full", "overflow", "no buffer space"))


# How long one CAN frame may wait out a full transmit buffer before it is
# dropped (the request is then repeated by the client's retry).
TX_FULL_WAIT_S = 2.0


@dataclass(frozen=True)
class CanBus:
    """A CAN bus the way python-can names one: an interface, a channel (its
    text exactly as python-can reads it) and an optional CAN bitrate."""

    interface: Optional[str] = None
    channel: Optional[str] = None
    bitrate: Optional[int] = None

    def __str__(self) -> str:
        text = f"{self.interface or '?'}:{self.channel or '?'}"
        return text + (f" at {self.bitrate} bit/s" if self.bitrate else "")


def parse_can_spec(spec: str) -> CanBus:
    """The short form ``INTERFACE:CHANNEL`` -> CanBus.

    The channel is python-can's channel text, verbatim: for ``slcan`` a
    trailing ``@N`` is the serial baud of the adapter, as python-can reads
    it (``slcan:/dev/ttyACM0@115200``). Any other interface refuses an
    ``@``, which used to mean the CAN bitrate here: that is ``--bitrate``."""
    if ":" not in spec:
        raise UsageError(
            f"--can {spec!r}: expected INTERFACE:CHANNEL, e.g. slcan:/dev/ttyACM0 or "
            "socketcan:can0 (or --interface and --channel)"
        )
    iface, channel = spec.split(":", 1)
    if not iface or not channel:
        raise UsageError(f"--can {spec!r}: interface and channel must not be empty")
    if "@" in channel:
        if iface != "slcan":
            raise UsageError(
                f"--can {spec!r}: '@' is python-can's serial baud of slcan only; "
                "give the CAN bitrate with --bitrate"
            )
        baud = channel.rsplit("@", 1)[1]
        if not baud.isdigit() or int(baud) <= 0:
            raise UsageError(f"--can {spec!r}: serial baud {baud!r} is not a positive integer")
    return CanBus(iface, channel)


def can_bus_config(bus: Optional[CanBus] = None) -> dict:
    """python-can's configuration of `bus`: what `bus` names, completed from
    python-can's own sources in its order (``CAN_INTERFACE``, ``CAN_CHANNEL``,
    ``CAN_BITRATE``, ``CAN_CONFIG`` in the environment, then its config files
    ``~/can.conf``, ``/etc/can.conf``, ``~/.can``, ``~/.canrc``) by
    ``can.util.load_config``. A bus named by none of them is a UsageError."""
    import can

    given: dict = {}
    if bus is not None:
        given = {k: v for k, v in vars(bus).items() if v is not None}
    try:
        cfg = dict(can.util.load_config(config=given))
    except NotImplementedError as exc:  # CanInterfaceNotImplementedError
        if not given.get("interface"):
            raise UsageError(
                "choose the drive: --port PATH, or a CAN bus with --can INTERFACE:CHANNEL or "
                "--interface/--channel (or python-can's CAN_INTERFACE/CAN_CHANNEL environment "
                "or its config file)"
            ) from None
        raise UsageError(f"CAN interface {given['interface']!r}: {exc}") from None
    except ValueError as exc:  # e.g. CAN_CONFIG that is not JSON
        raise UsageError(f"python-can configuration: {exc}") from None
    if cfg.get("channel") is None:
        raise UsageError(
            f"CAN interface {cfg['interface']}: no channel (--channel, --can "
            f"{cfg['interface']}:CHANNEL or CAN_CHANNEL)"
        )
    return cfg


def open_can_bus(bus):
    """A python-can bus from a CanBus, an ``INTERFACE:CHANNEL`` text or a
    python-can config dict (see :func:`can_bus_config`)."""
    import can

    if isinstance(bus, str):
        bus = parse_can_spec(bus)
    cfg = bus if isinstance(bus, dict) else can_bus_config(bus)
    cfg = dict(cfg)
    if cfg.get("interface") == "slcan":
        cfg.setdefault("sleep_after_open", 0.05)  # a pseudo-terminal needs no settling
    name = f"{cfg.get('interface')}:{cfg.get('channel')}"
    try:
        return can.Bus(**cfg)
    except (can.CanError, ValueError, OSError, ImportError, NotImplementedError) as exc:
        raise LinkError(f"cannot open CAN bus {name}: {exc}") from None


class CanTransport:
    """Requests and replies over ISO-TP (can-isotp), cyclic frames raw."""

    kind = "can"

    def __init__(self, bus, node: int, log_file: Optional[str] = None) -> None:
        import can
        import isotp

        if not 1 <= node <= pg.CAN_NODE_MAX:
            raise UsageError(f"--node {node}: must be 1..{pg.CAN_NODE_MAX}")
        self.node = node
        self.bus = open_can_bus(bus)
        self._on: Optional[OnMessage] = None
        self.notifier = can.Notifier(self.bus, [], timeout=0.01)
        self.logger = None
        if log_file:
            self.logger = can.Logger(log_file)
            self.notifier.add_listener(self.logger)
        address = isotp.Address(
            isotp.AddressingMode.Normal_29bits,  # our ids are extended (docs/canopen.md)
            txid=pg.can_id(pg.CAN_FUNC["request"], node),
            rxid=pg.can_id(pg.CAN_FUNC["response"], node),
        )
        self.stack = isotp.NotifierBasedCanStack(
            self.bus,
            self.notifier,
            address=address,
            params={
                "stmin": 0,
                "blocksize": 0,
                "tx_padding": None,
                "rx_flowcontrol_timeout": 1000,
                "rx_consecutive_frame_timeout": 1000,
                "blocking_send": False,
                "max_frame_size": pg.MSG_HDR + pg.MAX_PAYLOAD,
            },
            error_handler=self._isotp_error,
        )
        # can-isotp calls txfn from its own thread, where an exception (e.g.
        # python-can's transmit-buffer-full CanOperationError) would end the
        # thread and with it the link: send through _send_frame instead.
        self.stack.txfn = self._send_frame
        self.tx_full_waits = 0
        self.tx_dropped = 0
        self.isotp_errors = 0
        self.rx_frames = 0
        # every frame of this node on the bus, both ways (bus load figures)
        self.bus_tx_frames = 0
        self.bus_rx_frames = 0
        self._rx_id = pg.can_id(pg.CAN_FUNC["response"], node)
        self._run = False
        self._thread: Optional[threading.Thread] = None
        self._cyclic_ids = {
            pg.can_id(func, node): func for func in codec.CYCLIC_BY_FUNC if func is not None
        }

    def _isotp_error(self, error: Exception) -> None:
        self.isotp_errors += 1

    def _send_frame(self, msg) -> None:
        """can-isotp's transmit function: a full transmit buffer is waited
        out with back-off (1 ms doubling to 50 ms, at most TX_FULL_WAIT_S);
        any other send error drops the frame (counted). Never raises."""
        import can

        frame = can.Message(
            arbitration_id=msg.arbitration_id,
            data=msg.data,
            is_extended_id=msg.is_extended_id,
            is_fd=msg.is_fd,
            bitrate_switch=msg.bitrate_switch,
        )
        delay = 0.001
        deadline = time.monotonic() + TX_FULL_WAIT_S
        while True:
            try:
                self.bus.send(frame)
                self.bus_tx_frames += 1
                return
            except (can.CanError, OSError) as exc:
                if not tx_buffer_full(exc) or time.monotonic() > deadline:
                    self.tx_dropped += 1
                    return
            self.tx_full_waits += 1
            time.sleep(delay)
            delay = min(delay * 2, 0.05)

    def start(self, on_message: OnMessage) -> None:
        self._on = on_message
        self.notifier.add_listener(self._on_frame)
        self.stack.start()
        self._run = True
        self._thread = threading.Thread(target=self._reader, name="contour-isotp", daemon=True)
        self._thread.start()

    def _on_frame(self, frame) -> None:
        if frame.arbitration_id == self._rx_id and frame.is_extended_id:
            self.bus_rx_frames += 1
        func = self._cyclic_ids.get(frame.arbitration_id)
        if func is None or not frame.is_extended_id or self._on is None:
            return
        self.rx_frames += 1
        self.bus_rx_frames += 1
        msg = codec.CYCLIC_BY_FUNC[func]
        self._on(bytes([msg.id, 0]) + bytes(frame.data), frame.timestamp or time.time())

    def _reader(self) -> None:
        while self._run:
            data = self.stack.recv(block=True, timeout=0.05)
            if data and self._on is not None:
                self._on(bytes(data), time.time())

    def send(self, message: bytes) -> None:
        try:
            self.stack.send(message)
        except Exception as exc:  # noqa: BLE001 - isotp raises several kinds
            raise LinkError(f"CAN send failed: {exc}") from None

    def rx_errors(self) -> int:
        return self.isotp_errors

    def close(self) -> None:
        self._run = False
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        with contextlib.suppress(Exception):
            self.stack.stop()
        with contextlib.suppress(Exception):
            self.notifier.stop(timeout=0.5)
        if self.logger is not None:
            self.logger.stop()
        self.bus.shutdown()


def open_transport(
    port: Optional[str] = None,
    can=None,
    node: int = 1,
    **kw,
):
    """The transport to a drive: `port` (serial device or pyserial URL) or
    `can` (a CanBus, ``INTERFACE:CHANNEL`` text or python-can config dict),
    exactly one of them. Keywords: ``baudrate`` (serial), ``log_file`` (CAN)."""
    if bool(port) == bool(can):
        raise UsageError("choose the drive with exactly one of --port PATH or a CAN bus (--can)")
    if port:
        return SerialTransport(port, **{k: v for k, v in kw.items() if k == "baudrate"})
    return CanTransport(can, node, log_file=kw.get("log_file"))
