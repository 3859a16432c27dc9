"""The excitation experiment of one axis and its record.

The drive side is not built yet: `simulate` runs the experiment on the
simulated drive of the C simulator (hil_sim/sim.h, set up from a machine
description, contour.sim.machine), the same firmware, axis model and PID
as every other simulation. The axis is held at rest by the drive's own
PID; a periodic multisine (random phases, flat amplitude on `lines`
log-spaced DFT bins from `f_min_hz` to `f_max_hz`) is added to the motor
command through the simulator's injection point (sim_inject: an additive
voltage at the amplifier input per tick) for `periods` periods of
`period_ticks` ticks, then the drive moves the axis at +-v1 and +-v2
(constant-velocity legs, queued lines) for the friction estimate. Every
tick records, from the simulator's trace, the motor command u (V at the
amplifier input, the drive's command plus the injection) and the
position the drive measured y (m, from its encoder counts). Limits given
by the user bound it: travel (m either side of the start), command (V),
velocity (m/s, of the table over one tick); `simulate` checks them after
every block of ticks and stops at the first violation (the drive must do
it within the tick), as it stops when the drive faults.

The command computed at tick k is applied over tick k (sim.h, step 6).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, replace

import numpy as np

from contour.sim import core, machine


class ExperimentAborted(RuntimeError):
    pass


@dataclass
class Limits:
    travel_m: float = 0.010
    command_v: float = 20.0
    velocity_m_s: float = 0.2


@dataclass
class Plan:
    tick_hz: float = 10000.0
    period_ticks: int = 4096
    periods: int = 12
    amplitude_v: float = 3.0  # rms of the multisine, V
    f_min_hz: float = 5.0
    f_max_hz: float = 1500.0
    lines: int = 160  # excited bins, log-spaced (power where it is needed)
    seed: int = 1
    friction_speeds_m_s: tuple = (0.005, 0.010)
    friction_leg_s: float = 0.25

    def excited_bins(self) -> np.ndarray:
        return self.multisine()[1]

    def multisine(self) -> tuple[np.ndarray, np.ndarray]:
        """(one period of the excitation in V, the excited bin indices)."""
        n = self.period_ticks
        df = self.tick_hz / n
        k0 = max(1, int(math.ceil(self.f_min_hz / df)))
        k1 = min(n // 2 - 1, int(self.f_max_hz / df))
        bins = np.unique(np.round(np.geomspace(k0, k1, self.lines)).astype(int))
        rng = np.random.default_rng(self.seed)
        spec = np.zeros(n // 2 + 1, complex)
        spec[bins] = np.exp(2j * math.pi * rng.random(bins.size))
        x = np.fft.irfft(spec, n)
        x *= self.amplitude_v / math.sqrt(np.mean(x * x))
        return x, bins


@dataclass
class Record:
    tick_hz: float
    u: np.ndarray  # V, command applied over each tick
    y: np.ndarray  # m, encoder position at the start of each tick
    plan: Plan
    segments: dict = field(default_factory=dict)  # name -> (start, stop) ticks
    v_ref: np.ndarray | None = None  # m/s, reference velocity per tick


# trace columns of axis i (sim.h): reference, true table, measured, command
def _cols(i: int) -> tuple[int, int, int, int]:
    return 4 + 4 * i, 5 + 4 * i, 6 + 4 * i, 7 + 4 * i


def _start(m: machine.Machine, feedforward: str = "none") -> None:
    machine.apply(m, feedforward=feedforward)
    r = core.lib().sim_enable(1)
    if r != 0:
        raise ExperimentAborted(f"drive refused enable: {core.DRIVE_RESULT.get(r, r)}")


def _check(rows: np.ndarray, i: int, k0: int, limits: Limits, tick_hz: float) -> None:
    """Stop at the first tick of `rows` (tick k0 on) beyond a limit or
    faulted. Velocity: of the measured (motor encoder) position over
    VEL_TICKS ticks, what the drive sees."""
    _, _, meas, cmd = _cols(i)
    y, u = rows[:, meas], rows[:, cmd]
    vel = np.zeros(y.size)
    vel[VEL_TICKS:] = np.abs(y[VEL_TICKS:] - y[:-VEL_TICKS]) * tick_hz / VEL_TICKS
    checks = [
        (rows[:, 2] != 0, "drive fault", lambda k: core.fault_names(int(rows[k, 2]))),
        (np.abs(y) > limits.travel_m, "travel limit", lambda k: f"{y[k] * 1e3:.3f} mm"),
        (np.abs(u) > limits.command_v, "command limit", lambda k: f"{u[k]:.2f} V"),
        (vel > limits.velocity_m_s, "velocity limit", lambda k: f"{vel[k]:.4f} m/s"),
    ]
    first = None
    for bad, what, val in checks:
        if bad.any():
            k = int(np.argmax(bad))
            if first is None or k < first[0]:
                first = (k, what, val)
    if first is not None:
        k, what, val = first
        raise ExperimentAborted(f"{what} at tick {k0 + k}: {val(k)}")


VEL_TICKS = 4


def _run_checked(ticks, i, k0, limits, tick_hz, chunk) -> np.ndarray:
    """core.run in blocks of `chunk` ticks, each checked with the last
    VEL_TICKS rows of the block before it."""
    out = []
    done = 0
    tail = np.zeros((0, core.lib().sim_trace_cols()))
    while done < ticks:
        rows = core.run(min(chunk, ticks - done))
        _check(np.vstack([tail, rows]), i, k0 + done - tail.shape[0], limits, tick_hz)
        tail = rows[-VEL_TICKS:]
        out.append(rows)
        done += rows.shape[0]
    return np.vstack(out) if out else tail


def simulate(m: machine.Machine, ax: str, plan: Plan, limits: Limits) -> Record:
    """Run the experiment on axis `ax` ("x", "y", "z") of the simulated
    machine `m`, held by the drive's PID with the machine's gains."""
    i = machine.AXES.index(ax)
    t = 1.0 / plan.tick_hz
    if abs(plan.tick_hz - m.tick_hz) > 1e-9:
        raise ExperimentAborted(f"plan at {plan.tick_hz:g} Hz, machine at {m.tick_hz:g} Hz")
    _start(m)
    so = core.lib()
    exc, _ = plan.multisine()
    n_ms = plan.period_ticks * plan.periods
    inj = np.ascontiguousarray(np.tile(exc, plan.periods), dtype=np.float64)
    core.check(so.sim_inject(i, inj.ctypes.data, inj.size), "inject")
    try:
        parts = [_run_checked(n_ms, i, 0, limits, plan.tick_hz, plan.period_ticks)]
    finally:
        so.sim_inject(i, None, 0)
    segments = {"multisine": (0, n_ms)}
    legs = []
    for v in plan.friction_speeds_m_s:
        legs += [v, -v, -v, v]  # out and back twice: ends at the start
    k = n_ms
    pos = 0.0
    for j, v in enumerate(legs):
        pos += v * plan.friction_leg_s
        target = [0, 0, 0]
        target[i] = round(pos * 1e9)
        if core.queue_line(target, round(abs(v) * 1e9), tag=j + 1, exact_stop=True) != 0:
            raise ExperimentAborted(f"drive refused friction leg {j} ({v:+g} m/s)")
        ticks = int(plan.friction_leg_s * plan.tick_hz * 1.5) + int(0.05 * plan.tick_hz)
        rows = _run_checked(ticks, i, k, limits, plan.tick_hz, plan.period_ticks)
        vr = np.diff(rows[:, _cols(i)[0]], append=rows[-1, _cols(i)[0]]) * plan.tick_hz
        steady = np.flatnonzero(np.abs(vr - v) <= 0.02 * abs(v))
        if steady.size < 10:
            raise ExperimentAborted(f"friction leg {j}: no constant-velocity part")
        segments[f"leg{j}:{v:+g}"] = (k + int(steady[0]), k + int(steady[-1]) + 1)
        parts.append(rows)
        k += rows.shape[0]
    rows = np.vstack(parts)
    ref, _, meas, cmd = _cols(i)
    v_ref = np.diff(rows[:, ref], append=rows[-1, ref]) / t
    return Record(
        plan.tick_hz,
        np.ascontiguousarray(rows[:, cmd]),
        np.ascontiguousarray(rows[:, meas]),
        plan,
        segments,
        v_ref,
    )


def simulate_bounded(
    m: machine.Machine, ax: str, plan: Plan, limits: Limits, tries: int = 4
) -> tuple[Record, list[str]]:
    """`simulate`, halving the excitation after each stop at a limit (as
    the host does with the drive): (record, the stops met on the way)."""
    stops = []
    for _ in range(tries):
        try:
            return simulate(m, ax, plan, limits), stops
        except ExperimentAborted as e:
            stops.append(f"{plan.amplitude_v:g} V: {e}")
            plan = replace(plan, amplitude_v=plan.amplitude_v / 2)
    raise ExperimentAborted("; ".join(stops))


def with_axis(m: machine.Machine, ax: str, params: dict | None = None, gains: dict | None = None):
    """Machine `m` with axis `ax`'s parameters and/or PID gains replaced."""
    axis = dict(m.axis)
    g = dict(m.gains)
    if params is not None:
        axis[ax] = dict(params)
    if gains is not None:
        g[ax] = dict(gains)
    return dataclasses.replace(m, axis=axis, gains=g)


