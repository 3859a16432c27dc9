"""Estimation models, profiles and `contour estimate`."""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from contour import cli, gcode
from contour.errors import UserError
from contour.estimation import camargo2017, estimate_moves, estimate_program, parse_options
from contour.estimation import experiments as xp
from contour.estimation import profile as profiles
from contour.estimation.result import Moves

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared"
ANTONIO = sorted((SHARED / "data" / "antonio2019").glob("*.mpf"))
CAMARGO = sorted((SHARED / "data" / "camargo2017").glob("*.csv"))
GENERIC = ROOT / "profiles" / "generic.toml"
HERMLE = ROOT / "profiles" / "hermle_c1200v_itnc530.toml"
MRT = 0.00045


def prof(**values):
    return profiles.default().with_values({"motion.min_block_time_s": MRT, **values})


def run(text, model, profile=None, options=None):
    p = gcode.read("t.nc", text=text)
    return estimate_program(p, profile or prof(), model, options)


# ---- feed and mrt ------------------------------------------------------------


def test_feed_model_is_distance_over_feed_and_rapids_at_rapid_feed():
    p = prof(**{"motion.rapid_feed_mm_min": 12000.0})
    e = run("G0 X120\nG1 Y30 F600\nG4 P2\nY60\n", "feed", p)
    np.testing.assert_allclose(e.time_s, [0.6, 3.0, 2.0, 3.0])
    s = e.summary()
    assert s["total_s"] == pytest.approx(8.6)
    assert s["dwell_s"] == pytest.approx(2.0)
    assert s["rapid_s"] == pytest.approx(0.6)
    assert s["mean_feed_mm_min"] == pytest.approx(600)
    assert s["accel_s"] is None


def test_mrt_model_caps_short_blocks_at_the_minimum_block_time():
    # 0.1 mm at F15000 takes 0.4 ms < MRT; 1 mm takes 4 ms.
    e = run("G91 G1 F15000\nX0.1\nX1\nX0.1\n", "mrt")
    np.testing.assert_allclose(e.time_s, [MRT, 0.004, MRT])
    assert e.summary()["min_block_time_s"] == pytest.approx(2 * MRT)


# ---- camargo2017 ---------------------------------------------------------------


def half_ends(*lengths):
    return sum(0.5 * max(60 * L / 15000, MRT) for L in lengths)


def test_camargo_case3_reversal():
    e = run("G91 G1 F15000\nX0.1\nX-0.1\n", "camargo2017")
    f = 0.1015 * 0.1**0.4966
    assert e.total_s == pytest.approx(f + half_ends(0.1, 0.1), rel=1e-12)
    ey = run("G91 G1 F15000\nY0.1\nY-0.1\n", "camargo2017")
    assert ey.total_s == pytest.approx(0.107 * 0.1**0.394 + half_ends(0.1, 0.1), rel=1e-12)
    assert e.options["transitions"]["case3"] == 1


def test_camargo_case1_collinear_blocks_of_different_lengths():
    e = run("G91 G1 F15000\nX0.1\nX0.01\nX0.1\n", "camargo2017")
    # l_med = 0.055 mm is shorter than l_min = 0.1125 mm: MRT per transition.
    assert e.total_s == pytest.approx(2 * MRT + half_ends(0.1, 0.1), rel=1e-12)
    e2 = run(
        "G91 G1 F15000\nX0.1\nX0.01\nX0.1\n", "camargo2017", options={"collinear_rule": "case2"}
    )
    assert e2.total_s > 10 * e.total_s  # a Case 2 time instead


