"""End to end: the host tool against the simulated drive (`sim serve`) over
the serial pseudo-terminal and over SLCAN (python-can's own slcan interface,
ISO-TP from can-isotp): identify, parameters, a short job to its end
position, telemetry without gaps, link loss -> controlled stop, Ctrl-C,
garbage and replayed frames, and a passive CAN scan.

One simulated drive serves the whole module (started once, stopped at the
end); every test opens and closes its own connection (a pty has one reader).
"""

from __future__ import annotations

import csv
import json
import os
import time

import pytest
from contour import protocol_gen as pg
from contour.link import DriveError, codec
from contour.sim.serve import spawn
from linkhelp import client_for, fresh, link_args, run_cli, wait_state

TRANSPORTS = ["serial", "slcan"]


@pytest.fixture(scope="module")
def server():
    with spawn() as s:
        yield s


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_identify(server, transport, capsys):
    rc, out, _ = run_cli(["info", "--json", *link_args(server, transport)], capsys)
    assert rc == 0
    info = json.loads(out)
    assert info["protocol_version"] == pg.PROTOCOL_VERSION
    assert info["axes"] == 3 and info["node_id"] == 1 and info["tick_hz"] == 10000
    assert "simulated" in info["capabilities"] and "can" in info["capabilities"]
    assert info["planner_slots"] >= 2


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_parameters_typed_and_range_checked(server, transport, capsys):
    args = link_args(server, transport)
    rc, out, _ = run_cli(["set", "comm_timeout_ms", "750", *args], capsys)
    assert rc == 0 and "750" in out
    rc, out, _ = run_cli(["get", "comm_timeout_ms", *args], capsys)
    assert rc == 0 and out.strip() == "comm_timeout_ms = 750 ms"
    rc, _, err = run_cli(["set", "comm_timeout_ms", "nonsense", *args], capsys)
    assert rc == 2 and "not an integer" in err
    with client_for(server, transport) as c:
        pid = pg.PARAM_BY_NAME["comm_timeout_ms"].id
        # the drive checks too (bypassing the host's own check)
        with pytest.raises(DriveError, match=r"out of range \[0, 60000\]") as e:
            c.request("param_set", param=pid, value=70000)
        assert e.value.code == pg.ErrorCode.OUT_OF_RANGE
        assert c.get_param("comm_timeout_ms") == 750  # nothing half applied
        with pytest.raises(DriveError, match="read-only"):
            c.request("param_set", param=pg.PARAM_BY_NAME["position"].id, value=1)
        with pytest.raises(DriveError) as e:
            c.request("param_get", param=0x7777)
        assert e.value.code == pg.ErrorCode.UNKNOWN_PARAM
        with pytest.raises(DriveError) as e:
            c.get_param("position.a")  # axis 3 on a 3-axis drive
        assert e.value.code == pg.ErrorCode.BAD_AXIS
        with pytest.raises(DriveError) as e:
            c.request("enable", axis_mask=0x10, on=1)
        assert e.value.code == pg.ErrorCode.BAD_AXIS
        c.set_param("comm_timeout_ms", 1000)


JOB = """(short job)
G21 G90
G1 X2 Y1 F1500
G1 X3 Y-0.5
G2 X2 Y-1.5 I-1 J0
G1 X0.5 Y0.25 Z0.1
"""


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_short_job_ends_at_the_programmed_point(server, transport, tmp_path, capsys):
    with client_for(server, transport) as c:
        fresh(c)
        st = c.status()
    start = [p / 1e6 for p in st["pos"][:3]]
    job = tmp_path / "job.nc"
    job.write_text(JOB)
    rc, out, err = run_cli(
        ["run", str(job), "--json", "--quiet", *link_args(server, transport)], capsys
    )
    assert rc == 0, err
    res = json.loads(out)
    assert res["blocks"] > 4  # the arc is split into segments
    target = (0.5, 0.25, 0.1)
    # "done" means the axes are there: the reported end position, and the
    # drive's own reading right after, are within the 5 um window
    err_mm = max(abs(a - b) for a, b in zip(res["position_mm"], target))
    assert err_mm <= 0.005 + 1e-9, (
        f"end position {res['position_mm']} mm, expected {target} ({start})"
    )
    with client_for(server, transport) as c:
        pos = [p / 1e6 for p in c.status()["pos"][:3]]
        assert c.get_param("telem_period_ms") == 0  # the job's telemetry is off again
    assert max(abs(a - b) for a, b in zip(pos, target)) <= 0.005 + 1e-9, pos
    assert res["following_error_samples"] > 10
    assert 0.0 < res["max_following_error_um"] < 500.0


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_telemetry_has_no_gaps(server, transport, tmp_path, capsys):
    out = tmp_path / "telemetry.csv"
    rc, _, err = run_cli(
        [
            "monitor",
            "--out",
            str(out),
            "--period-ms",
            "10",
            "--duration",
            "1.5",
            *link_args(server, transport),
        ],
        capsys,
    )
    assert rc == 0, err
    assert " 0 missing" in err
    with open(out) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) >= 60
    seqs = [int(r["seq"]) for r in rows]
    assert all((b - a) & 0xFFFF == 1 for a, b in zip(seqs, seqs[1:]))
    assert all(r["pos2_nm"] != "" and r["ferr0_nm"] != "" for r in rows[:-1])


