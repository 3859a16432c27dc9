"""Experiment tables, program generation, fitting and `contour fit-profile`."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from contour import cli, gcode
from contour.errors import UserError
from contour.estimation import estimate_program
from contour.estimation import experiments as xp
from contour.estimation import fit as fitting
from contour.estimation import profile as profiles

ROOT = Path(__file__).resolve().parents[2]
CAMARGO_DIR = ROOT.parent / "shared" / "data" / "camargo2017"
CAMARGO = sorted(CAMARGO_DIR.glob("*.csv"))


def test_the_four_tables_are_read_as_they_are():
    exps = xp.read_all(CAMARGO)
    assert len(exps) == 152
    tables = {}
    for e in exps:
        tables[e.table] = tables.get(e.table, 0) + 1
    assert tables == {"exp1": 37, "exp2_x": 4, "exp2_y": 81, "exp3": 30}
    assert [e.name for e in exps if e.suspect] == ["E2Y75"]


def _deltas(e, n):
    prog = e.program(n)
    return np.diff(np.vstack([prog.start[:3], prog.end[:, :3]]), axis=0)


def test_generated_programs_follow_their_rows():
    exps = {e.name: e for e in xp.read_all(CAMARGO)}
    # exp2 Y: X = enl1, Z = enl2, Y alternates s1, s2 starting with s1.
    d = _deltas(exps["E2Y06"], 4)
    np.testing.assert_allclose(d, [[0.2, 0.2, 0.1], [0.2, 0.05, 0.1]] * 2)
    # exp2 X: Y = enl1, Z = enl2 (XYZ order of the other axes).
    d = _deltas(exps["E2X41"], 2)
    np.testing.assert_allclose(d, [[0.05, 0.2, 0.2], [0.005, 0.2, 0.2]])
    # exp3: +s then -s on one axis.
    d = _deltas(exps["E3Z0.050"], 4)
    np.testing.assert_allclose(d, [[0, 0, 0.05], [0, 0, -0.05]] * 2)
    # exp1: an empty cell omits the word; the full program has `lines` blocks at F15000.
    e = exps["E1V6P1"]
    assert "Z" not in e.pattern[0] and e.pattern[0].startswith("X0.1")
    prog = e.program()
    assert len(prog) == e.lines == 4000
    assert np.all(prog.feed == 15000)
    assert e.text(2).count("\n") == len(e.header) + 3


def test_plain_program_time_csv(tmp_path):
    (tmp_path / "a.nc").write_text("G1 X10 F600\n")
    (tmp_path / "runs.csv").write_text("program,time_s\na.nc,1.5\n")
    [e] = xp.read_csv(tmp_path / "runs.csv")
    assert e.path == str(tmp_path / "a.nc") and e.time_s == 1.5 and not e.periodic
    assert len(e.program()) == 1


@pytest.mark.parametrize(
    "text,message",
    [
        ("a,b\n1,2\n", "unknown experiment table"),
        ("program,time_s\na.nc,fast\n", "'fast' is not a number"),
        ("program,time_s\na.nc,-1\n", "time_s must be a positive number"),
        ("program,time_s\n", "no rows"),
        ("test,axis,s_mm,lines,time_s\nE,Q,0.1,10,3\n", "axis must be X, Y or Z"),
        ("test,axis,s_mm,lines,time_s\nE,X,0.1,1.5,3\n", "lines must be a whole number"),
        ("program,time_s\na.nc,1\na.nc,2\n", "appears twice"),
    ],
)
def test_bad_experiment_tables(tmp_path, text, message):
    f = tmp_path / "t.csv"
    f.write_text(text)
    with pytest.raises(UserError, match=message):
        xp.read_csv(f)


def _synthetic(tmp_path, profile, model, programs):
    """Write programs and their run times under `profile` (the truth)."""
    rows = ["program,time_s"]
    for i, text in enumerate(programs):
        name = f"p{i}.nc"
        (tmp_path / name).write_text(text)
        t = estimate_program(gcode.read(tmp_path / name), profile, model).total_s
        rows.append(f"{name},{t!r}")
    (tmp_path / "runs.csv").write_text("\n".join(rows) + "\n")
    return tmp_path / "runs.csv"


def test_fit_recovers_the_minimum_block_time_of_the_mrt_model(tmp_path):
    truth = profiles.default().with_values({"motion.min_block_time_s": 0.0021})
    progs = [
        "G91 G1 F6000\n" + "X0.01\n" * 50,
        "G91 G1 F6000\n" + "X0.05 Y0.01\n" * 30 + "X20\n",
        "G91 G1 F3000\n" + "Y0.3\n" * 40,
    ]
    runs = _synthetic(tmp_path, truth, "mrt", progs)
    exps = xp.read_csv(runs)
    base = profiles.default()
    params = [fitting.parse_param("motion.min_block_time_s", base)]

    def residuals(values):
        p = base.with_values(values)
        return np.array(
            [estimate_program(e.program(), p, "mrt").total_s / e.time_s - 1 for e in exps]
        )

    res = fitting.fit(params, residuals)
    assert res.values["motion.min_block_time_s"] == pytest.approx(0.0021, rel=1e-4)
    assert np.max(np.abs(res.residuals)) < 1e-4


def _planner_truth():
    v = {
        "motion.corner_rule": "smoothed-corner",
        "motion.velocity_profile": "trapezoid",
        "motion.min_block_time_s": 0.0005,
        "axes.X.corner_acceleration_mm_s2": 150.0,
        "axes.Y.corner_acceleration_mm_s2": 60.0,
        "axes.Z.corner_acceleration_mm_s2": 150.0,
        "axes.X.max_acceleration_mm_s2": 400.0,
        "axes.Y.max_acceleration_mm_s2": 250.0,
        "axes.Z.max_acceleration_mm_s2": 400.0,
    }
    return profiles.default().with_values(v)


PLANNER_PROGRAMS = [
    "G91 G1 F15000\n" + "X0.2 Y0.2 Z0.2\nX0.2 Y0.05 Z0.2\n" * 30,  # Y corners
    "G91 G1 F15000\n" + "X0.1 Y0.2 Z0.2\nX0.01 Y0.2 Z0.2\n" * 30,  # X corners
    "G91 G1 F15000\n" + "X0.3\nX-0.3\n" * 10,  # X reversals
    "G91 G1 F15000\n" + "Y0.3\nY-0.3\n" * 10,  # Y reversals
    "G91 G1 F15000\n" + "X0.001\n" * 300,  # block processing
    "G91 G1 F15000\n" + "Y0.1 Z0.1\nY0.1 Z0.12\n" * 30,
]


def test_cli_fit_recovers_planner_parameters_and_writes_a_profile(tmp_path, capsys):
    truth = _planner_truth()
    runs = _synthetic(tmp_path, truth, "planner", PLANNER_PROGRAMS)
    base = tmp_path / "base.toml"
    start = truth.with_values(
        {
            "motion.min_block_time_s": 0.0004,
            "axes.X.corner_acceleration_mm_s2": 100.0,
            "axes.Z.corner_acceleration_mm_s2": 100.0,
            "axes.Y.corner_acceleration_mm_s2": 80.0,
            "axes.X.max_acceleration_mm_s2": 300.0,
            "axes.Z.max_acceleration_mm_s2": 300.0,
            "axes.Y.max_acceleration_mm_s2": 300.0,
        }
    )
    profiles.save(start, base)
    out = tmp_path / "fitted.toml"
    rc = cli.main(
        [
            "fit-profile",
            "--experiments",
            str(runs),
            "--base",
            str(base),
            "--out",
            str(out),
            "--compare",
            "planner,feed",
            "--json",
        ]
    )
    assert rc == 0
    rep = json.loads(capsys.readouterr().out)
    fitted = {k: v["value"] for k, v in rep["fitted"].items()}
    assert fitted["axes.XZ.corner_acceleration_mm_s2"] == pytest.approx(150, rel=0.02)
    assert fitted["axes.Y.corner_acceleration_mm_s2"] == pytest.approx(60, rel=0.02)
    assert fitted["axes.XZ.max_acceleration_mm_s2"] == pytest.approx(400, rel=0.02)
    assert fitted["axes.Y.max_acceleration_mm_s2"] == pytest.approx(250, rel=0.02)
    assert fitted["motion.min_block_time_s"] == pytest.approx(0.0005, rel=0.02)
    assert rep["errors"]["planner"]["all"]["with_suspect"]["mean_abs_pct"] < 0.5
    assert rep["errors"]["feed"]["all"]["with_suspect"]["mean_abs_pct"] > 20
    text = out.read_text()
    assert "contour fit-profile --experiments" in text and "--base" in text
    p = profiles.load(out)
    assert p.get("axes.X.corner_acceleration_mm_s2") == p.get("axes.Z.corner_acceleration_mm_s2")


def test_fit_refuses_parameters_the_data_cannot_identify(tmp_path, capsys):
    truth = profiles.default().with_values({"motion.min_block_time_s": 0.002})
    runs = _synthetic(tmp_path, truth, "mrt", ["G91 G1 F6000\n" + "X0.01\n" * 20, "G1 X5 F600\n"])
    # The mrt model knows no accelerations: no measurement depends on them.
    rc = cli.main(
        [
            "fit-profile",
            "--experiments",
            str(runs),
            "--model",
            "mrt",
            "--fit",
            "motion.min_block_time_s",
            "axes.X.max_acceleration_mm_s2",
        ]
    )
    assert rc == 1
    err = capsys.readouterr().err
    assert "refusing to fit" in err and "axes.X.max_acceleration_mm_s2" in err
    # More parameters than measurements.
    one = tmp_path / "one.csv"
    one.write_text("program,time_s\np0.nc,1.0\n")
    rc = cli.main(
        [
            "fit-profile",
            "--experiments",
            str(one),
            "--fit",
            "axes.X.max_acceleration_mm_s2",
            "axes.Y.max_acceleration_mm_s2",
        ]
    )
    assert rc == 1
    assert "2 parameters but only 1 measurements" in capsys.readouterr().err


def test_fit_refuses_an_axis_the_tests_never_limit(tmp_path, capsys):
    # Only X moves: the Z corner acceleration changes nothing.
    truth = _planner_truth()
    runs = _synthetic(tmp_path, truth, "planner", PLANNER_PROGRAMS[:3] + PLANNER_PROGRAMS[4:5])
    rc = cli.main(
        [
            "fit-profile",
            "--experiments",
            str(runs),
            "--set",
            "motion.corner_rule=smoothed-corner",
            "--set",  # the default continuous S-curve refuses the smoothed corner
            "motion.velocity_profile=trapezoid",
            "--fit",
            "axes.X.corner_acceleration_mm_s2",
            "axes.Z.corner_acceleration_mm_s2",
        ]
    )
    assert rc == 1
    assert "no measurement depends on axes.Z.corner_acceleration_mm_s2" in capsys.readouterr().err


def test_identifiability_names_a_degenerate_combination():
    params = [fitting.Param(n, (n,), 1.0, 1e-3, 1e3) for n in ("a", "b", "c")]
    J = np.array([[1.0, 2.0, 0.3], [2.0, 4.0, 0.1], [0.5, 1.0, 0.7], [1.0, 2.0, 0.2]])
    why = fitting.identifiability(params, J)
    assert why.startswith("the data only constrain a combination of") and "a" in why
    assert fitting.identifiability(params, J + np.eye(4, 3)) is None


@pytest.mark.parametrize(
    "spec,message",
    [
        ("axes.Q.max_acceleration_mm_s2", "not a set of axes"),
        ("motion.corner_rule", "cannot fit"),
        ("axes.X.speed", "cannot fit"),
        ("motion.min_block_time_s=-1", "start value must be positive"),
        ("motion.min_block_time_s:5:1", "bounds must be 0 < LOW < HIGH"),
        ("motion.min_block_time_s=1:0.1:0.5", "outside"),
    ],
)
def test_bad_fit_parameters(spec, message):
    with pytest.raises(UserError, match=message):
        fitting.parse_param(spec, profiles.default())


def test_tied_axes_parameter():
    p = fitting.parse_param("axes.XZ.corner_acceleration_mm_s2=50:1:500", profiles.default())
    assert p.paths == ("axes.X.corner_acceleration_mm_s2", "axes.Z.corner_acceleration_mm_s2")
    assert (p.start, p.low, p.high) == (50, 1, 500)
    with pytest.raises(UserError, match="fitted twice"):
        fitting.check_overlap(
            [p, fitting.parse_param("axes.X.corner_acceleration_mm_s2", profiles.default())]
        )


def test_no_fit_report_on_the_camargo_tables(capsys):
    rc = cli.main(
        [
            "fit-profile",
            "--experiments",
            *map(str, CAMARGO),
            "--no-fit",
            "--compare",
            "planner,camargo2017,mrt,feed",
            "--base",
            str(ROOT / "profiles" / "hermle_c1200v_itnc530.toml"),
            "--json",
        ]
    )
    assert rc == 0
    rep = json.loads(capsys.readouterr().out)
    cam = rep["errors"]["camargo2017"]
    assert set(cam) == {"exp1", "exp2_x", "exp2_y", "exp3", "all"}
    assert cam["all"]["with_suspect"]["n"] == 152
    assert cam["all"]["without_suspect"]["n"] == 151
    assert "without_suspect" not in cam["exp3"]
    # distance/feed is off by far more than the empirical model
    feed = rep["errors"]["feed"]["all"]["with_suspect"]["mean_abs_pct"]
    assert feed > 5 * cam["all"]["with_suspect"]["mean_abs_pct"]
    assert math.isfinite(cam["exp2_y"]["without_suspect"]["mean_abs_pct"])
    # the targets the committed HERMLE profile meets (issue 6): the planner's
    # mean error at most 7 % over the 152 tests, better than camargo2017 on
    # every table (measured: 4.76 % overall; exp3 3.85 % against 4.10 %)
    pl = rep["errors"]["planner"]
    assert pl["all"]["with_suspect"]["n"] == 152
    assert pl["all"]["with_suspect"]["mean_abs_pct"] <= 7.0
    for table in ("exp1", "exp2_x", "exp2_y", "exp3"):
        mine = pl[table]["with_suspect"]["mean_abs_pct"]
        assert mine < cam[table]["with_suspect"]["mean_abs_pct"], table