def test_camargo_case2a_and_2b_formulas():
    # E2Y25: Y 0.1 -> 0.01 with X, Z 0.2 (unchanged, Case 1): 2A for Y.
    e = run("G91 G1 F15000\nX0.2 Y0.1 Z0.2\nX0.2 Y0.01 Z0.2\n", "camargo2017")
    tes = (1.6991 * 0.1 - 0.5266) * 0.01 + 0.3844 * 0.1 + 0.0103
    l1, l2 = math.sqrt(0.09), math.sqrt(0.0801)
    assert e.total_s == pytest.approx(tes + half_ends(l1, l2), rel=1e-12)
    assert e.options["transitions"]["case2a"] == 1
    # E2Y01: Y 0.2 -> 0.1 with X, Z 0.2: S1 is not smaller than 0.2: 2B.
    e = run("G91 G1 F15000\nX0.2 Y0.2 Z0.2\nX0.2 Y0.1 Z0.2\n", "camargo2017")
    l1, l2 = math.sqrt(0.12), math.sqrt(0.09)
    lm = 0.5 * (l1 + l2)
    tes = (0.4 * 0.2 + 0.0017) * lm + (-0.146 * 0.2 - 0.2289) * 0.1 + 0.056 * 0.2 + 0.027
    assert e.total_s == pytest.approx(tes + half_ends(l1, l2), rel=1e-12)
    minus = run(
        "G91 G1 F15000\nX0.2 Y0.2 Z0.2\nX0.2 Y0.1 Z0.2\n",
        "camargo2017",
        options={"case2b_s1_term": "-0.056"},
    )
    assert e.total_s - minus.total_s == pytest.approx(2 * 0.056 * 0.2, rel=1e-9)


def test_camargo_2a_rule_option_decides_between_the_other_axes():
    # Y's S1 = 0.1 lies between X (0.05) and Z (0.3).
    text = "G91 G1 F15000\nX0.05 Y0.1 Z0.3\nX0.05 Y0.02 Z0.3\n"
    strict = run(text, "camargo2017")
    below = run(text, "camargo2017", options={"case2a_rule": "below-max"})
    assert strict.options["transitions"] == {"case1": 0, "case2a": 0, "case2b": 1, "case3": 0}
    assert below.options["transitions"] == {"case1": 0, "case2a": 1, "case2b": 0, "case3": 0}
    assert strict.options["case2a_rule"] == "strict"


def test_camargo_zero_axis_rule_options():
    text = "G91 G1 F15000\nX0.1\nX0.1 Y0.05\n"
    l2 = math.hypot(0.1, 0.05)
    ends = half_ends(0.1, l2)
    case2 = run(text, "camargo2017").total_s - ends
    case3 = run(text, "camargo2017", options={"zero_axis_rule": "case3"}).total_s - ends
    case1 = run(text, "camargo2017", options={"zero_axis_rule": "case1"}).total_s - ends
    assert case2 == pytest.approx(0.3844 * 0.05 + 0.0103)  # 2A with S2 = 0
    assert case3 == pytest.approx(0.5 * 0.107 * 0.05**0.394)
    assert case1 == pytest.approx(max(30 * (0.1 + l2) / 15000, MRT))


def test_camargo_large_displacements_go_to_case1():
    text = "G91 G1 F15000\nX1 Y1\nX1 Y0.5\n"
    e = run(text, "camargo2017")
    assert e.options["transitions"]["case1"] == 1
    wide = run(text, "camargo2017", options={"case2_max_mm": 5.0})
    assert wide.total_s > 0.2  # the unbounded formula: 0.35 s-class blocks


def test_camargo_reproduces_the_thesis_on_experiment_2_y():
    # The spec: with the strict 2A/2B reading the published equations give
    # about 9 % mean absolute error on the Y-axis Experiment 2 data.
    exps = [e for e in xp.read_all(CAMARGO) if e.table == "exp2_y"]
    p = prof()
    pred = xp.predict(exps, lambda prog: estimate_program(prog, p, "camargo2017").total_s)
    err = np.abs(np.array(pred) / np.array([e.time_s for e in exps]) - 1)
    assert 0.085 < err.mean() < 0.105


def test_camargo_options_come_from_profile_and_are_validated():
    p = profiles.default().with_values({"camargo2017.end_segments": "none"})
    e = run("G91 G1 F15000\nX0.1\nX-0.1\n", "camargo2017", p)
    assert e.total_s == pytest.approx(0.1015 * 0.1**0.4966)
    with pytest.raises(UserError, match="collinear_rule must be one of"):
        parse_options("camargo2017", ["collinear_rule=sometimes"])
    with pytest.raises(UserError, match="has no option 'speed'"):
        parse_options("camargo2017", ["speed=3"])
    with pytest.raises(UserError, match="must be true or false"):
        parse_options("camargo2017", ["floor_at_case1=yes"])
    assert {f.name for f in camargo2017.OPTIONS} >= {
        "collinear_rule",
        "unchanged_axis_rule",
        "case2a_rule",
        "zero_axis_rule",
        "case2_max_mm",
        "floor_at_case1",
        "end_segments",
    }