def test_monitor_writes_a_can_log_the_dbc_decodes(server, tmp_path, capsys):
    import can
    import cantools

    out = tmp_path / "telemetry.asc"
    rc, _, err = run_cli(
        [
            "monitor",
            "--out",
            str(out),
            "--period-ms",
            "20",
            "--duration",
            "0.6",
            *link_args(server, "slcan"),
        ],
        capsys,
    )
    assert rc == 0, err
    db = cantools.database.load_file(
        os.path.join(os.path.dirname(__file__), "../../protocol/contour.dbc")
    )
    frames = list(can.ASCReader(str(out)))
    assert len(frames) >= 20 * 9
    status = [
        db.decode_message(f.arbitration_id, f.data)
        for f in frames
        if f.arbitration_id == pg.can_id(pg.CAN_FUNC["status"], 1)
    ]
    seqs = [s["seq"] for s in status]
    assert len(seqs) >= 20 and all((b - a) & 0xFFFF == 1 for a, b in zip(seqs, seqs[1:]))


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_link_loss_brings_a_controlled_stop(server, transport):
    with client_for(server, transport) as c:
        fresh(c)
        c.set_param("comm_timeout_ms", 200)
        st = c.status()
        x0 = st["pos"][0]
        target = [x0 + 40_000_000, st["pos"][1], st["pos"][2], 0]
        c.request("queue_block", block_seq=77, kind=0, flags=0, feed=10_000_000, target=target)
        assert wait_state(c, (pg.State.RUNNING,), 1.0)["state"] == pg.State.RUNNING
        time.sleep(0.3)
        # the host falls silent now
    time.sleep(1.5)
    with client_for(server, transport) as c:
        st = c.status()
        assert st["state"] == pg.State.FAULT, st
        assert st["faults"] == 1 << pg.Fault.COMM_TIMEOUT  # a stop, not an estop
        pos1 = st["pos"][0]
        assert x0 + 1_000_000 < pos1 < target[0] - 5_000_000  # stopped on the way
        time.sleep(0.2)
        assert abs(c.status()["pos"][0] - pos1) < 2000  # at rest
        c.request("fault_reset")
        assert c.status()["faults"] == 0
        c.set_param("comm_timeout_ms", 1000)


def test_ctrl_c_during_a_job_stops_in_a_controlled_way(server, tmp_path):
    from contour.link.stream import Streamer, blocks_from_gcode

    job = tmp_path / "long.nc"
    with client_for(server, "serial") as c:
        fresh(c)
        x0 = c.status()["pos"][0] / 1e6
        job.write_text(f"G21 G90\nG1 X{x0 + 30:.4f} F1200\n")
        blocks = list(blocks_from_gcode(str(job), start_mm=[x0, 0, 0]))
        calls = []

        def interrupt(p):
            calls.append(p)
            if p.elapsed_s > 0.3:
                raise KeyboardInterrupt

        with pytest.raises(KeyboardInterrupt):
            Streamer(c, blocks, on_progress=interrupt).run()
        st = c.status()
        assert st["state"] == pg.State.READY  # stopped, still enabled, no fault
        assert st["faults"] == 0
        assert x0 + 0.1 < st["pos"][0] / 1e6 < x0 + 29


def test_garbage_and_replayed_frames_over_serial(server):
    import serial

    with client_for(server, "serial") as c:
        before = c.status()
        # a status_get the client retried (reply late on a loaded machine)
        # reaches the drive after `before` was read: one replay each
        own_replays = c.retried
    port = serial.serial_for_url(server.serial, timeout=0.5)
    try:
        dec = codec.FrameDecoder()
        port.write(b"\x11\x22\x00\x7f\xff\x00garbage")  # noise, an empty and a bad frame
        bad = bytearray(codec.frame(codec.encode("identify", 1)))
        bad[4] ^= 0x01
        port.write(bytes(bad))
        frame = codec.frame(codec.encode("param_set", 42, param=1, value=600))
        port.write(frame)
        port.write(frame)  # replayed: answered from the cache, not executed again
        port.write(codec.frame(codec.encode("status_get", 43)))
        port.write(codec.frame(bytes([0xEE, 44])))  # unknown id
        port.write(codec.frame(codec.encode("param_get", 45) + b"\x00"))  # bad length
        replies = []
        end = time.monotonic() + 3
        while len(replies) < 5 and time.monotonic() < end:
            replies += [codec.decode(m) for m in dec.feed(port.read(256))]
    finally:
        port.close()
    assert [r.seq for r in replies] == [42, 42, 43, 44, 45]
    assert replies[0] == replies[1]
    st = replies[2].fields
    assert st["replayed"] == before["replayed"] + own_replays + 1
    assert st["rx_errors"] >= before["rx_errors"] + 2
    assert replies[3].name == "error" and replies[3].fields["code"] == pg.ErrorCode.UNKNOWN_MESSAGE
    assert replies[4].fields["code"] == pg.ErrorCode.BAD_LENGTH
    with client_for(server, "serial") as c:
        assert c.get_param("comm_timeout_ms") == 600
        c.set_param("comm_timeout_ms", 1000)


