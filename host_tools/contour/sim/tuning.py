"""Frequency-domain robustness of the loop gains (the analysis behind the
shipped gain sets; docs/simulator.md).

Loop model, per axis: the axis model of the machine file from the amplifier
command u (V at the amplifier input) to the motor encoder position l th1 (m),
discretised exactly (zero-order hold) at the control tick, in series with
the firmware's discrete PID (pid.h):

    C(z) = Kp + Ki T z / (z - 1) + Kd a (z - 1) / (T (z - (1 - a))),
    a = T / (tau + T)

(backward-Euler integral, derivative filtered by a first-order lag of time
constant tau). The command computed at a tick is applied over the next tick
(zero-order hold, no extra delay), as in the simulator.

The contour-error controller adds its output along the path normal; with the
geometry frozen (the path turns at v / R = 8 rad/s at R 20 mm, 10 m/min, well
below the ~150 rad/s crossover) the normal direction of each axis sees the
sum C_axis + C_cec. Both loops (axis alone: the tangential direction; axis +
CEC: the normal) are checked on both plants (X and Y tables):

- closed-loop stability: spectral radius of the closed-loop state matrix
  (plant + controller states) below 1;
- sensitivity peak Ms = max |1 / (1 + L(e^{jwT}))| over a log grid with dense
  points around the table mode (the mode is so lightly damped, zeta ~ 5e-4,
  that a coarse grid misses it); shipped sets have Ms <= 2;
- gain margin (dB), phase margin (deg) and crossover (rad/s) for reference.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def expm(m: np.ndarray) -> np.ndarray:
    """Matrix exponential: scaling and squaring of a Taylor series."""
    nrm = float(np.abs(m).sum(axis=1).max())
    s = max(0, int(math.ceil(math.log2(nrm / 0.25)))) if nrm > 0 else 0
    a = m / (2.0**s)
    out = np.eye(m.shape[0])
    term = np.eye(m.shape[0])
    for k in range(1, 21):
        term = term @ a / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out


def plant(p: dict, lead_mm: float | None = None):
    """Continuous (A, B, C_motor, C_table) of an axis parameter dict."""
    lead = (lead_mm if lead_mm is not None else p.get("lead_mm", 5.0)) * 1e-3
    l = lead / (2 * math.pi)  # noqa: E741
    K, B, I1, I2 = p["K"], p["B"], p["I1"], p["I2"]
    a = np.zeros((5, 5))
    a[0, 1] = 1.0
    a[1] = [-K / I1, -B / I1, K / I1, B / I1, p["kt"] / I1]
    a[2, 3] = 1.0
    a[3] = [K / I2, B / I2, -K / I2, -B / I2, 0.0]
    a[4] = [0.0, -p["kb"] / p["La"], 0.0, 0.0, -p["Ra"] / p["La"]]
    b = np.zeros((5, 1))
    b[4, 0] = p["kx"] / p["La"]
    c1 = np.array([[l, 0, 0, 0, 0.0]])
    c2 = np.array([[0, 0, l, 0, 0.0]])
    return a, b, c1, c2


def zoh(a: np.ndarray, b: np.ndarray, t: float):
    n, m = a.shape[0], b.shape[1]
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = a
    aug[:n, n:] = b
    e = expm(aug * t)
    return e[:n, :n], e[:n, n:]


def zoh_mean(a: np.ndarray, b: np.ndarray, c: np.ndarray, t: float):
    """The plant sampled as the drive's mean measurement (drive.h enc_mean):
    the output at tick k is the mean of c x over the tick before it,
    c (Phi1 x_{k-1} + Gam1 u_{k-1}) with Phi1 = (1/T) int_0^T e^{A s} ds and
    Gam1 likewise for the held input. As a state-space model without
    feed-through: state [x; m], m_{k+1} = c Phi1 x_k + c Gam1 u_k, output m.
    Returns (phi, gam, c) of that model."""
    n, m = a.shape[0], b.shape[1]
    k = n + m
    aug = np.zeros((2 * k, 2 * k))
    aug[:n, :n] = a
    aug[:n, n:k] = b
    aug[:k, k:] = np.eye(k)
    e = expm(aug * t)
    phi, gam = e[:n, :n], e[:n, n:k]
    integ = e[:k, k:] / t  # (1/T) int_0^T e^{M s} ds, M = [[A, B], [0, 0]]
    phi1, gam1 = integ[:n, :n], integ[:n, n:k]
    pa = np.zeros((n + 1, n + 1))
    pa[:n, :n] = phi
    pa[n, :n] = (c @ phi1)[0]
    ga = np.zeros((n + 1, m))
    ga[:n] = gam
    ga[n] = (c @ gam1)[0]
    ca = np.zeros((1, n + 1))
    ca[0, n] = 1.0
    return pa, ga, ca


def eigenvalues(p: dict) -> np.ndarray:
    return np.sort_complex(np.linalg.eigvals(plant(p)[0]))


def frd(phi, gam, c, z):
    n = phi.shape[0]
    eye = np.eye(n)
    return np.array([(c @ np.linalg.solve(zz * eye - phi, gam))[0, 0] for zz in z])


def pid_z(g: dict, t: float, z):
    a = t / (g.get("d_tau", 0.0) + t)
    return (
        g.get("kp", 0.0)
        + g.get("ki", 0.0) * t * z / (z - 1)
        + g.get("kd", 0.0) * a * (z - 1) / (t * (z - (1 - a)))
    )


def ctrl_ss(gains: list, t: float):
    """(Ac, Bc, Cc, Dc) of a sum of PIDs sharing the error: states
    [I_prev, e_prev, D_1 ... D_k] (one integrator: parallel integrators on
    the same error would add a redundant mode at z = 1)."""
    k = len(gains)
    n = 2 + k
    ac = np.zeros((n, n))
    bc = np.zeros(n)
    cc = np.zeros(n)
    ki = sum(g.get("ki", 0.0) for g in gains) * t
    dc = sum(g.get("kp", 0.0) for g in gains) + ki
    ac[0, 0] = 1.0
    bc[0] = ki
    cc[0] = 1.0
    bc[1] = 1.0  # e_prev <- e
    for i, g in enumerate(gains):
        a = t / (g.get("d_tau", 0.0) + t)
        kd = a * g.get("kd", 0.0) / t
        j = 2 + i
        ac[j, j] = 1 - a
        ac[j, 1] = -kd
        bc[j] = kd
        cc[j] = 1 - a
        cc[1] += -kd
        dc += kd
    return ac, bc, cc, dc


def spectral_radius(phi, gam, c, ctrls: list, t: float) -> float:
    n = phi.shape[0]
    ac, bc, cc, dc = ctrl_ss(ctrls, t)
    k = ac.shape[0]
    m = np.zeros((n + k, n + k))
    cv, gv = c[0], gam[:, 0]
    m[:n, :n] = phi - np.outer(gv, dc * cv)
    m[:n, n:] = np.outer(gv, cc)
    m[n:, :n] = -np.outer(bc, cv)
    m[n:, n:] = ac
    return float(np.abs(np.linalg.eigvals(m)).max())


def freq_grid(t: float, modes=()) -> np.ndarray:
    nyq = math.pi / t
    w = list(np.logspace(-1, math.log10(nyq * 0.999), 3000))
    for wr in modes:
        w += list(np.linspace(wr * 0.97, wr * 1.03, 800))
    return np.array(sorted(x for x in w if 0 < x < nyq))


@dataclass
class Margins:
    stable: bool
    rho: float
    ms: float
    gm_db: float
    pm_deg: float
    wc: float

    def as_dict(self) -> dict:
        return {
            "stable": self.stable,
            "spectral_radius": round(self.rho, 7),
            "sensitivity_peak": round(self.ms, 3),
            "gain_margin_db": round(self.gm_db, 2),
            "phase_margin_deg": round(self.pm_deg, 1),
            "crossover_rad_s": round(self.wc, 1),
        }


class Loop:
    """One axis plant at one tick rate, ready to evaluate gain sets."""

    def __init__(self, p: dict, tick_hz: float, mean: bool = False):
        """mean: the loop measures the encoder's mean over the tick (drive.h
        enc_mean: half a tick more delay, the boxcar's notches) instead of
        its sample."""
        self.t = 1.0 / tick_hz
        a, b, c1, _ = plant(p)
        if mean:
            self.phi, self.gam, self.c1 = zoh_mean(a, b, c1, self.t)
        else:
            self.phi, self.gam = zoh(a, b, self.t)
            self.c1 = c1
        modes = [abs(e.imag) for e in np.linalg.eigvals(a) if abs(e.imag) > 1]
        anti = math.sqrt(p["K"] / p["I2"])
        self.w = freq_grid(self.t, modes + [anti])
        self.z = np.exp(1j * self.w * self.t)
        self.p = frd(self.phi, self.gam, self.c1, self.z)

    def margins(self, *gains: dict) -> Margins:
        c = sum(pid_z(g, self.t, self.z) for g in gains)
        loop = c * self.p
        rho = spectral_radius(self.phi, self.gam, self.c1, list(gains), self.t)
        ms = float(np.abs(1 / (1 + loop)).max())
        mag = np.abs(loop)
        ph = np.unwrap(np.angle(loop))
        # crossover: first |L| = 1 from above
        idx = np.nonzero((mag[:-1] >= 1) & (mag[1:] < 1))[0]
        if idx.size:
            i = idx[0]
            wc = float(self.w[i])
            pm = float((math.degrees(ph[i]) + 180.0) % 360.0)
            if pm > 180:
                pm -= 360
        else:
            wc, pm = float("nan"), float("nan")
        # gain margin: |L| where the phase crosses -180 (mod 360), smallest margin
        gm = float("inf")
        wrapped = (np.degrees(ph) + 180.0) % 360.0 - 180.0
        cross = np.nonzero(np.abs(np.diff(np.sign(wrapped))) > 0)[0]
        for i in cross:
            if abs(wrapped[i]) > 90 or mag[i] <= 0 or not self.w[i] > wc:
                continue
            gm = min(gm, -20 * math.log10(mag[i]))
        return Margins(rho < 1.0, rho, ms, gm, pm, wc)


def machine_margins(m, tick_hz: float | None = None, mean: bool | None = None) -> dict:
    """Margins of every shipped loop of machine `m` (contour.sim.machine);
    mean: the mean measurement (default: as the machine's [servo]
    encoder_mean)."""
    hz = tick_hz or m.tick_hz
    if mean is None:
        mean = bool(m.servo.get("encoder_mean", 0))
    out = {}
    for ax in ("x", "y"):
        if ax not in m.axis:
            continue
        loop = Loop(m.axis[ax], hz, mean)
        g = m.gains[ax]
        out[f"axis_{ax}"] = loop.margins(g).as_dict()
        out[f"axis_{ax}+cec"] = loop.margins(g, m.gains["cec"]).as_dict()
    return out
