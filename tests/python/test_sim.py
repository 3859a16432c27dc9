"""The HIL simulator from Python: determinism, encoder agreement, the
circle scores, shipped gain sets, machine files and the command line."""

import json

import numpy as np
import pytest
from contour import cli
from contour.errors import UserError
from contour.sim import circle, core, job, machine, tuning


def test_x_axis_eigenvalues_match_spec():
    ev = tuning.eigenvalues(machine.load().axis["x"])
    re = sorted(ev.real)
    assert abs(re[0] + 1190) < 5 and abs(re[1] + 149) < 0.5
    assert max(abs(ev.imag)) == pytest.approx(4170, abs=5)
    assert min(abs(e) for e in ev) < 1e-6


@pytest.mark.parametrize("name", ["default", "thesis", "realistic", "thesis_mean", "default_mean"])
def test_shipped_gain_sets_are_robust(name):
    m = machine.load(name)
    for loop, mg in tuning.machine_margins(m).items():
        assert mg["stable"], (name, loop)
        assert mg["sensitivity_peak"] <= 2.0, (name, loop, mg)


def test_mean_measurement_loop_is_half_a_tick_late_and_costs_the_cec_its_margin():
    """tuning.Loop(mean=True): the plant seen through the mean over the tick
    (drive.h enc_mean) is the sampled plant delayed half a tick at low
    frequency; thesis.toml's CEC gains leave Ms 2.9 with it (why
    thesis_mean.toml retunes them), the axes alone stay below 1.4."""
    m = machine.load("thesis")
    s, mn = tuning.Loop(m.axis["x"], 333), tuning.Loop(m.axis["x"], 333, mean=True)
    w, t = s.w[:200], s.t
    ratio = mn.p[:200] / s.p[:200]
    assert np.allclose(ratio, np.exp(-0.5j * w * t), atol=2e-3)
    mg = tuning.machine_margins(m, mean=True)
    assert mg["axis_x"]["sensitivity_peak"] < 1.4
    assert 2.8 < mg["axis_x+cec"]["sensitivity_peak"] < 3.0
    assert (
        tuning.machine_margins(machine.load("thesis_mean"))["axis_x+cec"]["sensitivity_peak"] < 1.9
    )


def test_thesis_cec_gains_are_not_robust_at_10khz():
    """The published CEC gains (Table 4.1) fail the margin check."""
    m = machine.load()
    loop = tuning.Loop(m.axis["x"], 10000)
    axis = {"kp": 1500, "ki": 8000, "kd": 5}
    mg = loop.margins(axis, {"kp": 4e4, "ki": 2e6, "kd": 100})
    assert not mg.stable or mg.ms > 2


def test_circle_is_deterministic_and_edges_agree():
    a = circle.run_circle(20, 10000, controller="cec-exact", settle_s=0.1)
    b = circle.run_circle(20, 10000, controller="cec-exact", settle_s=0.1)
    assert np.array_equal(a.full, b.full)
    assert a.result.edges > 10000
    assert a.result.edge_mismatch_ticks == 0
    assert a.result.faults == []


def test_encoder_models_agree():
    """The fast encoder model (a substep's edges as one update) and the
    edge-accurate reference give the same run, bit for bit: every trace row
    and the scores (docs/simulator.md, "Encoder models")."""
    so = core.lib()
    runs = {}
    for model in ("edges", "fast"):
        runs[model] = circle.run_circle(
            20,
            10000,
            controller="cec-exact",
            feedforward="full",
            settle_s=0.1,
            encoder_model=model,
        )
        assert so.sim_encoder_model_get() == core.ENCODER_MODELS[model]
        runs[model + "_run_edges"] = int(so.sim_run_edges())
    a, b = runs["edges"], runs["fast"]
    assert runs["edges_run_edges"] == 0
    assert runs["fast_run_edges"] > 0.9 * b.result.edges
    assert np.array_equal(a.full, b.full)
    assert a.result == b.result
    assert a.result.edge_mismatch_ticks == 0


def test_encoder_model_from_machine_file_and_cli(tmp_path, capsys):
    so = core.lib()
    src = (machine.MACHINES / "default.toml").read_text()
    f = tmp_path / "m.toml"
    f.write_text('encoder_model = "edges"\n' + src)
    assert machine.load(str(f)).encoder_model == "edges"
    assert machine.load("default").encoder_model == "fast"
    circle.run_circle(20, 10000, controller="pid", settle_s=0.1, machine_file=str(f))
    assert so.sim_encoder_model_get() == core.ENCODER_MODELS["edges"]
    argv = ["sim", "circle", "--radius", "20", "--feed", "10000", "--controller", "pid"]
    assert cli.main([*argv, "--machine", str(f), "--encoder-model", "fast", "--json"]) == 0
    capsys.readouterr()
    assert so.sim_encoder_model_get() == core.ENCODER_MODELS["fast"]
    f.write_text('encoder_model = "exact"\n' + src)
    with pytest.raises(UserError, match="encoder_model"):
        machine.load(str(f))


def test_cec_removes_the_radius_error_of_the_pids():
    """Thesis set-up (no feed-forward), 10 kHz, R 20 mm, 10 m/min."""
    pid = circle.run_circle(20, 10000, controller="pid").result
    cec = circle.run_circle(20, 10000, controller="cec-curvature").result
    assert pid.mean_radial_error_mm > 0.1  # the PIDs leave the circle too large
    assert pid.max_contour_error_mm >= 20 * cec.max_contour_error_mm
    assert pid.circular_deviation_mm >= 2 * cec.circular_deviation_mm


