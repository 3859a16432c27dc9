"""The circle score's instrument (hil_sim/sim.h sim_table_record, circle.py
score): the true table sampled at the plant's substeps, >= 10 kHz whatever
the tick, against one sample per tick (docs/simulator.md, "Circle scenario
and scoring")."""

import math

import numpy as np
import pytest
from contour.sim import circle, core, machine


def _synthetic(tick_hz, dense_hz, vib_hz, amp, r=0.02, rev_s=0.4):
    """Trace rows (sim layout, one per tick) and instrument rows (t, x, y)
    of a circle traced exactly by the reference, the table on it plus a
    radial vibration amp sin(2 pi vib_hz t)."""
    w = 2 * math.pi / rev_s

    def table(t):
        a = w * t
        rad = r + amp * np.sin(2 * math.pi * vib_hz * t)
        return rad * np.cos(a), rad * np.sin(a)

    t = np.arange(1, int(1.5 * rev_s * tick_hz)) / tick_hz
    full = np.zeros((t.size, 16))
    full[:, 0] = t
    full[:, 4], full[:, 8] = r * np.cos(w * t), r * np.sin(w * t)
    full[:, 5], full[:, 9] = table(t)
    td = np.arange(1, int(1.5 * rev_s * dense_hz)) / dense_hz
    dense = np.column_stack([td, *table(td)])
    return full, dense


def test_dense_score_shows_a_vibration_the_tick_aliases_away():
    # a 666 Hz vibration sampled at 333 Hz in phase: every tick sees 0
    full, dense = _synthetic(333.0, 333.0 * 30, 666.0, 1e-6)
    res = circle.score(full, 0.0, 0.0, 0.02, 1, 0, dense=dense)
    assert res["scores"]["circular_deviation_mm"] * 1e3 == pytest.approx(2.0, rel=0.02)
    assert res["scores"]["max_contour_error_mm"] * 1e3 == pytest.approx(1.0, rel=0.02)
    assert res["tick_scores"]["circular_deviation_mm"] * 1e3 < 0.01
    # the scored window is the revolution's ticks: one revolution
    th = np.unwrap(np.arctan2(res["trace"][:, 2], res["trace"][:, 1]))
    assert abs(th[-1] - th[0]) == pytest.approx(2 * math.pi, abs=0.05)
    # without the instrument the tick rows are the score
    tick = circle.score(full, 0.0, 0.0, 0.02, 1, 0)
    assert tick["scores"]["circular_deviation_mm"] == res["tick_scores"]["circular_deviation_mm"]


def test_ten_khz_without_friction_scores_the_tick_samples():
    # one substep per tick: the instrument's samples are the trace rows
    run = circle.run_circle(20, 10000, controller="cec-curvature", feedforward="full", settle_s=0.1)
    r = run.result
    assert r.score_hz == 10000.0
    for k, v in r.tick_scores.items():
        assert getattr(r, k) == pytest.approx(v, rel=1e-9, abs=1e-15)


def test_three_ms_scores_the_table_between_ticks():
    m = machine.load("thesis_mean")
    run = circle.run_circle(20, 20000, controller="pid", feedforward="full", mach=m)
    r = run.result
    assert 10000.0 <= r.score_hz < 20000.0
    t = run.trace[:, 0]
    assert np.diff(t).max() < 1.0 / 10000.0 + 1e-9
    # the X table's vibration, forced at the hold's image (2 x 333 Hz), is
    # in the instrument's score and not in one sample per tick
    e = run.trace[:, 3]
    sp = np.abs(np.fft.rfft((e - e.mean()) * np.hanning(e.size)))
    fr = np.fft.rfftfreq(e.size, np.diff(t).mean())
    assert fr[np.argmax(sp * (fr > 300.0))] == pytest.approx(666.0, abs=5.0)
    assert r.circular_deviation_mm > 2 * r.tick_scores["circular_deviation_mm"]


def test_record_leaves_the_trace_unchanged_and_counts_lost_rows():
    so = core.lib()

    def trace(rec):
        m = machine.load("thesis_mean")
        machine.apply(m, feedforward="full", controller="pid")
        core.check(so.sim_enable(1), "enable")
        core.queue_line((2_000_000, 1_000_000, 0), 20_000_000, 1, True)
        if rec is not None:
            core.check(so.sim_table_record(rec.ctypes.data, rec.shape[0], 1e4), "record")
        try:
            out = core.run(40)
            n = so.sim_table_recorded()
        finally:
            so.sim_table_record(None, 0, 0.0)
        return out, n

    plain, _ = trace(None)
    cols = circle.rec_cols(so)
    rec = np.zeros((40 * so.sim_substeps(), cols))
    rows, n = trace(rec)
    assert np.array_equal(plain, rows)
    assert n == 40 * so.sim_substeps()  # 10.3 kHz: every substep
    # tick ends: the trace row of the next tick, bit for bit
    nsub = so.sim_substeps()
    assert np.array_equal(rec[nsub - 1 : -1 : nsub, 1], rows[1:, 5])
    assert np.array_equal(rec[nsub - 1 : -1 : nsub, 2], rows[1:, 9])
    assert np.all(np.diff(rec[:, 0]) > 0)
    small = np.zeros((10, cols))
    _, n = trace(small)
    assert n == 40 * nsub and small[-1, 0] > 0  # counted past the capacity, not written
    assert so.sim_table_record(None, 0, 0.0) == 0
    assert so.sim_table_record(small.ctypes.data, 10, 0.0) == -1


def test_record_has_the_2d_field_between_ticks():
    """With the 2-D error field on, every instrument sample carries it: the
    tick-end samples are the trace rows bit for bit and the samples between
    them continue smoothly (without the field they would jump by the
    field's error, microns, at every tick end)."""
    so = core.lib()
    m = machine.load("lacerda_xy_field")
    machine.apply(m, feedforward="full", controller="pid")
    core.check(so.sim_enable(1), "enable")
    core.queue_line((3_000_000, 2_000_000, 0), 20_000_000, 1, True)
    core.run(500)  # moving
    nsub = so.sim_substeps()
    assert nsub == 10  # friction: 10 us substeps
    rec = np.zeros((100 * nsub, circle.rec_cols(so)))
    core.check(so.sim_table_record(rec.ctypes.data, rec.shape[0], 1e5), "record")
    try:
        rows = core.run(100)
        n = so.sim_table_recorded()
    finally:
        so.sim_table_record(None, 0, 0.0)
    assert n == 100 * nsub
    assert np.array_equal(rec[nsub - 1 : -1 : nsub, 1:3], rows[1:, [5, 9]])
    field = np.hypot(*(rows[:, [5, 9]] - rows[:, [6, 10]]).T).max()
    assert field > 1e-6  # the field moves the table microns from the encoders' view
    d2 = np.abs(np.diff(rec[:, 1:3], 2, axis=0)).max()
    assert d2 < 0.02 * field
