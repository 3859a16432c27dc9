"""CiA 402 objects that are drive parameters, the heartbeat consumer 0x1016
and store / restore 0x1010 / 0x1011, through the python `canopen` master
against `sim serve` (issue 19, docs/canopen.md, co_param.h)."""

from __future__ import annotations

import random
import time
from contextlib import contextmanager
from pathlib import Path

import canopen
import pytest
from canopen.sdo.exceptions import SdoAbortedError
from contour import image as img
from contour.link.client import connect
from contour.sim.serve import spawn

EDS = Path(__file__).resolve().parents[2] / "protocol" / "contour.eds"
LOAD_ADDR = 0x08010200  # the simulated drive's application slot (test_config_e2e.py)
SAVE = 0x65766173  # "save"
LOAD = 0x64616F6C  # "load"


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


def _node(net) -> canopen.RemoteNode:
    node = canopen.RemoteNode(1, str(EDS))
    net.add_node(node)
    node.sdo.RESPONSE_TIMEOUT = 2.0
    return node


def _abort(fn) -> int:
    with pytest.raises(SdoAbortedError) as e:
        fn()
    return e.value.code


def _wait_sw(node, mask: int, want: int, timeout: float) -> int:
    end = time.monotonic() + timeout
    while True:
        sw = node.sdo["Statusword"].raw
        if sw & mask == want or time.monotonic() > end:
            return sw
        time.sleep(0.02)


def test_402_objects_are_the_drive_parameters(served, network):
    node = _node(network)
    sdo = node.sdo
    with connect(port=served.serial, timeout=1.0) as c:
        # SDO -> drive parameter (the own protocol reads it back)
        sdo["Max profile velocity"].raw = 500_000_000
        assert c.get_param("max_velocity.x") == 500_000_000
        sdo["Profile acceleration"].raw = 2_000_000  # um/s^2
        assert c.get_param("max_acceleration.x") == 2_000_000_000
        assert sdo["Profile deceleration"].raw == 2_000_000  # one a_max
        sdo["Quick stop deceleration"].raw = 3_000_000
        assert c.get_param("stop_deceleration") == 3_000_000_000
        sdo["Software position limit"]["Min position limit"].raw = -50_000_000
        sdo["Software position limit"]["Max position limit"].raw = 60_000_000
        assert c.get_param("soft_limit_min.x") == -50_000_000
        assert c.get_param("soft_limit_max.x") == 60_000_000
        sdo["Following error window"].raw = 0xFFFFFFFF  # off
        assert c.get_param("following_error_limit.x") == 0
        # drive parameter (own protocol) -> object
        c.set_param("following_error_limit.x", 3_000_000)
        c.set_param("max_velocity.x", 700_000_000)
        time.sleep(0.05)  # the main loop copies them into the objects
        assert sdo["Following error window"].raw == 3_000_000
        assert sdo["Max profile velocity"].raw == 700_000_000
        # ranges: the object's own, then the drive's
        assert _abort(lambda: setattr(sdo["Max profile velocity"], "raw", 999)) == 0x06090032
        assert _abort(lambda: setattr(sdo["Profile acceleration"], "raw", 2_000_000_000)) == (
            0x06090031
        )
        assert _abort(lambda: setattr(sdo["Following error window"], "raw", 0x80000000)) == (
            0x06090031
        )
        assert c.get_param("following_error_limit.x") == 3_000_000  # nothing changed
        # no following-error timeout in the drive: only 0
        sdo["Following error time out"].raw = 0
        assert _abort(lambda: setattr(sdo["Following error time out"], "raw", 10)) == 0x06090031
        # busy while moving: PP 40 mm at 10 mm/s
        sdo["Modes of operation"].raw = 1
        sdo["Profile velocity"].raw = 10_000_000
        for cw in (0x06, 0x07, 0x0F):
            sdo["Controlword"].raw = cw
        assert _wait_sw(node, 0x6F, 0x27, 1.0) & 0x6F == 0x27
        sdo["Target position"].raw = 40_000_000
        sdo["Controlword"].raw = 0x1F
        time.sleep(0.2)
        assert _abort(lambda: setattr(sdo["Max profile velocity"], "raw", 400_000_000)) == (
            0x08000022
        )
        assert c.get_param("max_velocity.x") == 700_000_000
        sdo["Controlword"].raw = 0x02  # quick stop
        time.sleep(0.5)
        sdo["Controlword"].raw = 0x06
        sdo["Modes of operation"].raw = 0
        assert _wait_sw(node, 0x6F, 0x21, 2.0) & 0x6F == 0x21
        sdo["Max profile velocity"].raw = 1_000_000_000  # idle again: taken
        assert c.get_param("max_velocity.x") == 1_000_000_000
        c.set_param("following_error_limit.x", 5_000_000)
        c.set_param("soft_limit_min.x", 0)
        c.set_param("soft_limit_max.x", 0)


MASTER = 0x7E  # the master's node id in these tests


