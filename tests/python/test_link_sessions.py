"""Two hosts and a host that dies, during a streamed job (`contour run`
against `sim serve`): the streaming host over the serial pty, a second host
over SLCAN.

- A second `run` while a job runs is refused before it queues anything,
  and the first job ends at its end point.
- A streaming host killed with SIGKILL while another host polls the status
  is stopped by the drive's watchdog (comm_timeout): the watcher does not
  keep the dead host's job running. After `reset` the next job runs.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest
from contour import protocol_gen as pg
from contour.sim.serve import spawn
from linkhelp import client_for, fresh, link_args, run_cli, wait_state

NM = 1_000_000


@pytest.fixture(scope="module")
def server():
    with spawn() as s:
        yield s


def _write_job(path, axis: str, start_mm: float, n: int, step: float, feed: float) -> float:
    lines = [f"G21 G90 G1 F{feed:g}"]
    lines += [f"{axis}{start_mm + (i + 1) * step:.4f}" for i in range(n)]
    path.write_text("\n".join(lines) + "\n")
    return start_mm + n * step


def _run_in_subprocess(server, job, *extra):
    argv = [sys.executable, "-m", "contour", "run", str(job), "--port", server.serial, *extra]
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_running(c, timeout=10.0) -> dict:
    end = time.monotonic() + timeout
    st = c.status()
    while time.monotonic() < end and not (st["state"] == pg.State.RUNNING and st["blocks_done"]):
        time.sleep(0.05)
        st = c.status()
    assert st["state"] == pg.State.RUNNING, st
    return st


def test_a_second_job_is_refused_while_one_runs(server, tmp_path, capsys):
    with client_for(server, "slcan") as c:
        x0, y0 = (v / NM for v in fresh(c)["pos"][:2])
    end_x = _write_job(tmp_path / "a.nc", "X", x0, 300, 0.05, 120)  # 7.5 s at 2 mm/s
    _write_job(tmp_path / "b.nc", "Y", y0, 20, 0.05, 600)
    p = _run_in_subprocess(server, tmp_path / "a.nc", "--json")
    try:
        with client_for(server, "slcan") as c:
            done0 = _wait_running(c)["blocks_done"]
        rc, _, err = run_cli(["run", str(tmp_path / "b.nc"), *link_args(server, "slcan")], capsys)
        assert rc == 1
        assert "b.nc:2: the drive is busy" in err and "nothing of this program was queued" in err
        out, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 0, err
    rep = json.loads(out)
    assert rep["blocks_done"] == 300  # every block of the first job, none of the second
    assert rep["position_mm"][0] == pytest.approx(end_x, abs=0.005)
    assert rep["position_mm"][1] == pytest.approx(y0, abs=0.005)
    with client_for(server, "slcan") as c:
        st = c.status()
        assert (st["blocks_done"] - done0) & 0xFFFFFFFF < 300


def test_a_killed_streaming_host_is_stopped_while_another_watches(server, tmp_path, capsys):
    with client_for(server, "slcan") as c:
        x0 = fresh(c)["pos"][0] / NM
        assert c.get_param("comm_timeout_ms") == 1000
    end_x = _write_job(tmp_path / "long.nc", "X", x0, 400, 0.05, 120)  # 10 s at 2 mm/s
    p = _run_in_subprocess(server, tmp_path / "long.nc")
    try:
        with client_for(server, "slcan") as c:
            _wait_running(c)
            time.sleep(0.5)
            p.send_signal(signal.SIGKILL)
            p.wait(timeout=10)
            # the watcher polls the status all along
            t_kill = time.monotonic()
            st = c.status()
            while time.monotonic() - t_kill < 5.0 and st["state"] != pg.State.FAULT:
                time.sleep(0.05)
                st = c.status()
            assert st["state"] == pg.State.FAULT, st
            assert st["faults"] == 1 << pg.Fault.COMM_TIMEOUT
            assert time.monotonic() - t_kill < 4.0  # 1 s of silence, then a controlled stop
            stopped_at = st["pos"][0] / NM
            assert x0 + 0.1 < stopped_at < end_x - 1.0  # stopped on the way, not at the end
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
        p.stdout.close()
        p.stderr.close()
    rc, _, _ = run_cli(["reset", *link_args(server, "slcan")], capsys)
    assert rc == 0
    job = tmp_path / "next.nc"
    end2 = _write_job(job, "X", stopped_at, 10, 0.1, 600)
    rc, _, err = run_cli(["run", str(job), *link_args(server, "serial")], capsys)
    assert rc == 0, err
    with client_for(server, "slcan") as c:
        st = wait_state(c, (pg.State.READY,))
        assert st["pos"][0] / NM == pytest.approx(end2, abs=0.005)
