"""The host client without a drive: retries keep the sequence number (so the
drive's replay cache makes them safe), errors become specific messages, and
the command-line link options are checked before anything is opened."""

from __future__ import annotations

import pytest
from contour import protocol_gen as pg
from contour.errors import UsageError, UserError
from contour.link import codec
from contour.link.client import Client, DriveError, parse_param, parse_value
from contour.link.transport import CanBus, LinkError, open_transport, parse_can_spec


class FakeTransport:
    """Answers like a drive; drops the first `drop` replies. `backlog`:
    messages of an earlier session delivered before the session_reply;
    `legacy`: firmware without sessions (session_open is unknown)."""

    def __init__(
        self, drop: int = 0, refuse: bool = False, backlog: tuple = (), legacy: bool = False
    ) -> None:
        self.sent: list[bytes] = []
        self.drop = drop
        self.refuse = refuse
        self.backlog = list(backlog)
        self.legacy = legacy
        self.wrong_first = False
        self.on = None

    def start(self, on):
        self.on = on

    def send(self, data: bytes) -> None:
        self.sent.append(data)
        if self.drop:
            self.drop -= 1
            return
        req = codec.decode(data)
        if req.name == "session_open":
            for old in self.backlog:
                self.on(old, 0.0)
            self.backlog = []
            if self.legacy:
                reply = codec.encode("error", req.seq, req=req.id, code=1, arg=req.id, lo=0, hi=0)
            else:
                reply = codec.encode(
                    "session_reply", req.seq, nonce=req.fields["nonce"], sessions=2
                )
        elif self.refuse and req.name == "param_set":
            reply = codec.encode("error", req.seq, req=req.id, code=4, arg=1, lo=0, hi=60000)
        elif req.name == "status_get":
            reply = codec.encode("drive_state", req.seq)
        else:
            if self.wrong_first:
                self.wrong_first = False
                self.on(codec.encode("ack", req.seq, req=pg.MSG_BY_NAME["stop"].id), 0.0)
            reply = codec.encode("param_value", req.seq, param=req.fields["param"], value=5)
        self.on(reply, 0.0)

    def close(self) -> None:
        pass


def test_lost_reply_is_retried_with_the_same_seq():
    t = FakeTransport()
    c = Client(t, timeout=0.05, retries=3)
    c.status()
    t.drop = 2
    assert c.get_param("comm_timeout_ms") == 5
    assert len(t.sent) == 5 and t.sent[2] == t.sent[3] == t.sent[4]
    assert c.retried == 2


def test_first_command_of_a_session_is_preceded_by_session_open():
    t = FakeTransport()
    c = Client(t, timeout=0.05)
    c.set_param("comm_timeout_ms", 5)
    assert [codec.decode(m).name for m in t.sent] == ["session_open", "param_set"]
    assert c.session == codec.decode(t.sent[0]).fields["nonce"]


def test_firmware_without_sessions_gets_a_harmless_first_request():
    t = FakeTransport(legacy=True)
    c = Client(t, timeout=0.05)
    c.set_param("comm_timeout_ms", 5)
    names = [codec.decode(m).name for m in t.sent]
    assert names == ["session_open", "status_get", "param_set"]
    assert c.session is None


def test_an_earlier_sessions_replies_are_never_taken_for_ours():
    """The drive's transmit backlog of a killed session arrives first: replies
    under every seq this session will use, and telemetry. None of it may
    answer a request of this session."""
    t0 = FakeTransport()
    c0 = Client(t0, timeout=0.05)
    c0.status()
    seq0 = codec.decode(t0.sent[-1]).seq
    stale = [codec.encode("param_value", (seq0 + k) & 0xFF, param=0, value=99) for k in range(1, 8)]
    stale.append(codec.encode("ack", (seq0 + 2) & 0xFF, req=pg.MSG_BY_NAME["param_set"].id))
    stale.append(codec.encode("session_reply", (seq0 + 1) & 0xFF, nonce=1234, sessions=1))
    telemetry = codec.encode("status", 0, state=2)
    t = FakeTransport(backlog=(*stale, telemetry))
    c = Client(t, timeout=0.05, retries=0)
    c._seq = seq0  # the next session happens to continue the same seq counter
    assert c.get_param("comm_timeout_ms") == 5
    assert c.stale_replies == len(stale)
    assert c.unsolicited() is None


def test_a_reply_of_another_request_under_the_same_seq_is_dropped():
    t = FakeTransport()
    c = Client(t, timeout=0.05, retries=1)
    c.status()
    t.wrong_first = True  # a stale ack under the param_get's seq comes first
    assert c.get_param("comm_timeout_ms") == 5
    assert c.stale_replies == 1 and c.retried == 0


def test_no_reply_at_all_is_a_clear_link_error():
    t = FakeTransport(drop=100)
    c = Client(t, timeout=0.01, retries=1)
    with pytest.raises(LinkError, match="no reply from the drive to session_open after 2 tries"):
        c.status()


def test_error_reply_names_parameter_and_range():
    c = Client(FakeTransport(refuse=True), timeout=0.05)
    with pytest.raises(DriveError, match=r"comm_timeout_ms out of range \[0, 60000\]") as e:
        c.set_param("comm_timeout_ms", 70000)
    assert e.value.code == pg.ErrorCode.OUT_OF_RANGE


