"""The default simulated machine (`sim serve` without --machine:
hil_sim/machines/tuned.toml) behaves like a tuned machine: rapids and feeds
at its limits, on every axis, diagonals and quick reversals, end without a
fault at their end points, and the drive's own following error (its ferr
telemetry, every 1 ms) stays below a third of the following-error limit.

The machine's numbers are read from its file, so the test follows the file;
docs/simulator.md "The default machine" has the measured figures.
"""

from __future__ import annotations

import time

import pytest
from contour import protocol_gen as pg
from contour.errors import UserError
from contour.link import connect
from contour.link.stream import Streamer, blocks_from_gcode
from contour.sim import machine
from contour.sim.serve import DEFAULT_MACHINE, spawn
from linkhelp import run_cli, wait_state

FERR_FRACTION = 1 / 3  # peak following error must stay below this part of the limit
END_COUNTS = 3  # end position within this many encoder counts


@pytest.fixture(scope="module")
def tuned():
    return machine.load(DEFAULT_MACHINE)


@pytest.fixture(scope="module")
def server():
    with spawn() as s:
        yield s


def count_nm(m, ax: str) -> float:
    return m.axis[ax]["lead_mm"] * 1e6 / (4 * m.axis[ax]["encoder_lines"])


def test_limits_leave_amplifier_headroom(tuned):
    """The planner's worst case for the amplifier, accelerating to v_max
    (S-curve: the acceleration falls from a_max to 0 at j_max as the speed
    reaches v_max), needs at most 90 % of its voltage in the axis model:
    back-EMF kb v / l plus Ra (I1 + I2) a / (kt l) (B and La neglected)."""
    v_max, a_max, j_max = (tuned.planner[k] for k in ("v_max", "a_max", "j_max"))
    assert v_max >= a_max**2 / j_max  # a_max is reached on the way to v_max
    for ax in "xyz"[: tuned.axes]:
        p = tuned.axis[ax]
        lead = tuned.l(ax)
        worst = 0.0
        for k in range(101):
            t = k / 100 * a_max / j_max  # time into the last (jerk-down) phase
            a = a_max - j_max * t
            v = v_max - a_max**2 / (2 * j_max) + a_max * t - j_max * t * t / 2
            volts = p["kb"] * v / lead + p["Ra"] * (p["I1"] + p["I2"]) * a / (p["kt"] * lead)
            worst = max(worst, volts)
        assert worst <= 0.9 * p["vmax"], (ax, worst)
    assert tuned.ff_mode == "full"
    assert 0 < tuned.servo["ferr_limit_mm"] <= 1.0


def settle(c, target_nm, tol_nm: float, timeout: float = 3.0) -> dict:
    end = time.monotonic() + timeout
    st = c.status()
    while time.monotonic() < end:
        if all(abs(st["pos"][i] - target_nm[i]) <= tol_nm for i in range(3)):
            break
        time.sleep(0.02)
        st = c.status()
    return st


def ready(c) -> None:
    c.set_param("comm_timeout_ms", 1000)
    st = c.status()
    if st["state"] in (pg.State.FAULT, pg.State.ESTOP):
        c.request("fault_reset")
        wait_state(c, (pg.State.DISABLED, pg.State.READY))


@pytest.mark.parametrize("program", ["G0 X20\n", "G1 X50 F30000\n"])
def test_the_reported_moves_run_from_the_command_line(server, tuned, program, tmp_path, capsys):
    """The two moves of the issue, as an operator types them."""
    with connect(port=server.serial) as c:
        ready(c)
    job = tmp_path / "job.nc"
    job.write_text("G90 G0 X0 Y0 Z0\n" + program)
    rc, out, err = run_cli(["run", str(job), "--port", server.serial, "--quiet"], capsys)
    assert rc == 0, err
    target = list(blocks_from_gcode(str(job)))[-1].target_nm
    with connect(port=server.serial) as c:
        st = settle(c, target, END_COUNTS * count_nm(tuned, "x"))
        assert st["state"] == pg.State.READY and st["faults"] == 0
        assert abs(st["pos"][0] - target[0]) <= END_COUNTS * count_nm(tuned, "x")


