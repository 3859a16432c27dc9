"""Two simulated drives on one CAN bus (`sim serve --drives 2`), driven by
the python `canopen` master (a master nobody here wrote) through the SLCAN
pty exactly as through a USB-CAN adapter: scan, identity, the EDS, the 402
state machine, PDO mapping by SDO, and a CSP move of both drives in step
with SYNC (issue 19, docs/canopen.md)."""

from __future__ import annotations

import time
from pathlib import Path

import canopen
import pytest
from contour import protocol_gen as pg
from contour.link.client import connect
from contour.sim.serve import spawn

EDS = Path(__file__).resolve().parents[2] / "protocol" / "contour.eds"


@pytest.fixture(scope="module")
def bus():
    with spawn(["--drives", "2"]) as s:
        net = canopen.Network()
        net.connect(interface="slcan", channel=s.slcan, bitrate=1000000)
        try:
            yield s, net
        finally:
            net.disconnect()


def _nodes(net) -> list[canopen.RemoteNode]:
    out = []
    for n in (1, 2):
        node = canopen.RemoteNode(n, str(EDS))
        net.add_node(node)
        node.sdo.RESPONSE_TIMEOUT = 2.0
        out.append(node)
    return out


def test_scan_finds_both_drives_and_their_identity(bus):
    _, net = bus
    net.scanner.reset()
    net.scanner.search()
    time.sleep(1.0)
    assert sorted(net.scanner.nodes) == [1, 2]
    for n in (1, 2):
        node = canopen.RemoteNode(n, canopen.ObjectDictionary())
        net.add_node(node)
        node.sdo.RESPONSE_TIMEOUT = 2.0
        assert int.from_bytes(node.sdo.upload(0x1000, 0), "little") == 0x00020192
        assert node.sdo.upload(0x1018, 0) == b"\x04"
        assert int.from_bytes(node.sdo.upload(0x1018, 3), "little") != 0


def test_pdo_mapping_changed_by_sdo_then_used(bus):
    _, net = bus
    node = _nodes(net)[1]
    node.tpdo.read()
    t3 = node.tpdo[3]
    assert not t3.enabled
    t3.clear()
    t3.add_variable("Position actual value")
    t3.add_variable("Modes of operation display")
    t3.trans_type = 1
    t3.cob_id = 0x380 + 2
    t3.enabled = True
    t3.save()  # disable, map, enable: the CiA 301 sequence
    node.nmt.state = "OPERATIONAL"
    time.sleep(0.05)
    node.sdo["Modes of operation"].raw = 8
    net.sync.transmit()
    t3.wait_for_reception(timeout=1.0)
    assert t3["Modes of operation display"].raw == 8
    assert t3["Position actual value"].raw == node.sdo["Position actual value"].raw
    node.sdo["Modes of operation"].raw = 0
    with pytest.raises(canopen.sdo.exceptions.SdoAbortedError) as e:
        node.sdo["Modes of operation"].raw = 3  # profile velocity: not built
    assert e.value.code == 0x06090030


def test_both_drives_move_in_step_with_sync_in_csp(bus):
    served, net = bus
    nodes = _nodes(net)
    net.nmt.state = "OPERATIONAL"  # broadcast
    time.sleep(0.05)
    seen: dict[int, list[int]] = {1: [], 2: []}
    start = []
    for node in nodes:
        node.tpdo.read()
        node.rpdo.read()
        node.sdo["Modes of operation"].raw = 8
        for cw in (0x06, 0x07, 0x0F):
            node.sdo["Controlword"].raw = cw
        time.sleep(0.05)
        sw = node.sdo["Statusword"].raw
        assert sw & 0x6F == 0x27 and sw & 0x1000, hex(sw)  # enabled, following the target
        start.append(node.sdo["Position actual value"].raw)
        node.tpdo[2].add_callback(
            lambda m, n=node.id: seen[n].append(m["Position actual value"].raw)
        )
    step = 1500  # nm per SYNC: 0.75 mm/s at 500 Hz
    cycles = 400
    for k in range(1, cycles + 1):
        for node, p0 in zip(nodes, start):
            node.rpdo[2]["Controlword"].raw = 0x0F
            node.rpdo[2]["Target position"].raw = p0 + k * step
            node.rpdo[2].transmit()
        net.sync.transmit()
        time.sleep(0.002)
    time.sleep(0.3)
    net.sync.transmit()
    time.sleep(0.1)
    for node, p0 in zip(nodes, start):
        moved = node.sdo["Position actual value"].raw - p0
        assert abs(moved - cycles * step) < 2000, moved  # within 2 um of the last target
    # in step: the k-th TPDO of each drive (the same SYNC) holds the same sample
    n = min(len(seen[1]), len(seen[2]))
    assert n > cycles // 2
    skew = max(abs((a - start[0]) - (b - start[1])) for a, b in zip(seen[1][:n], seen[2][:n]))
    assert skew <= 1000, skew  # nm
    # each drive ran every target as a block, none refused
    for node_id, path in ((1, served.serial), (2, served.serials[2])):
        with connect(port=path, timeout=1.0) as c:
            st = c.status()
            assert st["faults"] == 0 and st["blocks_done"] >= cycles * 0.9, (node_id, st)
    for node in nodes:
        node.sdo["Controlword"].raw = 0x06  # shutdown: the drive is disabled again
        assert not node.sdo["Statusword"].raw & 0x10


def test_contour_scan_lists_both_drives_with_both_protocols():
    from contour.commands.scan import scan

    with spawn(["--drives", "2", "--node", "4"]) as s:
        found = scan({"interface": "slcan", "channel": s.slcan, "bitrate": 1000000}, 2.5)
    assert sorted(found) == [4, 5]
    for e in found.values():
        assert e["protocol_version"] == pg.PROTOCOL_VERSION and e["state"] == "disabled"
        assert e["canopen"] in ("pre-operational", "boot-up")  # and CANopen's