# ---- planner (the drive's C planner) ------------------------------------------


def planner_prof(**values):
    base = {
        "motion.velocity_profile": "trapezoid",
        "motion.min_block_time_s": 1e-6,
        "motion.corner_rule": "junction-deviation",
    }
    for a in "XYZ":
        base[f"axes.{a}.max_velocity_mm_min"] = 60000.0
        base[f"axes.{a}.max_acceleration_mm_s2"] = 1000.0
    base.update(values)
    return profiles.default().with_values(base)


def test_planner_single_move_is_the_trapezoid_closed_form():
    e = run("G1 X100 F6000\n", "planner", planner_prof())
    # 100 mm/s, 1000 mm/s^2: 0.1 s up, 0.9 s cruise, 0.1 s down.
    assert e.total_s == pytest.approx(1.1, rel=1e-6)
    s = e.summary()
    assert s["accel_s"] == pytest.approx(0.1, rel=1e-6)
    assert s["cruise_s"] == pytest.approx(0.9, rel=1e-6)
    assert s["decel_s"] == pytest.approx(0.1, rel=1e-6)
    assert e.peak_mm_min[0] == pytest.approx(6000, rel=1e-6)


def test_planner_profile_units_reach_the_planner():
    # The axis velocity limit (mm/min) caps the programmed feed.
    p = planner_prof(**{"axes.X.max_velocity_mm_min": 3000.0})
    e = run("G1 X100 F6000\n", "planner", p)
    assert e.total_s == pytest.approx(100 / 50 + 50 / 1000, rel=1e-6)
    # Diagonal: the block acceleration is the per-axis one projected.
    e = run("G1 X100 Y100 F6000\n", "planner", planner_prof())
    a = 1000 * math.sqrt(2)
    assert e.total_s == pytest.approx(100 * math.sqrt(2) / 100 + 100 / a, rel=1e-6)


def test_planner_exact_stop_and_continuous_path():
    cont = run("G64 G1 X50 F6000\nX100\n", "planner", planner_prof())
    stop = run("G61 G1 X50 F6000\nX100\n", "planner", planner_prof())
    assert cont.total_s == pytest.approx(1.1, rel=1e-6)
    assert stop.total_s == pytest.approx(1.2, rel=1e-6)
    assert stop.exit_mm_min[0] == 0


def test_planner_dwell_and_min_block_time():
    e = run("G1 X10 F600\nG4 P0.5\n", "planner", planner_prof())
    assert e.summary()["dwell_s"] == pytest.approx(0.5)
    assert e.total_s == pytest.approx(1.0 + 0.01 + 0.5, rel=1e-6)
    # 400 tiny collinear blocks take at least the minimum block time each.
    text = "G91 G1 F15000\n" + "X0.001\n" * 400
    e = run(text, "planner", planner_prof(**{"motion.min_block_time_s": 0.00045}))
    assert e.total_s == pytest.approx(400 * 0.00045, rel=0.02)
    assert e.summary()["min_block_time_s"] > 0.9 * e.total_s


def test_planner_smoothed_corner_rule_is_slower_with_lower_corner_acceleration():
    text = "G91 G1 F15000\n" + "X0.2 Y0.2 Z0.2\nX0.2 Y0.1 Z0.2\n" * 20
    fast = run(text, "planner", planner_prof(**{"motion.corner_rule": "smoothed-corner"}))
    slow = run(
        text,
        "planner",
        planner_prof(
            **{"motion.corner_rule": "smoothed-corner", "axes.Y.corner_acceleration_mm_s2": 50.0}
        ),
    )
    assert slow.total_s > 1.5 * fast.total_s


def test_extrapolated_experiment_times_equal_whole_programs():
    exps = {e.name: e for e in xp.read_all(CAMARGO)}
    p = planner_prof(**{"motion.corner_rule": "smoothed-corner"})
    for name in ("E2Y37", "E3X0.010", "E1V4P7"):
        e = exps[name]

        def timer(prog, model):
            return estimate_program(prog, p, model).total_s

        for model in ("planner", "camargo2017"):
            part = xp.predict_one(e, lambda prog, m=model: timer(prog, m))
            whole = xp.predict_one(e, lambda prog, m=model: timer(prog, m), full=True)
            assert part == pytest.approx(whole, rel=1e-6), (name, model)


