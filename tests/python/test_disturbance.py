"""Issue 21: the thesis's cutting-force disturbance (eq. 4.3) and a table
spring as simulator scenarios ([disturbance] in a machine file, sim.h
"Disturbances"), checked against steady states computed by hand.

With proportional-only axis loops (ki = 0, no feed-forward) a constant load
torque Tc = l F on the motor side needs the current Tc / kt, the voltage
Ra Tc / kt more than without it, so the axial error grows by
    dE = Ra l F / (kt kx kp)
whatever the axis speed (the model is linear; back-EMF and the derivative
term are the same with and without the force)."""

import json
import math

import numpy as np
import pytest
from contour.errors import UserError
from contour.sim import core, machine

RA, KT, KX = 9.0, 0.2, 16.0
L = 0.005 / (2 * math.pi)


def _run(dist: dict, ki: float = 0.0, target_mm=(30.0, 0.0), feed_mm_min=3000.0):
    m = machine.load("default")
    for ax in "xyz":
        m.gains[ax]["ki"] = ki
    m.disturbance = dist
    machine.apply(m, feedforward="none", controller="pid")
    assert core.lib().sim_enable(1) == 0
    tgt = [int(target_mm[0] * 1e6), int(target_mm[1] * 1e6), 0]
    assert core.queue_line(tgt, int(feed_mm_min / 60 * 1e6)) == 0
    tr = core.run(6000)  # 0.6 s; the line takes 0.6 s at 3 m/min
    k = slice(4000, 5000)  # 0.4..0.5 s: constant feed, transient gone
    ex = tr[k, 4] - tr[k, 5]
    ey = tr[k, 8] - tr[k, 9]
    return m, float(ex.mean()), float(ey.mean()), tr


def _gain(m, ax):
    return RA * L / (KT * KX * m.gains[ax]["kp"])


def test_cutting_force_shifts_the_errors_by_the_model_steady_state():
    """X line at 3 m/min (path angle 0): F_x = F_at + F_w cos 45,
    F_y = -F_w sin 45; the contour error of an X line is -E_y."""
    f_at, f_w = 20.0, 100.0
    m, ex0, ey0, _ = _run({})
    _, ex1, ey1, _ = _run({"f_at": f_at, "f_w": f_w})
    dx = _gain(m, "x") * (f_at + f_w * math.cos(math.pi / 4))
    dy = -_gain(m, "y") * f_w * math.sin(math.pi / 4)
    assert dx == pytest.approx(156.1e-6, rel=1e-3)  # by hand, kp 1300 V/m
    assert ex1 - ex0 == pytest.approx(dx, rel=0.01, abs=0.5e-6)
    assert ey1 - ey0 == pytest.approx(dy, rel=0.01, abs=0.5e-6)
    assert abs(ey0) < 0.5e-6  # no force: the Y axis holds its position


def test_cutting_force_from_ks_s_p_and_phi():
    """F_w = k_s s^0.73 p; phi moves the force between the axes: with
    phi = 90 deg on an X line, F_x = F_w cos 90 = 0, F_y = -F_w."""
    m = machine.from_dict({"disturbance": {"k_s": 2000.0, "feed_per_tooth_mm": 0.1, "depth_mm": 1}})
    assert m.cutting_f_w() == pytest.approx(2000.0 * 0.1**0.73)
    fw = m.cutting_f_w()
    m, ex0, ey0, _ = _run({})
    _, ex1, ey1, _ = _run({"f_w": fw, "phi_deg": 90.0})
    assert ex1 - ex0 == pytest.approx(0.0, abs=0.5e-6)
    assert ey1 - ey0 == pytest.approx(-_gain(m, "y") * fw, rel=0.01)


def test_spring_pulls_the_table_by_the_model_steady_state():
    """A spring k on X relaxed at x0 = -1 mm, the axis held at 0 (a Y move):
    E = G k (x - x0) with x = -E, G = Ra l / (kt kx kp):
    E = -G k x0 / (1 + G k)."""
    k, x0 = 1e4, -1e-3  # 10 N/mm
    m, ex0, _, _ = _run({}, target_mm=(0.0, 30.0))
    _, ex1, _, _ = _run({"spring_x": 10.0, "spring_x0_mm": -1.0}, target_mm=(0.0, 30.0))
    g = _gain(m, "x")
    assert ex1 - ex0 == pytest.approx(-g * k * x0 / (1 + g * k), rel=0.01)


def test_no_disturbance_is_bit_identical():
    """An all-zero [disturbance] section gives the same trace bits as none."""
    _, _, _, a = _run({}, ki=5000.0)
    _, _, _, b = _run({"f_at": 0.0, "f_w": 0.0, "spring_x": 0.0}, ki=5000.0)
    assert np.array_equal(a, b)


def test_bad_disturbance_keys_are_refused():
    with pytest.raises(UserError, match="disturbance"):
        machine.from_dict({"disturbance": {"f_cut": 1.0}})
    with pytest.raises(UserError, match="disturbance.f_w"):
        machine.from_dict({"disturbance": {"f_w": -1.0}})


def test_cli_cutting_force_and_spring(capsys):
    """--cutting-force and --spring reach the model (the scores change) and
    are reported in the JSON; a malformed value is a usage error."""
    from contour import cli

    base = ["sim", "circle", "--radius", "20", "--feed", "10000", "--controller", "pid", "--json"]
    out = {}
    for name, extra in (
        ("none", []),
        ("cut", ["--cutting-force", "20,100"]),
        ("spring", ["--spring", "5"]),
    ):
        assert cli.main(base + extra) == 0
        out[name] = json.loads(capsys.readouterr().out)
    assert out["none"]["disturbance"] == {}
    assert out["cut"]["disturbance"] == {"f_at": 20.0, "f_w": 100.0}
    assert out["spring"]["disturbance"] == {"spring_x": 5.0, "spring_y": 5.0, "f_w": 0.0}
    for name in ("cut", "spring"):
        assert out[name]["iae_um_s"] != pytest.approx(out["none"]["iae_um_s"], rel=0.01)
    assert cli.main(base + ["--cutting-force", "20"]) == 2
    assert "F_AT,F_W" in capsys.readouterr().out  # --json: the error as JSON
