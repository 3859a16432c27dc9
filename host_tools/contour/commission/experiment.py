"""The excitation experiment of one axis and its record.

Experiment (the drive side is not built yet: `simulate` runs it on the
Python twin of the axis model): the axis is held at rest by its PID; a
periodic multisine (random phases, flat amplitude on `lines` log-spaced
DFT bins from `f_min_hz` to `f_max_hz`) is added to the motor command for `periods`
periods of `period_ticks` ticks, then the axis is moved at +-v1 and +-v2
(constant-velocity legs) for the friction estimate. Every tick records the
motor command u (V at the amplifier input) and the encoder position y
(m, quantised to counts). Limits given by the user bound it: travel (m
either side of the start), command (V), velocity (m/s); `simulate`
checks them and stops the record at the first violation, as the drive
must.

The simulation is the model of axis_model.h in Python: exact zero-order
hold of the linear part (contour.sim.tuning.plant), `substeps` substeps
per tick, Coulomb friction on both sides as a smooth tanh law (not the C
model's stick-slip constraint), Gaussian encoder noise and quantisation.
The command computed at tick k is applied over tick k (tuning.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from contour.sim import tuning


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


def _pid(g: dict, t: float):
    a = t / (g.get("d_tau", 0.0) + t)
    kp, ki, kd = g.get("kp", 0.0), g.get("ki", 0.0), g.get("kd", 0.0)
    st = {"i": 0.0, "e": 0.0, "d": 0.0}

    def step(e: float) -> float:
        st["i"] += ki * t * e
        st["d"] = (1 - a) * st["d"] + a * kd * (e - st["e"]) / t
        st["e"] = e
        return kp * e + st["i"] + st["d"]

    return step


def simulate(p: dict, gains: dict, plan: Plan, limits: Limits, substeps: int = 4) -> Record:
    """Run the experiment on the model of axis dict `p` held by PID `gains`."""
    t = 1.0 / plan.tick_hz
    h = t / substeps
    a, b, c1, _ = tuning.plant(p)
    lead = p.get("lead_mm", 5.0) * 1e-3
    l_ = lead / (2 * math.pi)
    # inputs [u, T1 (motor side torque), T2 (table side torque)]
    bb = np.zeros((5, 3))
    bb[:, 0] = b[:, 0]
    bb[1, 1] = -1.0 / p["I1"]
    bb[3, 2] = -1.0 / p["I2"]
    phi, gam = tuning.zoh(a, bb, h)
    fc1 = p.get("coulomb_motor", 0.0)
    fc2 = p.get("coulomb_table", 0.0) * l_
    cpr = 4.0 * p.get("encoder_lines", 1000.0)
    m_per_count = lead / cpr
    noise = p.get("encoder_noise_counts", 0.0)
    rng = np.random.default_rng(plan.seed + 1000)
    vmax = p.get("vmax", 160.0) / p["kx"]
    pid = _pid(gains, t)

    exc, _ = plan.multisine()
    n_ms = plan.period_ticks * plan.periods
    legs = []
    for v in plan.friction_speeds_m_s:
        legs += [v, -v, -v, v]  # out and back twice: ends at the start
    n_leg = int(plan.friction_leg_s * plan.tick_hz)
    n = n_ms + n_leg * len(legs)
    v_ref = np.zeros(n)
    v_ref[n_ms:] = np.repeat(legs, n_leg)
    segments = {"multisine": (0, n_ms)}
    for i, v in enumerate(legs):
        segments[f"leg{i}:{v:+g}"] = (n_ms + i * n_leg, n_ms + (i + 1) * n_leg)

    z = np.zeros(5)
    u_rec = np.zeros(n)
    y_rec = np.zeros(n)
    ref = 0.0
    w0 = 0.5  # rad/s, smoothing of the friction law
    for k in range(n):
        pos = float(c1[0] @ z)
        reading = pos / m_per_count + 0.5 + (noise * rng.standard_normal() if noise else 0.0)
        y = math.floor(reading) * m_per_count
        ref += v_ref[k] * t
        u = pid(ref - y) + (exc[k % plan.period_ticks] if k < n_ms else 0.0)
        if abs(y) > limits.travel_m:
            raise ExperimentAborted(f"travel limit at tick {k}: {y * 1e3:.3f} mm")
        if abs(u) > limits.command_v:
            raise ExperimentAborted(f"command limit at tick {k}: {u:.2f} V")
        if abs(z[1] * l_) > limits.velocity_m_s:
            raise ExperimentAborted(f"velocity limit at tick {k}: {z[1] * l_:.4f} m/s")
        u_rec[k] = u
        y_rec[k] = y
        uu = max(-vmax, min(vmax, u))
        for _ in range(substeps):
            tin = np.array([uu, fc1 * math.tanh(z[1] / w0), fc2 * math.tanh(z[3] / w0)])
            z = phi @ z + gam @ tin
    return Record(plan.tick_hz, u_rec, y_rec, plan, segments, v_ref)


def simulate_bounded(
    p: dict, gains: dict, plan: Plan, limits: Limits, tries: int = 4, **kw
) -> tuple[Record, list[str]]:
    """`simulate`, halving the excitation after each stop at a limit (as
    the host does with the drive): (record, the stops met on the way)."""
    stops = []
    for _ in range(tries):
        try:
            return simulate(p, gains, plan, limits, **kw), stops
        except ExperimentAborted as e:
            stops.append(f"{plan.amplitude_v:g} V: {e}")
            plan = replace(plan, amplitude_v=plan.amplitude_v / 2)
    raise ExperimentAborted("; ".join(stops))