def test_moves_from_arrays_and_zero_length_segments():
    m = Moves.from_arrays([[1, 0, 0], [0, 0, 0], [1, 0, 0]], 600)
    e = estimate_moves(m, prof(), "feed")
    np.testing.assert_allclose(e.time_s, [0.1, 0.0, 0.1])
    e = estimate_moves(m, planner_prof(), "planner")
    assert e.time_s[1] == 0


# ---- profiles -------------------------------------------------------------------


def test_profile_files_load_and_round_trip(tmp_path):
    g = profiles.load(GENERIC)
    assert g.motion["corner_rule"] == "junction-deviation"
    out = tmp_path / "p.toml"
    profiles.save(g, out, header="hello")
    again = profiles.load(out)
    assert again.data == g.data
    assert out.read_text().startswith("# hello")


@pytest.mark.parametrize(
    "text,message",
    [
        ("[motion]\nmin_block_time = 1\n", "unknown field 'min_block_time'"),
        ("[motion]\nmin_block_time_s = -1\n", "must be a non-negative finite number"),
        ("[motion]\njunction_deviation_mm = 0\n", "must be a positive finite number"),
        ("[motion]\ncorner_rule = 'round'\n", "corner_rule must be one of"),
        ("[axes.Q]\nmax_jerk_mm_s3 = 1\n", "unknown axis 'Q'"),
        ("[axes.X]\nmax_jerk_mm_s3 = 'fast'\n", "must be a number"),
        ("speed = 3\n", "unknown table or key 'speed'"),
        ("[motion\n", "not a valid TOML file"),
    ],
)
def test_bad_profiles_are_clear_errors(tmp_path, text, message):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(UserError, match=message):
        profiles.load(f)


# ---- the command line -------------------------------------------------------------