def job_at_limits(m) -> str:
    """Rapids and feeds at the limits on every axis, back and forth, the
    diagonals (feed at v_max along the path, rapids with every axis at
    v_max) and short reversals that never reach v_max."""
    f = round(m.planner["v_max"] * 60000)
    lines = ["G90 G0 X0 Y0 Z0"]
    for ax in "XYZ"[: m.axes]:
        lines += [
            f"G0 {ax}20",
            f"G0 {ax}0",
            f"G1 {ax}50 F{f}",
            f"G1 {ax}0",
            f"G1 {ax}-30",
            f"G0 {ax}0",
        ]
    lines += [
        f"G1 X50 Y50 F{f}",
        "G1 X0 Y0",
        "G0 X50 Y50 Z50",
        "G0 X0 Y0 Z0",
        f"G1 X50 Y20 Z10 F{f}",
        "G1 X5 Y0 Z0",
        "G1 X0",
        "G1 X5",
        "G1 X0",
        "G0 X100",
        "G0 X0",
    ]
    return "\n".join(lines) + "\n"


def test_rapids_and_feeds_at_the_limits(server, tuned, tmp_path):
    job = tmp_path / "limits.nc"
    job.write_text(job_at_limits(tuned))
    limit_nm = tuned.servo["ferr_limit_mm"] * 1e6
    axes = tuned.axes
    peak = [0] * axes
    peak_cmd = [0] * axes  # 10 mV at the amplifier input
    samples = 0
    with connect(port=server.serial) as c:
        ready(c)
        st = c.status()
        blocks = list(blocks_from_gcode(str(job), start_mm=[p / 1e6 for p in st["pos"][:3]]))

        def sample(d) -> None:
            nonlocal samples
            if d.name.startswith("ferr_") and int(d.name[5:]) < axes:
                k = int(d.name[5:])
                peak[k] = max(peak[k], abs(d.fields["ferr"]))
                peak_cmd[k] = max(peak_cmd[k], abs(d.fields["cmd"]))
                samples += 1

        # raises on a fault; returns with the axes in position (5 um)
        streamer = Streamer(c, blocks, queue_s=1.0, telem_period_ms=1, on_telemetry=sample)
        result = streamer.run()
        target = blocks[-1].target_nm
        st = settle(c, target, END_COUNTS * count_nm(tuned, "x"))
    assert result["max_following_error_um"] * 1000 == max(peak)
    kx = [tuned.axis[ax]["kx"] for ax in "xyz"[:axes]]
    print(  # shown by pytest -rP (docs/simulator.md "The default machine")
        f"{len(blocks)} blocks, {samples} ferr samples; peak following error (um) "
        f"{[round(p / 1e3, 1) for p in peak]}, limit {limit_nm / 1e3:g} um; peak motor "
        f"voltage (V) {[round(c * 0.01 * k, 1) for c, k in zip(peak_cmd, kx)]}"
    )
    assert result["blocks"] == len(blocks)
    assert st["state"] == pg.State.READY and st["faults"] == 0
    for i in range(axes):
        tol = END_COUNTS * count_nm(tuned, "xyz"[i])
        assert abs(st["pos"][i] - target[i]) <= tol, (i, st["pos"][i], target[i])
    # every 1 ms over a job of several seconds on each axis
    assert samples >= axes * 1000
    assert all(p > 0 for p in peak)  # every axis moved and reported
    worst = max(peak)
    assert worst < FERR_FRACTION * limit_nm, (
        f"peak following error {[p / 1e3 for p in peak]} um; limit {limit_nm / 1e3:g} um"
    )


def test_feedforward_mode_of_a_machine_file():
    """[feedforward] mode is the feed-forward when the caller names none;
    the thesis set-up (default.toml) keeps none; a wrong mode is refused."""
    assert machine.load("default").ff_mode == "none"
    assert machine.from_dict({"feedforward": {"mode": "velocity"}}).ff_mode == "velocity"
    with pytest.raises(UserError, match="feedforward.mode"):
        machine.from_dict({"feedforward": {"mode": "fast"}})