def following_error(
    m: machine.Machine, ax: str, gains: dict | None = None, distance_m: float = 0.02, v=0.1
) -> float:
    """Largest |reference - measured position| (m) of the drive over a line
    move of axis `ax` there and back at `v` (the machine's planner limits),
    with 0.1 s of settling after each leg, on the simulated drive: the
    verification job. `gains` (None: the machine's, no feed-forward): kp,
    ki, kd, d_tau, velocity_feedforward (V/(m/s)), acceleration_feedforward
    (V/(m/s^2))."""
    i = machine.AXES.index(ax)
    ff = "none"
    if gains is not None:
        pid = {**m.gains[ax], **{k: gains[k] for k in ("kp", "ki", "kd", "d_tau")}}
        m = dataclasses.replace(
            with_axis(m, ax, gains=pid),
            feedforward={
                "kvff": gains.get("velocity_feedforward", 0.0),
                "kaff": gains.get("acceleration_feedforward", 0.0),
            },
        )
        ff = "full"
    _start(m, ff)
    worst = 0.0
    ref, _, meas, _ = _cols(i)
    for j, target in enumerate((distance_m, 0.0)):
        tgt = [0, 0, 0]
        tgt[i] = round(target * 1e9)
        if core.queue_line(tgt, round(v * 1e9), tag=j + 1, exact_stop=True) != 0:
            raise ExperimentAborted("drive refused the verification move")
        ticks = int((distance_m / v + 0.1 + 0.1) * m.tick_hz)
        rows = core.run(ticks)
        if (rows[:, 2] != 0).any():
            k = int(np.argmax(rows[:, 2] != 0))
            names = core.fault_names(int(rows[k, 2]))
            raise ExperimentAborted(f"verification move faulted: {names}")
        worst = max(worst, float(np.max(np.abs(rows[:, ref] - rows[:, meas]))))
    return worst