def test_cli_estimate_json_has_total(capsys, tmp_path):
    prog = tmp_path / "a.nc"
    prog.write_text("G1 X10 F600\nG1 Y10\n")
    assert (
        cli.main(["estimate", str(prog), "--profile", str(GENERIC), "--model", "feed", "--json"])
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    assert out["total_s"] == pytest.approx(2.0)
    assert out["blocks"] == 2 and out["model"] == "feed"


def test_cli_estimate_text_report_and_per_block_csv(capsys, tmp_path):
    prog = tmp_path / "a.nc"
    prog.write_text("G1 X10 F600 M8\nG2 X20 Y0 I5 J0\nG4 P1\n")
    csv_path = tmp_path / "blocks.csv"
    rc = cli.main(["estimate", str(prog), "--profile", str(GENERIC), "--per-block", str(csv_path)])
    assert rc == 0
    out = capsys.readouterr().out
    for word in ("total time:", "acceleration", "minimum block time", "blocks:", "mean", "M8"):
        assert word in out
    rows = list(csv.DictReader(csv_path.open()))
    assert len(rows) > 3  # the arc was split
    total = float(out.split("total time:")[1].split()[0])
    assert sum(float(r["time_s"]) for r in rows) == pytest.approx(total, rel=1e-3)


def test_cli_estimate_errors_exit_1_and_usage_2(capsys, tmp_path):
    prog = tmp_path / "a.nc"
    prog.write_text("G1 X1.2.3 F600\n")
    assert cli.main(["estimate", str(prog), "--profile", str(GENERIC)]) == 1
    assert f"{prog}:1: malformed number" in capsys.readouterr().err
    prog.write_text("G1 X1 F600\n")
    assert cli.main(["estimate", str(prog), "--profile", str(tmp_path / "none.toml")]) == 1
    assert "cannot read profile" in capsys.readouterr().err
    assert cli.main(["estimate", str(prog), "--profile", str(GENERIC), "--feed", "-5"]) == 2


@pytest.mark.parametrize("model", ["planner", "camargo2017", "mrt", "feed"])
def test_all_nine_siemens_programs_estimate_with_generic_profile(capsys, model):
    for path in ANTONIO:
        rc = cli.main(
            [
                "estimate",
                str(path),
                "--profile",
                str(GENERIC),
                "--model",
                model,
                "--feed",
                "2500",
                "--json",
            ]
        )
        assert rc == 0, path.name
        out = json.loads(capsys.readouterr().out)
        assert out["total_s"] > 1.0, path.name
        assert any(s["kind"] == "CYCLE800" for s in out["skipped"])


def test_siemens_program_without_feed_is_refused(capsys):
    path = next(p for p in ANTONIO if p.name == "cycle832_3p2_x5.mpf")
    assert cli.main(["estimate", str(path), "--profile", str(GENERIC)]) == 1
    err = capsys.readouterr().err
    assert f"{path}:22: cannot evaluate F=R0" in err and "--feed" in err


def test_committed_hermle_profile_predicts_unseen_style_tests():
    # The four published experiment-2 X tests and the X reversals: the
    # fitted profile must stay within the 10 % the hold-out target asks.
    p = profiles.load(HERMLE)
    exps = [e for e in xp.read_all(CAMARGO) if e.table == "exp2_x" or e.name.startswith("E3X")]
    pred = xp.predict(exps, lambda prog: estimate_program(prog, p, "planner").total_s)
    err = np.abs(np.array(pred) / np.array([e.time_s for e in exps]) - 1)
    assert err.mean() < 0.10


def test_committed_hermle_profile_reversals_use_s_curves_at_rest():
    # The reversal table exp3 is where the planner had to beat camargo2017's
    # 4.10 %: the committed profile gets there with S-curves at rest and a
    # fitted Y jerk (measured 3.85 % over the 30 reversal tests).
    p = profiles.load(HERMLE)
    assert p.motion["velocity_profile"] == "s-curve-at-rest"
    exps = [e for e in xp.read_all(CAMARGO) if e.table == "exp3"]
    pred = xp.predict(exps, lambda prog: estimate_program(prog, p, "planner").total_s)
    err = np.abs(np.array(pred) / np.array([e.time_s for e in exps]) - 1)
    assert err.mean() < 0.041
    # the trapezoid with the same limits loses the short Y reversals
    t = p.with_values({"motion.velocity_profile": "trapezoid"})
    pred_t = xp.predict(exps, lambda prog: estimate_program(prog, t, "planner").total_s)
    err_t = np.abs(np.array(pred_t) / np.array([e.time_s for e in exps]) - 1)
    assert err_t.mean() > err.mean() + 0.01


def test_estimate_equals_execution_on_the_simulated_drive(tmp_path):
    # The same program through `contour sim run` (planner + interpolator +
    # servo loops on the simulated machine) and through the estimator with
    # a profile holding the simulated drive's planner settings.
    from contour.sim import job, machine

    m = machine.load(None)
    pl = m.planner
    v = {
        "motion.velocity_profile": "s-curve-continuous",  # the drive's default
        "motion.corner_rule": "junction-deviation",
        "motion.junction_deviation_mm": pl["junction_dev"] * 1000,
        "motion.min_block_time_s": 0.0,
        "motion.rapid_feed_mm_min": min(job.RAPID_M_S, pl["v_max"]) * 60000,
        "motion.lookahead_blocks": 64,
    }
    for a in "XYZ":
        v[f"axes.{a}.max_velocity_mm_min"] = pl["v_max"] * 60000
        v[f"axes.{a}.max_acceleration_mm_s2"] = pl["a_max"] * 1000
        v[f"axes.{a}.max_jerk_mm_s3"] = pl["j_max"] * 1000
    prog = tmp_path / "job.nc"
    prog.write_text(
        "G21 G90 G64\nG0 X5 Y5\nG1 X20 Y5 F3000\nX20 Y15\nX25 Y18 Z1\nG61 X30 Y18\n"
        "G64 G1 X40 Y30 F6000\nG4 P0.2\nG1 X0 Y0 Z0 F4000\n"
    )
    executed = job.run_job(str(prog))
    assert executed["faults"] == []
    est = estimate_program(gcode.read(prog), profiles.default().with_values(v), "planner")
    assert est.total_s == pytest.approx(executed["executed_s"], rel=0.001)


def test_a_block_the_planner_refuses_names_its_program_line(monkeypatch):
    from contour.planner import BlockRefused, Planner

    def refuse(self, *a, **kw):
        raise BlockRefused(1, "planner ring full")

    monkeypatch.setattr(Planner, "estimate", refuse)
    with pytest.raises(UserError, match=r"^line 3: planner: planner ring full$"):
        run("G21 G90\nG1 X10 F600\nG1 X20\nG1 X30\n", "planner")
