"""CiA 402 multi-axis objects: axes 1 and 2 of the drive (Y, Z) at 0x6800
and 0x7000 as logical devices of node 1, driven by the python `canopen`
master against `sim serve` (issue 19, docs/canopen.md, co_drive.h)."""

from __future__ import annotations

import time
from pathlib import Path

import canopen
import pytest
from canopen.sdo.exceptions import SdoAbortedError
from contour.sim.serve import spawn

EDS = Path(__file__).resolve().parents[2] / "protocol" / "contour.eds"


@pytest.fixture(scope="module")
def node():
    with spawn() as s:
        net = canopen.Network()
        net.connect(interface="slcan", channel=s.slcan, bitrate=500000)
        try:
            n = canopen.RemoteNode(1, str(EDS))
            net.add_node(n)
            n.sdo.RESPONSE_TIMEOUT = 2.0
            yield n
        finally:
            net.disconnect()


def _wait(node, name: str, mask: int, want: int, timeout: float) -> int:
    end = time.monotonic() + timeout
    while True:
        sw = node.sdo[name].raw
        if sw & mask == want or time.monotonic() > end:
            return sw
        time.sleep(0.02)


def _enable(node, axis: int) -> None:
    for cw in (0x06, 0x07, 0x0F):
        node.sdo[f"Axis {axis} controlword"].raw = cw
    sw = _wait(node, f"Axis {axis} statusword", 0x6F, 0x27, 1.0)
    assert sw & 0x6F == 0x27, hex(sw)


def test_profile_position_on_axis_1(node):
    sdo = node.sdo
    x0 = sdo["Position actual value"].raw
    y0 = sdo["Axis 1 position actual value"].raw
    assert sdo["Axis 1 statusword"].raw & 0x6F in (0x40, 0x60)  # its own state machine
    with pytest.raises(SdoAbortedError) as e:
        sdo["Axis 1 modes of operation"].raw = 6  # homing: axis 0 only
    assert e.value.code == 0x06090030
    sdo["Axis 1 modes of operation"].raw = 1
    assert sdo["Axis 1 modes of operation display"].raw == 1
    _enable(node, 1)
    assert sdo["Statusword"].raw & 0x6F in (0x40, 0x60), "axis 0 stays switch on disabled"
    sdo["Profile velocity"].raw = 20_000_000
    sdo["Axis 1 target position"].raw = y0 + 2_000_000
    sdo["Axis 1 controlword"].raw = 0x1F
    assert sdo["Axis 1 statusword"].raw & 0x1000, "set-point acknowledged"
    sdo["Axis 1 controlword"].raw = 0x0F
    time.sleep(0.1)
    _wait(node, "Axis 1 statusword", 0x0400, 0x0400, 3.0)
    assert abs(sdo["Axis 1 position actual value"].raw - (y0 + 2_000_000)) < 5000
    assert abs(sdo["Position actual value"].raw - x0) < 5000, "X held"
    sdo["Axis 1 controlword"].raw = 0x06
    assert _wait(node, "Axis 1 statusword", 0x6F, 0x21, 1.0) & 0x10 == 0, "drive disabled"


def test_cyclic_synchronous_position_on_axis_2(node):
    sdo = node.sdo
    node.nmt.send_command(0x01)  # SYNC acts in OPERATIONAL
    z0 = sdo["Axis 2 position actual value"].raw
    y0 = sdo["Axis 1 position actual value"].raw
    sdo["Axis 2 target position"].raw = z0
    sdo["Axis 2 modes of operation"].raw = 8
    _enable(node, 2)
    assert sdo["Axis 2 statusword"].raw & 0x1000, "following the target"
    for k in range(1, 101):  # 1 mm in 100 steps of 10 um
        sdo["Axis 2 target position"].raw = z0 + 10_000 * k
        node.network.sync.transmit()
    time.sleep(0.3)
    assert abs(sdo["Axis 2 position actual value"].raw - (z0 + 1_000_000)) < 5000
    assert abs(sdo["Axis 1 position actual value"].raw - y0) < 5000, "Y held"
    sdo["Axis 2 controlword"].raw = 0x06
    sdo["Axis 2 modes of operation"].raw = 0
    node.nmt.send_command(0x80)
