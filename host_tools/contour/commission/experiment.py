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


class Twin:
    """The axis model of dict `p` stepped one tick at a time (see above)."""

    def __init__(self, p: dict, tick_hz: float, substeps: int = 4, seed: int = 1):
        t = 1.0 / tick_hz
        h = t / substeps
        a, b, c1, _ = tuning.plant(p)
        lead = p.get("lead_mm", 5.0) * 1e-3
        self.l = lead / (2 * math.pi)
        bb = np.zeros((5, 3))  # inputs [u, T1 motor side, T2 table side]
        bb[:, 0] = b[:, 0]
        bb[1, 1] = -1.0 / p["I1"]
        bb[3, 2] = -1.0 / p["I2"]
        self.phi, self.gam = tuning.zoh(a, bb, h)
        self.c1 = c1[0]
        self.fc1 = p.get("coulomb_motor", 0.0)
        self.fc2 = p.get("coulomb_table", 0.0) * self.l
        self.m_per_count = lead / (4.0 * p.get("encoder_lines", 1000.0))
        self.noise = p.get("encoder_noise_counts", 0.0)
        self.rng = np.random.default_rng(seed)
        self.umax = p.get("vmax", 160.0) / p["kx"]
        self.substeps = substeps
        self.z = np.zeros(5)

    def encoder(self) -> float:
        """Encoder position, m (quantised, with the reading noise)."""
        c = float(self.c1 @ self.z) / self.m_per_count + 0.5
        if self.noise:
            c += self.noise * self.rng.standard_normal()
        return math.floor(c) * self.m_per_count

    def motor_velocity(self) -> float:
        return float(self.z[1]) * self.l

    def step(self, u: float) -> None:
        uu = max(-self.umax, min(self.umax, u))
        w0 = 0.5  # rad/s, smoothing of the friction law
        for _ in range(self.substeps):
            tin = np.array(
                [uu, self.fc1 * math.tanh(self.z[1] / w0), self.fc2 * math.tanh(self.z[3] / w0)]
            )
            self.z = self.phi @ self.z + self.gam @ tin


def following_error(
    p: dict, gains: dict, tick_hz: float, distance_m=0.02, v=0.1, a=2.0, kv=0.0, ka=0.0
) -> float:
    """Largest |reference - encoder| (m) over a trapezoidal move there and
    back (PID `gains`, feed-forward kv V/(m/s), ka V/(m/s^2)), with 0.1 s
    of settling after each leg: the verification job of the twin."""
    t = 1.0 / tick_hz
    tw = Twin(p, tick_hz)
    pid = _pid(gains, t)
    ta = v / a
    tc = max(0.0, distance_m / v - ta)
    prof = []
    for sign in (1.0, -1.0):
        for k in range(int((2 * ta + tc + 0.1) / t)):
            tt = k * t
            if tt < ta:
                prof.append((sign * a * tt, sign * a))
            elif tt < ta + tc:
                prof.append((sign * v, 0.0))
            elif tt < 2 * ta + tc:
                prof.append((sign * (v - a * (tt - ta - tc)), -sign * a))
            else:
                prof.append((0.0, 0.0))
    ref = 0.0
    worst = 0.0
    for vel, acc in prof:
        e = ref - tw.encoder()
        worst = max(worst, abs(e))
        tw.step(pid(e) + kv * vel + ka * acc)
        ref += vel * t
    return worst


def simulate(p: dict, gains: dict, plan: Plan, limits: Limits, substeps: int = 4) -> Record:
    """Run the experiment on the model of axis dict `p` held by PID `gains`."""
    t = 1.0 / plan.tick_hz
    tw = Twin(p, plan.tick_hz, substeps, plan.seed + 1000)
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

    u_rec = np.zeros(n)
    y_rec = np.zeros(n)
    ref = 0.0
    for k in range(n):
        y = tw.encoder()
        ref += v_ref[k] * t
        u = pid(ref - y) + (exc[k % plan.period_ticks] if k < n_ms else 0.0)
        if abs(y) > limits.travel_m:
            raise ExperimentAborted(f"travel limit at tick {k}: {y * 1e3:.3f} mm")
        if abs(u) > limits.command_v:
            raise ExperimentAborted(f"command limit at tick {k}: {u:.2f} V")
        if abs(tw.motor_velocity()) > limits.velocity_m_s:
            raise ExperimentAborted(f"velocity limit at tick {k}: {tw.motor_velocity():.4f} m/s")
        u_rec[k] = u
        y_rec[k] = y
        tw.step(u)
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
