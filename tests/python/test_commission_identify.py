"""Identification of the axis model from an excitation record (issue 23,
contour.commission): simulated machines whose parameters differ from the
defaults; the identified resonance within 10 % of the model's own."""

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


def variant(name: str) -> tuple[dict, dict]:
    """(axis dict, holding gains) of one test machine."""
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
    return p, gains


@pytest.mark.parametrize("name", ["heavier", "softer", "friction_noise", "other_machine_y"])
def test_resonance_within_10_percent(name):
    p, gains = variant(name)
    rec, _ = experiment.simulate_bounded(p, gains, experiment.Plan(), experiment.Limits())
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
    p, gains = variant("default")
    p["K"] *= 1e4
    rec = experiment.simulate(p, gains, experiment.Plan(periods=6), experiment.Limits())
    res = identify.identify(rec)
    assert res.model == "rigid"
    assert res.resonance_hz is None
    assert res.reason


def test_noise_is_refused():
    """Encoder positions unrelated to the command: no model is claimed."""
    p, gains = variant("default")
    rec = experiment.simulate(p, gains, experiment.Plan(periods=4), experiment.Limits())
    rng = np.random.default_rng(3)
    rec.y = rng.standard_normal(rec.y.size) * 1e-6
    with pytest.raises(identify.IdentifyError):
        identify.identify(rec)


def test_too_few_periods_refused():
    p, gains = variant("default")
    plan = experiment.Plan(periods=2, friction_speeds_m_s=())
    rec = experiment.simulate(p, gains, plan, experiment.Limits())
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
    p, gains = variant("default")
    with pytest.raises(experiment.ExperimentAborted):
        experiment.simulate(p, gains, experiment.Plan(periods=3), limits)