def test_parameter_names_and_values_are_checked():
    assert parse_param("position.y")[1] == pg.PARAM_BY_NAME["position"].id + 1
    assert parse_param("position.2")[1] == pg.PARAM_BY_NAME["position"].id + 2
    with pytest.raises(UserError, match="per axis"):
        parse_param("position")
    with pytest.raises(UserError, match="unknown parameter"):
        parse_param("bogus")
    with pytest.raises(UserError, match="not per axis"):
        parse_param("comm_timeout_ms.x")
    p = pg.PARAM_BY_NAME["comm_timeout_ms"]
    assert parse_value(p, "0x10") == 16
    with pytest.raises(UserError, match="out of range"):
        parse_value(p, "60001")


def test_link_selection_strings():
    # the channel is python-can's text verbatim: slcan's @N is the serial baud
    assert parse_can_spec("slcan:/dev/pts/3@115200") == CanBus("slcan", "/dev/pts/3@115200")
    assert parse_can_spec("socketcan:can0") == CanBus("socketcan", "can0")
    for bad in ("can0", "slcan:", ":x", "slcan:/dev/x@fast", "socketcan:can0@500000"):
        with pytest.raises(UsageError):
            parse_can_spec(bad)
    with pytest.raises(UsageError, match="exactly one"):
        open_transport()
    with pytest.raises(LinkError, match="cannot open serial port"):
        open_transport(port="/nonexistent/tty")
    with pytest.raises(UsageError, match="node"):
        open_transport(can="virtual:x", node=128)


def test_virtual_can_bus_round_trip_through_isotp():
    """A host and a tiny drive stand-in on python-can's virtual bus: the
    ISO-TP path of CanTransport carries a 40-byte reply."""
    import threading

    import can
    import isotp
    from contour.link.transport import CanTransport

    chan = "contour-test-vbus"
    drive_bus = can.Bus(interface="virtual", channel=chan)
    addr = isotp.Address(
        isotp.AddressingMode.Normal_29bits,
        txid=pg.can_id(pg.CAN_FUNC["response"], 5),
        rxid=pg.can_id(pg.CAN_FUNC["request"], 5),
    )
    stack = isotp.CanStack(drive_bus, address=addr, params={"blocking_send": False})
    stop = threading.Event()

    def drive():
        while not stop.is_set():
            stack.process()
            data = stack.recv()
            if data:
                req = codec.decode(bytes(data))
                if req.name == "session_open":
                    n = req.fields["nonce"]
                    stack.send(codec.encode("session_reply", req.seq, nonce=n, sessions=1))
                else:
                    stack.send(codec.encode("drive_state", req.seq, state=1, pos=[1, 2, 3, 0]))
            stop.wait(0.001)

    th = threading.Thread(target=drive, daemon=True)
    th.start()
    try:
        t = CanTransport(f"virtual:{chan}", node=5)
        c = Client(t, timeout=0.5)
        st = c.status()
        assert st["state"] == 1 and st["pos"][:3] == [1, 2, 3]
        c.close()
    finally:
        stop.set()
        th.join(timeout=1)
        drive_bus.shutdown()


def test_scan_lists_several_nodes_and_sends_nothing():
    import threading

    import can
    from contour.commands.scan import scan

    chan = "contour-test-scan"
    drives = can.Bus(interface="virtual", channel=chan, receive_own_messages=False)
    seen: list = []
    stop = threading.Event()

    def beat():
        hb = pg.MSG_BY_NAME["heartbeat"]
        while not stop.is_set():
            for node in (3, 7):
                data = codec.encode_payload(
                    hb, {"state": 1, "axes": 3, "protocol_version": 1, "fw_version": 0x000100}
                )
                drives.send(
                    can.Message(arbitration_id=pg.can_id(31, node), data=data, is_extended_id=True)
                )
            # a CANopen node's heartbeat (pre-operational) and a protocol-2
            # drive's 11-bit heartbeat (0x7C0 | node)
            drives.send(can.Message(arbitration_id=0x700 + 9, data=b"\x7f", is_extended_id=False))
            old = codec.encode_payload(
                hb, {"state": 1, "axes": 3, "protocol_version": 2, "fw_version": 0x000100}
            )
            drives.send(can.Message(arbitration_id=0x7C0 | 12, data=old, is_extended_id=False))
            while (m := drives.recv(timeout=0)) is not None:
                seen.append(m)  # anything the scanner transmitted
            stop.wait(0.05)

    th = threading.Thread(target=beat, daemon=True)
    th.start()
    try:
        found = scan(f"virtual:{chan}", 0.4)
    finally:
        stop.set()
        th.join(timeout=1)
        drives.shutdown()
    assert sorted(found) == [3, 7, 9, 12]
    assert found[9]["canopen"] == "pre-operational" and "state" not in found[9]
    assert found[12]["state"] == "old-ids" and found[12]["protocol_version"] == 2
    assert found[3]["protocol_version"] == 1 and "canopen" not in found[3]
    assert found[7]["state"] == "ready" and found[3]["firmware_version"] == "0.1.0"
    assert seen == []
