"""The simulated drive on a CANopen bus: the python `canopen` master (a master
nobody here wrote) reaches it through `sim serve`'s SLCAN pty (issue 19,
docs/canopen.md)."""

from __future__ import annotations

import time
from pathlib import Path

import can
import canopen
import pytest
from canopen.sdo.exceptions import SdoAbortedError
from contour import protocol_gen as pg
from contour.link.client import connect
from contour.sim.serve import spawn

EDS = Path(__file__).resolve().parents[2] / "protocol" / "contour.eds"


@pytest.fixture(scope="module")
def served():
    with spawn() as s:
        yield s


@pytest.fixture(scope="module")
def network(served):
    net = canopen.Network()
    net.connect(interface="slcan", channel=served.slcan, bitrate=500000)
    try:
        yield net
    finally:
        net.disconnect()


class _Counter(can.Listener):
    def __init__(self) -> None:
        self.ours = 0
        self.standard = 0

    def on_message_received(self, msg) -> None:
        if msg.is_extended_id and pg.can_split(msg.arbitration_id) is not None:
            self.ours += 1
        elif not msg.is_extended_id:
            self.standard += 1


def test_scan_sees_only_canopen_nodes_while_our_telemetry_streams(served, network):
    """Our protocol streams telemetry (set up over the serial link) on its
    29-bit ids; the master's scanner, which masks ids with 0x780 / 0x7F and
    does not look at IDE, must still find node 1 only (protocol 2's 11-bit
    pos frame 0x1C1 made it report a false node 65)."""
    counter = _Counter()
    network.notifier.add_listener(counter)
    with connect(port=served.serial, timeout=1.0) as c:
        c.set_param("telem_period_ms", 10)  # ~900 frames/s: 30 % of the 500 kbit/s bus
        try:
            time.sleep(0.3)
            network.scanner.reset()
            network.scanner.search()
            time.sleep(1.0)
            assert network.scanner.nodes == [1]
        finally:
            c.set_param("telem_period_ms", 0)
    network.notifier.remove_listener(counter)
    assert counter.ours > 300, counter.ours  # the telemetry did stream on the bus


def _node(net) -> canopen.RemoteNode:
    node = canopen.RemoteNode(1, canopen.ObjectDictionary())
    net.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 2.0
    return node


def test_scan_finds_exactly_node_1(network):
    network.scanner.reset()
    network.scanner.search()
    time.sleep(1.0)
    assert network.scanner.nodes == [1]


def test_sdo_reads_device_type_identity_and_name(network):
    node = _node(network)
    assert int.from_bytes(node.sdo.upload(0x1000, 0), "little") == 0x00020192
    assert node.sdo.upload(0x1018, 0) == b"\x04"
    revision = int.from_bytes(node.sdo.upload(0x1018, 3), "little")
    assert revision != 0  # the firmware version (major << 16 | minor << 8 | patch)
    assert node.sdo.upload(0x1008, 0) == b"contour axis drive"  # segmented


def test_sdo_write_and_abort_codes(network):
    node = _node(network)
    node.sdo.download(0x2000, 0, b"Z axis, left gantry")  # segmented download
    assert node.sdo.upload(0x2000, 0) == b"Z axis, left gantry"
    with pytest.raises(SdoAbortedError) as e:
        node.sdo.download(0x1000, 0, b"\x00\x00\x00\x00")
    assert e.value.code == 0x06010002
    with pytest.raises(SdoAbortedError) as e:
        node.sdo.upload(0x1234, 0)
    assert e.value.code == 0x06020000


def test_master_with_our_eds_reads_objects_by_name(network):
    node = canopen.RemoteNode(1, str(EDS))
    network.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 2.0
    assert node.sdo["Device type"].raw == 0x00020192
    assert node.sdo["Manufacturer device name"].raw == "contour axis drive"
    assert node.sdo["Identity object"]["Highest sub-index supported"].raw == 4
    node.sdo["Error behavior object"]["Communication error"].raw = 1
    assert node.sdo["Error behavior object"]["Communication error"].raw == 1
    with pytest.raises(SdoAbortedError) as e:
        node.sdo["Error behavior object"]["Communication error"].raw = 3
    assert e.value.code == 0x06090031