def test_product_default_within_one_micrometre():
    res = circle.run_circle(20, 10000, controller="cec-exact", feedforward="full").result
    assert res.circular_deviation_mm <= 1e-3
    assert res.max_contour_error_mm <= 1e-3


def test_scores_match_their_definition():
    run = circle.run_circle(50, 10000, controller="pid", feedforward="full", settle_s=0.1)
    e = run.trace[:, 3]
    r = run.result
    assert r.circular_deviation_mm == pytest.approx((e.max() - e.min()) * 1e3)
    assert r.max_contour_error_mm == pytest.approx(np.abs(e).max() * 1e3)
    # one full revolution is scored
    th = np.unwrap(np.arctan2(run.trace[:, 2], run.trace[:, 1]))
    assert abs(th[-1] - th[0]) == pytest.approx(2 * np.pi, abs=0.01)


def test_bad_inputs_are_user_errors(tmp_path):
    with pytest.raises(UserError, match="radius"):
        circle.run_circle(-1, 10000, controller="pid")
    bad = tmp_path / "m.toml"
    bad.write_text("[axis.x]\nI3 = 1.0\n")
    with pytest.raises(UserError, match="unknown key"):
        machine.load(str(bad))
    bad.write_text("tick_hz = 5\n")
    with pytest.raises(UserError, match="tick_hz"):
        machine.load(str(bad))
    bad.write_text("[axis.x\n")
    with pytest.raises(UserError, match="invalid TOML"):
        machine.load(str(bad))
    with pytest.raises(UserError, match="not found"):
        machine.load("no-such-machine")


def test_cli_circle_json(capsys):
    rc = cli.main(
        [
            "sim",
            "circle",
            "--radius",
            "20",
            "--feed",
            "10000",
            "--controller",
            "cec-exact",
            "--feedforward",
            "full",
            "--json",
        ]
    )
    out = json.loads(capsys.readouterr().out)
    assert rc == 0
    for key in ("iae_mm_s", "max_contour_error_mm", "circular_deviation_mm"):
        assert key in out
    assert cli.main(["sim", "circle", "--radius", "0", "--feed", "10", "--controller", "pid"]) == 2


def test_sim_run_gcode(tmp_path):
    nc = tmp_path / "job.nc"
    # a smooth path: line, tangent half circle, tangent line; then a dwell
    nc.write_text("G21 G90 G17\nG1 X10 F6000\nG3 X10 Y10 I0 J5\nG1 X0\nG4 P0.05\nM30\n")
    rep = job.run_job(str(nc), controller="cec-exact", feedforward="full")
    assert rep["faults"] == []
    assert rep["blocks"] == 4
    # 35.7 mm at 100 mm/s plus the ramps (the dwell comes after the motion)
    assert 0.36 < rep["executed_s"] < 0.45
    assert rep["max_contour_error_um"] < 10  # the curvature steps at the arc ends
    assert rep["edge_mismatch_ticks"] == 0


def test_serve_is_wired(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["sim", "serve", "--help"])
    assert exc.value.code == 0
    assert "serve" in capsys.readouterr().out


@pytest.mark.parametrize("direction", ["ccw", "cw"])
def test_realistic_machine_target(direction):
    """Friction with 90 % friction feed-forward, feed-forward gains X 2 %
    low, Y 2 % high, the drive's quadrant-glitch compensation and
    feed-forward learning (docs/simulator.md "Realistic machine"). Issue
    21's figure: the CEC <= 5 um and >= 2x better than the PIDs alone.
    Measured with the compensation reading the friction step across each
    reversal (drive_ff.h): 0.5 s of settling CEC 3.90 / 3.84 um (ccw / cw)
    against 12.53; 8 s 3.55 / 3.50 against 12.03 (3.4x). While it read the
    last two reversals: 5.03 against 10.38 at 0.5 s, 5.88 against 10.35 at
    8 s (the PIDs' lower figure: those jumps also took out part of the
    feed-forward gain error's ellipse); reading the axis integrator alone
    before that, 4.68 at 0.5 s drifted to 14.8 um at 30 s."""

    def dev(ctl, settle):
        r = circle.run_circle(
            20,
            10000,
            direction,
            controller=ctl,
            feedforward="full",
            machine_file="realistic",
            settle_s=settle,
        ).result
        assert r.faults == []
        return r.circular_deviation_mm

    pid, cec = dev("pid", 0.5), dev("cec-curvature", 0.5)
    assert cec <= 4.5e-3  # issue 21: <= 5 um
    assert pid >= 2.8 * cec  # issue 21: >= 2x
    pid, cec = dev("pid", 8.0), dev("cec-curvature", 8.0)
    assert cec <= 4.2e-3  # issue 21: <= 5 um, settled
    assert pid >= 2.8 * cec  # issue 21: >= 2x, settled


def test_thesis_tick_product_default():
    res = circle.run_circle(
        20, 10000, controller="cec-exact", feedforward="full", machine_file="thesis"
    )
    assert res.result.tick_hz == 333
    assert res.result.circular_deviation_mm <= 3e-3
