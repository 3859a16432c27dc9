"""The ctypes wrapper of the drive's planner (contour.planner)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from contour.errors import UserError
from contour.planner import Planner, PlannerProfile


def _prof(**kw) -> PlannerProfile:
    # the per-block S-curve these closed forms are written for (the default
    # is the drive's, the continuous S-curve)
    base = dict(
        shape="s-curve",
        v_max_mm_s=(500.0, 500.0, 500.0),
        a_max_mm_s2=(2000.0, 2000.0, 2000.0),
        j_max_mm_s3=(50000.0, 50000.0, 50000.0),
    )
    base.update(kw)
    return PlannerProfile(**base)


def test_single_move_closed_forms():
    # 100 mm at 100 mm/s, A = 2 m/s^2, J = 50 m/s^3: L/v + v/A (+ A/J for the S-curve)
    r = Planner(_prof(shape="s-curve")).estimate([[100, 0, 0]], feed_mm_min=6000)
    assert r.total_s == pytest.approx(1.09, abs=1e-8)
    b = r.blocks[0]
    assert b["v_peak_mm_s"] == pytest.approx(100.0)
    assert b["t_acc_s"] == pytest.approx(0.09, abs=1e-8)
    assert b["t_cruise_s"] == pytest.approx(0.91, abs=1e-8)
    r = Planner(_prof(shape="trapezoid")).estimate([[100, 0, 0]], feed_mm_min=6000)
    assert r.total_s == pytest.approx(1.05, abs=1e-8)
    # the drive executes whole ticks: ceil(1.05 s / 0.1 ms)
    assert r.ticks == 10500
    assert r.executed_s == pytest.approx(1.05)


def test_s_curve_at_rest_shape():
    # rest to rest: the S-curve (1.09 s); a chain of collinear 0.1 mm blocks
    # runs as the trapezoid between its S-curve first and last blocks, where the
    # plain S-curve (acceleration 0 at every block end) crawls
    one = [[100, 0, 0]]
    r = Planner(_prof(shape="s-curve-at-rest")).estimate(one, feed_mm_min=6000)
    assert r.total_s == pytest.approx(1.09, abs=1e-8)
    pts = np.zeros((1000, 3))
    pts[:, 0] = 0.1 * np.arange(1, 1001)
    kw = dict(j_max_mm_s3=(2000.0,) * 3)
    res = {
        shape: Planner(_prof(shape=shape, **kw)).estimate(pts, 12000)
        for shape in ("trapezoid", "s-curve", "s-curve-at-rest")
    }
    t = {k: v.total_s for k, v in res.items()}
    # measured: 0.708 s, 10.82 s, 0.856 s (the two slow S-curve end blocks)
    assert t["trapezoid"] < t["s-curve-at-rest"] < t["trapezoid"] * 1.3
    assert t["s-curve"] > 10 * t["trapezoid"]
    # inner blocks: about the trapezoid's look-ahead limited speed (depth 64;
    # a little lower: the newest queued block stops with the S-curve)
    mid, trap = res["s-curve-at-rest"].blocks[500], res["trapezoid"].blocks[500]
    assert mid["t_total_s"] == pytest.approx(trap["t_total_s"], rel=0.01)
    # reversals: every block from and to rest, the S-curve's time
    rev = np.array([[1.0 * (k % 2 == 0), 0, 0] for k in range(10)])
    a = Planner(_prof(shape="s-curve-at-rest")).estimate(rev, 6000)
    s = Planner(_prof(shape="s-curve")).estimate(rev, 6000)
    assert a.total_s == pytest.approx(s.total_s, abs=1e-9)


def test_s_curve_continuous_shape():
    # the CAM circle of the stream bench (0.05 mm chords of R 20 mm at F10000,
    # 10 m/s^2, 1000 m/s^3): the continuous S-curve runs it at feed between
    # a jerk-limited start and stop, joining blocks at non-zero acceleration;
    # the per-block S-curve (acceleration 0 at every block end) cannot
    n = 2000
    ang = np.arange(1, n + 1) * 0.05 / 20.0
    pts = np.stack([20 * np.cos(ang), 20 * np.sin(ang), 0 * ang], axis=1)
    tuned = dict(a_max_mm_s2=(10000.0,) * 3, j_max_mm_s3=(1e6,) * 3)
    ideal = n * 0.05 / (10000 / 60)
    r = Planner(_prof(shape="s-curve-continuous", **tuned)).estimate(
        pts, feed_mm_min=10000, start_mm=(20, 0, 0)
    )
    assert ideal < r.total_s < ideal + 0.04
    mid = r.blocks[n // 2]
    assert mid["v_peak_mm_s"] == pytest.approx(10000 / 60, rel=1e-6)
    assert r.blocks[-1]["v_exit_mm_s"] == 0
    slow = Planner(_prof(shape="s-curve", **tuned)).estimate(
        pts, feed_mm_min=10000, start_mm=(20, 0, 0)
    )
    assert slow.total_s > 3 * r.total_s
    with pytest.raises(UserError, match="smoothed-corner"):
        _prof(shape="s-curve-continuous", corner="smoothed-corner").to_c()


def test_corner_rules_and_exact_stop():
    pts = [[100, 0, 0], [100, 100, 0]]
    jd = Planner(_prof(corner="junction-deviation")).estimate(pts, 24000)
    s, aj = math.sqrt(0.5), 2000 * math.sqrt(2)
    assert jd.blocks["v_entry_mm_s"][1] == pytest.approx(
        math.sqrt(aj * 0.01 * s / (1 - s)), rel=1e-4
    )
    sm = Planner(_prof(corner="smoothed-corner", corner_acc_mm_s2=(300, 300, 300))).estimate(
        pts, 24000
    )
    assert sm.blocks["v_entry_mm_s"][1] == pytest.approx(math.sqrt(300 * 100 / 1.0), rel=1e-5)
    vs = Planner(_prof(corner="velocity-step", corner_dv_mm_s=(5, 5, 5))).estimate(pts, 24000)
    assert vs.blocks["v_entry_mm_s"][1] == pytest.approx(5.0, abs=1e-5)
    st = Planner(_prof()).estimate(pts, 24000, exact_stop=[True, False])
    assert st.blocks["v_exit_mm_s"][0] == 0.0
    assert st.total_s > jd.total_s


def test_smoothed_corner_caps_block_speed():
    # staircase of 0.3 mm X/Y blocks: every inner block runs at its corner
    # speed sqrt(a_c l / |du|) from end to end, t = l / v_c
    n = 100
    i = np.arange(n)
    pts = np.stack([((i + 2) // 2) * 0.3, ((i + 1) // 2) * 0.3, np.zeros(n)], axis=1)
    prof = _prof(shape="trapezoid", corner="smoothed-corner", corner_acc_mm_s2=(186, 57, 186))
    r = Planner(prof).estimate(pts, 15000)
    vc = math.sqrt(57 * 0.3)
    inner = r.blocks[1:-1]
    assert np.allclose(inner["v_max_mm_s"], vc, rtol=1e-6)
    assert np.allclose(inner["t_total_s"], 0.3 / vc, rtol=1e-6)
    assert inner["corner_capped"].all()
    assert not r.blocks["corner_capped"][0] and not r.blocks["corner_capped"][-1]
    # other rules never cap
    jd = Planner(_prof(shape="trapezoid")).estimate(pts, 15000)
    assert not jd.blocks["corner_capped"].any()


def test_min_block_time_throughput_and_cap():
    # camargo2017-like staircase: 2000 collinear 0.01 mm blocks at F15000
    n = 2000
    pts = np.zeros((n, 3))
    pts[:, 0] = 0.01 * np.arange(1, n + 1)
    prof = _prof(shape="trapezoid", min_block_time_s=0.00045, mbt_window=8)
    r = Planner(prof).estimate(pts, 15000)
    steady = r.blocks["t_total_s"][100:-100]
    assert np.allclose(steady, 0.00045, atol=2e-9)
    assert r.blocks["mbt_limited"][100:-100].all()
    assert r.t_mbt_s == pytest.approx(r.blocks["t_mbt_s"].sum())
    # a short block between long ones: free with throughput, slowed by a cap
    pts = [[10, 0, 0], [10.02, 0, 0], [20, 0, 0]]
    thr = Planner(prof).estimate(pts, 6000)
    cap = Planner(
        _prof(shape="trapezoid", min_block_time_s=0.00045, block_time_rule="cap")
    ).estimate(pts, 6000)
    assert thr.blocks["t_total_s"][1] == pytest.approx(0.0002, abs=1e-8)
    assert cap.blocks["t_total_s"][1] >= 0.00045 - 1e-9


def test_dwell_skip_and_split_sum():
    pts = [[10, 0, 0], [10, 0, 0], [10, 0, 0], [20, 5, 0]]
    r = Planner(_prof()).estimate(pts, 3000, dwell_s=[0, 0.5, 0, 0])
    assert r.blocks["t_total_s"][1] == pytest.approx(0.5)
    assert bool(r.blocks["skipped"][2])
    b = r.blocks
    assert np.allclose(
        b["t_acc_s"] + b["t_cruise_s"] + b["t_dec_s"] + [0, 0.5, 0, 0], b["t_total_s"]
    )
    assert r.t_acc_s + r.t_cruise_s + r.t_dec_s + 0.5 == pytest.approx(r.total_s)


def test_depth_changes_the_lookahead():
    # a long run of short collinear blocks ending in a stop: a deeper
    # look-ahead can only be faster
    pts = np.zeros((500, 3))
    pts[:, 0] = 0.05 * np.arange(1, 501)
    shallow = Planner(_prof(shape="trapezoid", depth=4)).estimate(pts, 30000)
    deep = Planner(_prof(shape="trapezoid", depth=256)).estimate(pts, 30000)
    assert deep.total_s < shallow.total_s


@pytest.mark.parametrize(
    "kw, msg",
    [
        (dict(shape="cubic"), "shape"),
        (dict(corner="round"), "corner"),
        (dict(a_max_mm_s2=(0, 1, 1)), "a_max_mm_s2"),
        (dict(v_max_mm_s=(1, 2)), "3 values"),
        (dict(block_time_rule="both"), "block_time_rule"),
        (dict(mbt_window=0), "mbt_window"),
        (dict(tick_hz=7), "tick_hz"),
        (dict(j_max_mm_s3=(10, 10, 10)), "profile rejected"),  # a/j = 200 s
    ],
)
def test_bad_profiles(kw, msg):
    with pytest.raises(UserError, match=msg):
        Planner(_prof(**kw))


def test_bad_blocks():
    pl = Planner(_prof())
    with pytest.raises(UserError, match="feed"):
        pl.estimate([[1, 0, 0]], 0)
    with pytest.raises(UserError, match=r"\(n, 3\)"):
        pl.estimate([[1, 0]], 100)
    with pytest.raises(UserError, match="non-finite"):
        pl.estimate([[float("nan"), 0, 0]], 100)
    with pytest.raises(UserError, match="block 1"):
        pl.estimate([[1, 0, 0], [1e7, 0, 0]], 100)  # 10 km block