def test_nmt_state_from_heartbeat(network):
    node = _node(network)
    node.sdo.download(0x1017, 0, (100).to_bytes(2, "little"))
    node.nmt.send_command(0x01)  # start
    node.nmt.wait_for_heartbeat(timeout=2.0)
    node.nmt.wait_for_heartbeat(timeout=2.0)
    assert node.nmt.state == "OPERATIONAL"
    node.nmt.send_command(0x80)  # pre-operational
    node.nmt.wait_for_heartbeat(timeout=2.0)
    node.nmt.wait_for_heartbeat(timeout=2.0)
    assert node.nmt.state == "PRE-OPERATIONAL"


def test_cia402_enable_and_back_through_controlword(network):
    node = canopen.RemoteNode(1, str(EDS))
    network.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 2.0

    def status() -> int:
        time.sleep(0.05)  # the drive's main loop refreshes 0x6041
        return node.sdo["Statusword"].raw

    assert status() & 0x6F in (0x40, 0x60)  # switch on disabled (bit 5 undefined)
    node.sdo["Controlword"].raw = 0x06
    assert status() & 0x6F == 0x21
    node.sdo["Controlword"].raw = 0x07
    assert status() & 0x6F == 0x23
    node.sdo["Controlword"].raw = 0x0F
    sw = status()
    assert sw & 0x6F == 0x27, hex(sw)
    assert sw & 0x10, "voltage enabled: the drive is enabled"
    node.sdo["Controlword"].raw = 0x06  # shutdown: 8
    sw = status()
    assert sw & 0x6F == 0x21, hex(sw)
    assert not sw & 0x10, "the drive is disabled again"


def _wait_sw(node, mask: int, want: int, timeout: float) -> int:
    end = time.monotonic() + timeout
    while True:
        sw = node.sdo["Statusword"].raw
        if sw & mask == want or time.monotonic() > end:
            return sw
        time.sleep(0.02)


def test_profile_position_and_homing(network):
    """PP (0x6060 = 1): a set-point on controlword bit 4, absolute then
    relative, acknowledged in bit 12, done in bit 10; homing (6) on the
    simulated X axis's switch (-21.3 mm) and index (-20 mm table)."""
    node = canopen.RemoteNode(1, str(EDS))
    network.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 2.0
    node.sdo["Modes of operation"].raw = 1
    node.sdo["Profile velocity"].raw = 20_000_000  # 20 mm/s
    for cw in (0x06, 0x07, 0x0F):
        node.sdo["Controlword"].raw = cw
    assert _wait_sw(node, 0x6F, 0x27, 1.0) & 0x6F == 0x27
    node.sdo["Target position"].raw = 3_000_000
    node.sdo["Controlword"].raw = 0x1F  # new set-point
    assert node.sdo["Statusword"].raw & 0x1000, "set-point acknowledged"
    node.sdo["Controlword"].raw = 0x0F
    assert not node.sdo["Statusword"].raw & 0x1000
    time.sleep(0.1)
    assert _wait_sw(node, 0x0400, 0x0400, 3.0) & 0x0400, "target reached"
    assert abs(node.sdo["Position actual value"].raw - 3_000_000) < 5000
    node.sdo["Target position"].raw = -1_000_000
    node.sdo["Controlword"].raw = 0x5F  # relative
    node.sdo["Controlword"].raw = 0x4F
    time.sleep(0.1)
    _wait_sw(node, 0x0400, 0x0400, 3.0)
    assert abs(node.sdo["Position actual value"].raw - 2_000_000) < 5000
    with pytest.raises(SdoAbortedError) as e:
        node.sdo["Homing method"].raw = 3
    assert e.value.code == 0x06090030
    node.sdo["Modes of operation"].raw = 6
    node.sdo["Homing method"].raw = 1  # negative switch, then the index
    node.sdo["Homing speeds"]["Speed during search for switch"].raw = 20_000_000
    node.sdo["Homing speeds"]["Speed during search for zero"].raw = 5_000_000
    node.sdo["Home offset"].raw = -20_000_000
    node.sdo["Controlword"].raw = 0x1F
    sw = _wait_sw(node, 0x3400, 0x1400, 10.0)
    assert sw & 0x3400 == 0x1400, hex(sw)  # homing attained, no error, at rest
    assert abs(node.sdo["Position actual value"].raw + 20_000_000) < 5000
    node.sdo["Controlword"].raw = 0x06
    node.sdo["Modes of operation"].raw = 0