def test_scan_lists_the_drive_without_talking(server, capsys):
    rc, out, err = run_cli(
        ["scan", "--can", f"slcan:{server.slcan}@500000", "--time", "2.5", "--json"], capsys
    )
    assert rc == 0, err
    found = json.loads(out)
    assert [d["node"] for d in found] == [1]
    assert found[0]["protocol_version"] == pg.PROTOCOL_VERSION
    rc, _, err = run_cli(["scan", "--port", server.serial], capsys)
    assert rc == 2 and "CAN bus" in err


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_two_sessions_in_a_row_never_mix_replies(server, transport):
    """Session 1 turns fast telemetry on, fires requests without reading a
    reply and vanishes (a host killed mid-request): the drive's answers and
    telemetry wait in the link. Session 2, whose seq counter runs over the
    same numbers, must get only its own answers."""
    pid = pg.PARAM_BY_NAME["comm_timeout_ms"].id
    c1 = client_for(server, transport)
    fresh(c1)
    c1.set_param("telem_period_ms", 10)
    for k in range(40):
        c1.t.send(codec.encode("param_get", k, param=pid))
    c1.close()
    c2 = client_for(server, transport)
    try:
        c2._seq = 0xFF  # session_open takes seq 0, then 1, 2, ... as session 1 did
        assert c2.get_param("comm_timeout_ms") == 1000
        assert c2.session is not None
        for v in (111, 222, 333):
            assert c2.set_param("comm_timeout_ms", v) == v
            assert c2.get_param("comm_timeout_ms") == v
        assert c2.set_param("telem_period_ms", 0) == 0
        assert c2.status()["state"] in (pg.State.READY, pg.State.DISABLED)
        c2.set_param("comm_timeout_ms", 1000)
    finally:
        c2.close()


# ---- monitor: busy port, output kinds, write errors, SIGTERM ---------------------------


def test_monitor_refuses_an_output_it_does_not_write(tmp_path, capsys):
    out = tmp_path / "t.parquet"
    # refused before the port is opened: the port does not even exist
    rc, _, err = run_cli(["monitor", "--port", "/nonexistent", "--out", str(out)], capsys)
    assert rc == 2 and "not .parquet" in err and not out.exists()


def test_monitor_says_the_port_is_busy(server, tmp_path, capsys):
    with client_for(server, "serial") as c:
        c.identify()
        rc, _, err = run_cli(
            ["monitor", "--port", server.serial, "--out", str(tmp_path / "t.csv")], capsys
        )
    assert rc == 1 and "is busy: another process holds it" in err, err


def test_monitor_write_error_is_one_line_and_restores_telemetry(server, tmp_path, capsys):
    with client_for(server, "serial") as c:
        fresh(c)
        c.set_param("telem_period_ms", 250)
    full = tmp_path / "full.csv"
    full.symlink_to("/dev/full")
    rc, _, err = run_cli(
        ["monitor", "--port", server.serial, "--out", str(full), "--duration", "0.5"], capsys
    )
    assert rc == 1 and "No space left on device" in err and "Traceback" not in err, err
    with client_for(server, "serial") as c:
        assert c.get_param("telem_period_ms") == 250  # as it was before, not off
        c.set_param("telem_period_ms", 0)


def test_monitor_restores_telemetry_on_sigterm(server, tmp_path):
    import signal
    import subprocess
    import sys

    with client_for(server, "serial") as c:
        fresh(c)
        c.set_param("telem_period_ms", 250)
    out = tmp_path / "t.csv"
    argv = ["monitor", "--port", server.serial, "--out", str(out), "--period-ms", "10"]
    p = subprocess.Popen(
        [sys.executable, "-m", "contour", *argv], stderr=subprocess.PIPE, text=True
    )
    try:
        end = time.monotonic() + 10
        while time.monotonic() < end and (not out.exists() or out.stat().st_size < 2000):
            time.sleep(0.05)  # rows are flushed in blocks: several hundred cycles in
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=10)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 128 + signal.SIGTERM, err
    assert "monitor:" in err and "rows written" in err
    with client_for(server, "serial") as c:
        assert c.get_param("telem_period_ms") == 250
        c.set_param("telem_period_ms", 0)
    with open(out) as fh:
        assert len(list(csv.DictReader(fh))) > 10
