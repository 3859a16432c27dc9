"""The sweep of "CEC never worse than the PIDs" (contour.sim.diagnose.sweep,
docs/simulator.md "Outside the tables: the sweep"): on the realistic
machine at low feed the CEC was worse than the PIDs alone while the
quadrant-glitch compensation read the axis integrator alone (R 30 mm,
2 m/min: 13.02 against 10.71 um); with the CEC's integrators read too it is
better. The worse-row list finds a worse row when there is one."""

from __future__ import annotations

from contour.sim import diagnose


def test_realistic_low_feed_not_worse():
    rows = diagnose.sweep(("F",), (30,), (2,), ("ccw",), log=lambda *_: None)
    assert len(rows) == 3
    assert diagnose.sweep_worse(rows) == []


def test_sweep_worse_lists_a_worse_row():
    row = {"setup": "F", "radius_mm": 30, "feed_m_min": 2, "direction": "ccw"}
    rows = [
        {**row, "controller": "pid", "circular_deviation_um": 1.0, "max_contour_error_um": 2.0},
        {
            **row,
            "controller": "cec-exact",
            "circular_deviation_um": 1.02,
            "max_contour_error_um": 1.0,
        },
    ]
    assert diagnose.sweep_worse(rows) == [("F", 30, 2, "ccw", "cec-exact", "cd", 1.0, 1.02)]


def test_sweep_main_refuses_an_unknown_setup_before_running(monkeypatch, capsys):
    """`diagnose sweep A,X` refused at once (a KeyError after all of A's
    circles had run before), and ids in any case taken (`sweep f`)."""
    ran = []
    monkeypatch.setattr(diagnose, "sweep", lambda setups: ran.append(list(setups)) or [])
    assert diagnose.sweep_main(["A,X"]) == 2
    assert ran == []
    assert "unknown set-up X" in capsys.readouterr().err
    assert diagnose.sweep_main(["f, c10"]) == 0
    assert ran == [["F", "C10"]]