def test_heartbeat_consumer_is_the_communication_watchdog(network):
    """0x1016 watches the master's heartbeat: when it stops during a PP
    move, the drive stops on its path, latches the comm fault (402 FAULT,
    EMCY 0x8130) and leaves OPERATIONAL (0x1029 = 0)."""
    node = _node(network)
    sdo = node.sdo
    entry = sdo["Consumer heartbeat time"]
    assert entry[0].raw == 4
    assert _abort(lambda: setattr(entry[2], "raw", 0x01000000 | 100)) == 0x06090030
    entry[1].raw = MASTER << 16 | 200  # 200 ms
    assert _abort(lambda: setattr(entry[2], "raw", MASTER << 16 | 300)) == 0x06040043
    sdo["Error behavior object"]["Communication error"].raw = 0  # -> pre-operational
    beat = network.send_periodic(0x700 + MASTER, b"\x05", 0.05)
    try:
        node.nmt.send_command(0x01)
        sdo["Modes of operation"].raw = 1
        sdo["Profile velocity"].raw = 10_000_000
        for cw in (0x06, 0x07, 0x0F):
            sdo["Controlword"].raw = cw
        assert _wait_sw(node, 0x6F, 0x27, 1.0) & 0x6F == 0x27
        target = sdo["Position actual value"].raw + 40_000_000
        sdo["Target position"].raw = target
        sdo["Controlword"].raw = 0x1F
        time.sleep(0.5)  # 200 ms of heartbeats missing would have tripped it
        assert _wait_sw(node, 0x6F, 0x27, 0.1) & 0x6F == 0x27, "still enabled, moving"
        node.emcy.reset()
    finally:
        beat.stop()
    emcy = node.emcy.wait(0x8130, timeout=2.0)
    assert emcy is not None, [hex(e.code) for e in node.emcy.log]
    sw = _wait_sw(node, 0x4F, 0x08, 2.0)
    assert sw & 0x4F == 0x08, hex(sw)  # FAULT
    time.sleep(0.3)  # the axis settles once the outputs are off
    p1 = sdo["Position actual value"].raw
    time.sleep(0.2)
    assert abs(sdo["Position actual value"].raw - p1) < 5_000, "at rest"
    assert p1 < target - 20_000_000, "stopped on its way"
    assert node.nmt.state == "PRE-OPERATIONAL"
    entry[1].raw = 0  # unwatched again
    sdo["Controlword"].raw = 0x80  # fault reset
    assert _wait_sw(node, 0x4F, 0x40, 1.0) & 0x4F == 0x40
    sdo["Modes of operation"].raw = 0


def _wait_app(server, timeout: float = 5.0) -> None:
    end = time.monotonic() + timeout
    while True:
        try:
            with connect(port=server.serial) as c:
                if c.identify()["axes"] > 0:
                    return
        except Exception:  # noqa: BLE001 - a drive that just reset: ask again
            pass
        if time.monotonic() > end:
            raise AssertionError("the application did not start")
        time.sleep(0.05)


@contextmanager
def _drive_on(flash: Path, image: Path | None = None):
    """A simulated drive on the flash file (flashed with image first), and
    the python `canopen` master on its bus."""
    with spawn(["--flash", str(flash), "--boot-window-ms", "200" if image else "0"]) as s:
        if image is not None:
            from contour.cli import main as cli

            assert cli(["flash", str(image), "--port", s.serial, "--no-progress"]) == 0
        _wait_app(s)
        net = canopen.Network()
        net.connect(interface="slcan", channel=s.slcan, bitrate=500000)
        try:
            yield s, _node(net)
        finally:
            net.disconnect()


def test_store_and_restore_parameters(tmp_path):
    """0x1010 "save" is `config save` (refused while enabled, wrong signature
    refused); it survives a restart on the same flash; 0x1011 "load" gives
    the defaults at the next start."""
    flash = tmp_path / "drive.flash"
    image = tmp_path / "app.img"
    payload = random.Random(7).randbytes(4096)
    image.write_bytes(
        img.build(
            payload, board_id=1, fw_version=img.parse_version("1.2.3"), load_addr=LOAD_ADDR
        ).to_bytes()
    )
    with _drive_on(flash, image) as (_, node):
        sdo = node.sdo
        save = sdo["Store parameters"]["Save all parameters"]
        assert save.raw == 1  # saves on command
        default = sdo["Max profile velocity"].raw
        assert default != 123_000_000
        sdo["Max profile velocity"].raw = 123_000_000
        for cw in (0x06, 0x07, 0x0F):
            sdo["Controlword"].raw = cw
        assert _wait_sw(node, 0x6F, 0x27, 1.0) & 0x6F == 0x27
        assert _abort(lambda: setattr(save, "raw", SAVE)) == 0x08000022  # enabled
        sdo["Controlword"].raw = 0x06
        assert _wait_sw(node, 0x6F, 0x21, 1.0) & 0x6F == 0x21
        assert _abort(lambda: setattr(save, "raw", LOAD)) == 0x08000020  # wrong signature
        save.raw = SAVE
        assert save.raw == 1
        sdo["Max profile velocity"].raw = 77_000_000  # after the save: not kept
    with _drive_on(flash) as (s, node):
        assert node.sdo["Max profile velocity"].raw == 123_000_000
        with connect(port=s.serial) as c:
            assert c.get_param("param_store_status") == 1  # loaded
        restore = node.sdo["Restore default parameters"]["Restore all default parameters"]
        assert _abort(lambda: setattr(restore, "raw", SAVE)) == 0x08000020
        restore.raw = LOAD
        assert node.sdo["Max profile velocity"].raw == 123_000_000  # until the next start
    with _drive_on(flash) as (_, node):
        assert node.sdo["Max profile velocity"].raw == default
