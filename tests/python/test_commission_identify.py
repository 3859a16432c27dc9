"""Identification of the axis model from an excitation record (issue 23,
contour.commission): the experiment runs on the C simulator's drive
(sim_inject) configured with machines whose parameters differ from the
defaults; the identified resonance within 10 % of the true value of the
axis model the simulator was configured with."""

import math

import numpy as np
import pytest
from contour.commission import experiment, identify
from contour.sim import machine, tuning


def true_resonance_hz(p: dict) -> float:
    return max(abs(e.imag) for e in tuning.eigenvalues(p)) / (2 * math.pi)


def true_friction_v(p: dict) -> float:
    l_ = p.get("lead_mm", 5.0) * 1e-3 / (2 * math.pi)
    torque = p.get("coulomb_motor", 0.0) + p.get("coulomb_table", 0.0) * l_
    return torque * p["Ra"] / (p["kt"] * p["kx"])


def variant(name: str) -> tuple[machine.Machine, dict]:
    """(machine, its X axis dict) of one test machine: the default machine
    with X's parameters and holding gains replaced."""
    m = machine.load("default")
    p = dict(m.axis["x"])
    gains = dict(m.gains["x"])
    if name == "heavier":
        p["I2"] *= 2.5
    elif name == "softer":
        p["K"] *= 0.4
    elif name == "friction_noise":
        p.update(coulomb_motor=0.01, coulomb_table=10.0, encoder_noise_counts=0.5)
    elif name == "other_machine_y":
        r = machine.load("realistic")
        p = dict(r.axis["y"])
        p["K"] *= 0.6
        gains = dict(r.gains["y"])
    return experiment.with_axis(m, "x", p, gains), p


@pytest.mark.parametrize("name", ["heavier", "softer", "friction_noise", "other_machine_y"])
def test_resonance_within_10_percent(name):
    m, p = variant(name)
    rec, _ = experiment.simulate_bounded(m, "x", experiment.Plan(), experiment.Limits())
    res = identify.identify(rec)
    true = true_resonance_hz(p)
    assert res.model == "two_inertia", res.reason
    assert abs(res.resonance_hz - true) <= 0.10 * true, (res.resonance_hz, true)
    anti = math.sqrt(p["K"] / p["I2"]) / (2 * math.pi)
    assert abs(res.antiresonance_hz - anti) <= 0.10 * anti
    # the interval is finite and contains the truth within 10 %
    assert 0 < res.resonance_ci_hz < 0.05 * true
    fr = true_friction_v(p)
    if fr > 0:
        assert abs(res.friction_v - fr) <= 0.2 * fr, (res.friction_v, fr)
    else:
        assert abs(res.friction_v) < 0.01
    d = res.as_dict()
    assert d["resonance_hz"] == pytest.approx(res.resonance_hz, abs=0.01)


def test_stiff_axis_gives_rigid_model():
    """A resonance far above the Nyquist frequency is not in the data: the
    result is the rigid-body model and no resonance, with the reason."""
    m, p = variant("default")
    p["K"] *= 1e4
    rec = experiment.simulate(
        experiment.with_axis(m, "x", p), "x", experiment.Plan(periods=6), experiment.Limits()
    )
    res = identify.identify(rec)
    assert res.model == "rigid"
    assert res.resonance_hz is None
    assert res.reason


def test_noise_is_refused():
    """Encoder positions unrelated to the command: no model is claimed."""
    m, _ = variant("default")
    rec = experiment.simulate(m, "x", experiment.Plan(periods=4), experiment.Limits())
    rng = np.random.default_rng(3)
    rec.y = rng.standard_normal(rec.y.size) * 1e-6
    with pytest.raises(identify.IdentifyError):
        identify.identify(rec)


def test_too_few_periods_refused():
    m, _ = variant("default")
    plan = experiment.Plan(periods=2, friction_speeds_m_s=())
    rec = experiment.simulate(m, "x", plan, experiment.Limits())
    with pytest.raises(identify.IdentifyError, match="periods"):
        identify.identify(rec)


@pytest.mark.parametrize(
    "limits",
    [
        experiment.Limits(travel_m=0.001),
        experiment.Limits(command_v=5.0),
        experiment.Limits(velocity_m_s=0.02),
    ],
)
def test_experiment_stops_at_user_limits(limits):
    m, _ = variant("default")
    with pytest.raises(experiment.ExperimentAborted):
        experiment.simulate(m, "x", experiment.Plan(periods=3), limits)


def _held_rows(inject=None, ticks=50):
    """Trace rows of the default machine's drive holding X at rest, with
    `inject` (V per tick) added to X's command by sim_inject."""
    from contour.sim import core

    experiment._start(machine.load("default"))
    so = core.lib()
    if inject is not None:
        buf = np.ascontiguousarray(inject, dtype=np.float64)
        assert so.sim_inject(0, buf.ctypes.data, buf.size) == 0
        rows = core.run(ticks)
        left = so.sim_inject_left(0)
        so.sim_inject(0, None, 0)
        return rows, left
    return core.run(ticks), 0


def test_sim_inject_adds_to_the_command():
    """The injection point of the C simulator: the trace's command is the
    drive's plus the injected volts, the axis responds, nothing is left
    after the buffer; an empty buffer changes no bit of the trace."""
    base, _ = _held_rows()
    empty, _ = _held_rows(np.zeros(0))
    assert np.array_equal(base, empty)
    rows, left = _held_rows(np.full(20, 1.0))
    assert left == 0
    assert rows[0, 7] == pytest.approx(base[0, 7] + 1.0, abs=1e-12)
    assert not np.array_equal(rows[:, 6], base[:, 6])  # the encoder saw it
