"""Gains from an identified axis model (identify.Identification).

Loop: the identified model (command V -> motor position m), discretised
exactly by zero-order hold at the drive's tick, in series with the
firmware's discrete PID (tuning.pid_z: backward-Euler integral, derivative
filtered with time constant `d_tau`, which is not a drive parameter and is
taken as given). The margins are those of contour.sim.tuning.Loop:
spectral radius of the closed loop (stability), sensitivity peak Ms,
gain and phase margins.

Methods:
- "robust" (default): maximise the integral gain Ki (the load-disturbance
  rejection, hence the following error under friction and cutting force)
  subject to Ms <= `ms_target` and a stable discrete loop, by Nelder-Mead
  simplex on log(Kp, Ki, Kd) with a penalty for the constraints
  (Astrom-Hagglund's MIGO design done numerically), started from the
  feasible PID of largest Ki on a coarse grid below the Ziegler-Nichols
  gains (Kp from ZN/1000 to ZN, Ti of Tu/2 .. 2048 Tu, Td 0 or Tu/8).
- "zn": Ziegler-Nichols from the ultimate gain Ku (proportional gain at
  which the sampled loop reaches the stability boundary) and period Tu:
  Kp = 0.6 Ku, Ki = Kp / (Tu / 2), Kd = Kp Tu / 8.

Feed-forward (drive parameters velocity_feedforward, V/(m/s), and
acceleration_feedforward, V/(m/s^2)): the inverse of the model's low
frequency part k / (s (1 + s/p1) (1 + s/p2)): kv = 1 / k,
ka = (1/p1 + 1/p2) / k.

The constraints hold on the identified model and on the same model with
the table mode's damping ratios at LIGHT_ZETA (friction damps the mode at
the experiment's small amplitudes, so the record overstates its damping;
the default X table's mode has zeta 8e-5); the margins reported are the
worse of the two.

Before any result is returned the closed loop is checked: a method whose
gains leave the loop unstable raises TuneError (nothing is written).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from contour.sim import tuning

from . import identify as idf

LIGHT_ZETA = 5e-5  # damping ratio of the table mode in the worst-case model
# the identified damping over the true one where its interval was tight
# (commission_xy Y: 2.19e-3 / 1.08e-3, X 4.94e-3 / 3.97e-3): the design
# holds on the identified ratio / ZETA_BIAS
ZETA_BIAS = 4.0


class TuneError(ValueError):
    pass


@dataclass
class Tuned:
    method: str
    gains: dict  # kp, ki, kd, d_tau, velocity_feedforward, acceleration_feedforward
    margins: tuning.Margins
    ms_target: float
    ku: float
    tu_s: float

    def as_dict(self) -> dict:
        m = self.margins.as_dict()
        return {
            "method": self.method,
            "gains": {k: float(f"{v:.6g}") for k, v in self.gains.items()},
            "phase_margin_deg": m["phase_margin_deg"],
            "gain_margin_db": m["gain_margin_db"],
            "sensitivity_peak": m["sensitivity_peak"],
            "ms_target": self.ms_target,
            "spectral_radius": m["spectral_radius"],
            "stable": m["stable"],
            "ultimate_gain": float(f"{self.ku:.6g}"),
            "ultimate_period_s": float(f"{self.tu_s:.6g}"),
        }


def worst_zeta(ident: idf.Identification) -> dict | None:
    """Damping ratios of the worst-case model (None: rigid model): per
    ratio (zr, za), the identified value / ZETA_BIAS when its 95 % interval
    is tighter than half the value, else LIGHT_ZETA; never above the
    identified value nor below LIGHT_ZETA."""
    if ident.fit.model != "two_inertia":
        return None
    out = {}
    for k in ("zr", "za"):
        v = float(ident.fit.params[k])
        ci = ident.fit.ci95.get(k)
        tight = ci is not None and math.isfinite(ci) and v > 0 and ci < v / 2
        out[k] = max(LIGHT_ZETA, v / ZETA_BIAS) if tight else LIGHT_ZETA
        out[k] = min(out[k], max(v, LIGHT_ZETA))
    return out


def model_loop(
    ident: idf.Identification, tick_hz: float, zeta: float | dict | None = None
) -> tuning.Loop:
    """tuning.Loop of the identified model (the margins machinery of the
    shipped gain sets, on the model instead of the machine file); `zeta`
    replaces the damping ratios of the resonance and anti-resonance (a
    number: both; a dict: {"zr", "za"}, worst_zeta)."""
    theta, model = dict(ident.fit.params), ident.fit.model
    if zeta is not None and model == "two_inertia":
        if isinstance(zeta, dict):
            theta.update(zeta)
        else:
            theta["zr"] = theta["za"] = zeta
    a, b, c = idf._series_ss(theta, model)
    loop = tuning.Loop.__new__(tuning.Loop)
    loop.t = 1.0 / tick_hz
    loop.phi, loop.gam = tuning.zoh(a, b[:, None], loop.t)
    loop.c1 = c[None, :]
    modes = [theta[k] for k in ("wr", "wa") if k in theta]
    w = tuning.freq_grid(loop.t, modes)
    # +-0.5 % of each mode at 1e-5 spacing: resolves a peak of zeta 5e-5
    fine = [np.linspace(wm * 0.995, wm * 1.005, 1001) for wm in modes]
    w = np.unique(np.concatenate([w, *fine]))
    loop.w = w[w < math.pi / loop.t]
    loop.z = np.exp(1j * loop.w * loop.t)
    loop.p = tuning.frd(loop.phi, loop.gam, loop.c1, loop.z)
    return loop


def ultimate(loop: tuning.Loop) -> tuple[float, float]:
    """(Ku, Tu): the proportional gain at which the sampled loop reaches the
    stability boundary (the smallest 1 / |P| where the phase of P crosses
    -180 deg) and the period of that crossing."""
    ph = np.degrees(np.unwrap(np.angle(loop.p)))
    wrapped = ph % 360.0 - 180.0  # 0 where the phase is -180 (mod 360)
    cross = np.nonzero((np.abs(np.diff(np.sign(wrapped))) > 0) & (np.abs(wrapped[:-1]) < 90))[0]
    if cross.size == 0:
        raise TuneError("the model's phase never reaches -180 deg below the Nyquist frequency")
    mags = np.abs(loop.p[cross])
    i = int(cross[np.argmax(mags)])
    return 1.0 / float(np.abs(loop.p[i])), 2 * math.pi / float(loop.w[i])


def gain_margin_db(loop: tuning.Loop, g: dict, wc: float) -> float:
    """Smallest -20 log10 |L| where the phase of L crosses -180 deg (mod
    360) above the crossover wc (rad/s; a crossing below it, where the
    double integrator puts the phase near -180, bounds a gain reduction,
    not an increase); inf when there is none below the Nyquist frequency."""
    lw = tuning.pid_z(g, loop.t, loop.z) * loop.p
    ph = np.degrees(np.unwrap(np.angle(lw)))
    wrapped = ph % 360.0 - 180.0
    cross = np.nonzero(
        (np.abs(np.diff(np.sign(wrapped))) > 0) & (np.abs(wrapped[:-1]) < 90) & (loop.w[:-1] > wc)
    )[0]
    if cross.size == 0:
        return math.inf
    return float(min(-20 * math.log10(abs(lw[i])) for i in cross))


def _nelder_mead(fun, x0, step=0.3, iters=400, tol=1e-6):
    n = len(x0)
    pts = [np.array(x0, float)]
    for i in range(n):
        x = np.array(x0, float)
        x[i] += step
        pts.append(x)
    vals = [fun(p) for p in pts]
    for _ in range(iters):
        order = np.argsort(vals)
        pts = [pts[i] for i in order]
        vals = [vals[i] for i in order]
        if abs(vals[-1] - vals[0]) < tol and np.max(np.abs(pts[-1] - pts[0])) < tol:
            break
        c = np.mean(pts[:-1], axis=0)
        xr = c + (c - pts[-1])
        fr = fun(xr)
        if fr < vals[0]:
            xe = c + 2 * (c - pts[-1])
            fe = fun(xe)
            pts[-1], vals[-1] = (xe, fe) if fe < fr else (xr, fr)
        elif fr < vals[-2]:
            pts[-1], vals[-1] = xr, fr
        else:
            xc = c + 0.5 * (pts[-1] - c)
            fc = fun(xc)
            if fc < vals[-1]:
                pts[-1], vals[-1] = xc, fc
            else:
                for i in range(1, n + 1):
                    pts[i] = pts[0] + 0.5 * (pts[i] - pts[0])
                    vals[i] = fun(pts[i])
    i = int(np.argmin(vals))
    return pts[i], vals[i]


# the thesis's simplex tuning: a 10 mm circle at 10 m/min (lacerda1998.md)
SIMPLEX_R_M = 0.010
SIMPLEX_V_M_S = 10.0 / 60
SIMPLEX_V_EPS = 1e-4  # m/s: the Coulomb sign smoothed over +-0.1 mm/s


def circle_iae(
    ident: idf.Identification, tick_hz: float, g: dict, ff: dict, friction_v: float = 0.0
) -> float:
    """The simplex method's criterion: the integral of the absolute
    following error (IAE, m s) of one axis of the thesis's circle (R 10 mm
    at 10 m/min: x_ref = R (cos wt - 1), one revolution from rest) on the
    identified model's sampled loop (ZOH plant at the tick, the firmware's
    PID `g`, velocity and acceleration feed-forward `ff`), with the
    identified Coulomb friction `friction_v` (V, smoothed over
    +-SIMPLEX_V_EPS of motor velocity) acting on the command and no
    friction feed-forward (the drive's follows the reference and is decided
    by the verification). The thesis scored the circle's contour error;
    per axis, with both axes alike, that is this axis's error."""
    theta, model = ident.fit.params, ident.fit.model
    a, b, c = idf._series_ss(theta, model)
    t = 1.0 / tick_hz
    phi, gam = tuning.zoh(a, b[:, None], t)
    gam = gam[:, 0]
    ac, bc, cc, dc = tuning.ctrl_ss([{k: g[k] for k in ("kp", "ki", "kd", "d_tau")}], t)
    n, k = phi.shape[0], ac.shape[0]
    m = np.zeros((n + k, n + k))
    m[:n, :n] = phi - dc * np.outer(gam, c)
    m[:n, n:] = np.outer(gam, cc)
    m[n:, :n] = -np.outer(bc, c)
    m[n:, n:] = ac
    br = np.concatenate([dc * gam, bc])
    bu = np.concatenate([gam, np.zeros(k)])
    cv = np.concatenate([c @ a, np.zeros(k)])  # motor velocity (c b = 0)
    cy = np.concatenate([c, np.zeros(k)])
    w = SIMPLEX_V_M_S / SIMPLEX_R_M
    steps = int(round(2 * math.pi / w * tick_hz))
    tt = np.arange(steps) * t
    r = SIMPLEX_R_M * (np.cos(w * tt) - 1)
    uff = ff.get("velocity_feedforward", 0.0) * (-SIMPLEX_R_M * w * np.sin(w * tt))
    uff = uff + ff.get("acceleration_feedforward", 0.0) * (-SIMPLEX_R_M * w * w * np.cos(w * tt))
    x = np.zeros(n + k)
    iae = 0.0
    for j in range(steps):
        iae += abs(r[j] - cy @ x)
        u = uff[j]
        if friction_v:
            u -= friction_v * math.tanh((cv @ x) / SIMPLEX_V_EPS)
        x = m @ x + br * r[j] + bu * u
        if not abs(x[n - 1]) < 1.0:  # diverged: one metre off a 10 mm circle
            return math.inf
    return iae * t


def feedforward(ident: idf.Identification) -> dict:
    th = ident.fit.params
    k = th["k"]
    return {
        "velocity_feedforward": 1.0 / k,
        "acceleration_feedforward": (1.0 / th["p1"] + 1.0 / th["p2"]) / k,
    }


def _simplex(ident, tick_hz: float, ms_target: float, d_tau: float, worst) -> dict:
    """The thesis's procedure: Nelder-Mead on log(Kp, Ki, Kd) minimising
    circle_iae (with the identified friction), the same Ms and stability
    constraints as robust as a penalty, started from the robust design
    (a feasible point; the thesis started from a hand-tuned set)."""
    ff = feedforward(ident)
    f = getattr(ident, "friction_v", None)
    f = float(f) if f is not None and f > 0 else 0.0
    start = tune(ident, tick_hz, "robust", ms_target, d_tau).gains

    def objective(x, g):
        iae = circle_iae(ident, tick_hz, g, ff, f)
        return math.log(iae) if math.isfinite(iae) else None

    cost = _penalised_cost(objective, worst, ms_target, d_tau)
    x0 = np.log([start["kp"], start["ki"], max(start["kd"], start["kp"] * 1e-4)])
    best, _ = _nelder_mead(cost, x0, step=0.3, iters=150, tol=1e-4)
    best, _ = _nelder_mead(cost, best, step=0.1, iters=100, tol=1e-4)
    return _gains_of(best, d_tau)


def _gains_of(x, d_tau: float) -> dict:
    """PID gains from the search variables log(Kp, Ki, Kd)."""
    kp, ki, kd = (math.exp(v) for v in x)
    return {"kp": kp, "ki": ki, "kd": kd, "d_tau": d_tau}


def _penalised_cost(objective, worst, ms_target: float, d_tau: float):
    """The search cost of robust and simplex: unstable gains cost 1e6 plus
    their spectral radius, an Ms above the target a steep penalty, and
    objective(x, gains) the rest (None: a failed evaluation, 1e5)."""

    def cost(x):
        g = _gains_of(x, d_tau)
        m = worst(g)
        if not m.stable:
            return 1e6 + m.rho
        excess = max(0.0, m.ms - ms_target)
        v = objective(x, g)
        if v is None:
            return 1e5
        return v + 1e3 * excess * excess + 10 * excess

    return cost


def tune(
    ident: idf.Identification,
    tick_hz: float,
    method: str = "robust",
    ms_target: float = 1.6,
    d_tau: float = 1e-3,
) -> Tuned:
    loop = model_loop(ident, tick_hz)
    # friction damps the table mode in the record (at the experiment's small
    # amplitudes it acts like viscous damping), so the identified damping is
    # an upper bound: the design must also hold on the undamped mode
    loops = [loop]
    if ident.fit.model == "two_inertia":
        loops.append(model_loop(ident, tick_hz, zeta=worst_zeta(ident)))

    def worst(g):
        ms = [lp.margins(g) for lp in loops]
        if not all(m.stable for m in ms):
            return next(m for m in ms if not m.stable)
        return max(ms, key=lambda m: m.ms)

    ku, tu = ultimate(loop)
    zn = {"kp": 0.6 * ku, "ki": 0.6 * ku / (tu / 2), "kd": 0.6 * ku * tu / 8, "d_tau": d_tau}
    if method == "zn":
        g = zn
    elif method == "robust":
        cost = _penalised_cost(lambda x, g: -x[1], worst, ms_target, d_tau)  # largest Ki

        # a feasible start: the largest-Ki PID of a coarse family below ZN
        x0, best_ki = None, -math.inf
        for kp in np.geomspace(zn["kp"] / 1000, zn["kp"], 16):
            for ti in tu * 4.0 ** np.arange(-0.5, 6.0):
                for td in (0.0, tu / 8):
                    x = np.log([kp, kp / ti, max(kp * td, 1e-12)])
                    m = worst(_gains_of(x, d_tau))
                    if m.stable and m.ms <= ms_target and x[1] > best_ki:
                        x0, best_ki = x, x[1]
        if x0 is None:
            raise TuneError(f"robust: no stable start with Ms <= {ms_target}")
        best, _ = _nelder_mead(cost, x0)
        for _ in range(2):  # restarts: NM stalls on the penalty's kink
            best, _ = _nelder_mead(cost, best, step=0.1)
        g = _gains_of(best, d_tau)
    elif method == "simplex":
        g = _simplex(ident, tick_hz, ms_target, d_tau, worst)
    else:
        raise TuneError(f"unknown method {method!r} (robust, zn, simplex)")
    if g["kd"] < 1e-9:  # the simplex drove it to nothing: say so
        g["kd"] = 0.0
    m = worst(g)
    m.gm_db = min(gain_margin_db(lp, g, lp.margins(g).wc) for lp in loops)
    if not m.stable:
        raise TuneError(
            f"{method}: the discretised closed loop is unstable (spectral radius {m.rho:.6f})"
        )
    if method in ("robust", "simplex") and m.ms > ms_target * 1.02:
        raise TuneError(f"{method}: no stable gains meet Ms <= {ms_target} (best {m.ms:.2f})")
    out = dict(g)
    out.update(feedforward(ident))
    f = getattr(ident, "friction_v", None)
    out["friction_ff_v"] = float(f) if f is not None and f > 0 else 0.0
    return Tuned(method, out, m, ms_target, ku, tu)


# ---- the contour-error controller ---------------------------------------------------

CEC_ALPHAS = tuple(2.0 ** (-k / 2) for k in range(9))  # 1 .. 1/16
CEC_THETAS_DEG = tuple(range(0, 91, 5))


@dataclass
class CecTuned:
    gains: dict  # kp, ki, kd, d_tau of the CEC's PID (cec.h), SI as the axis gains
    alpha: float  # CEC = alpha x the slower axis's PID (0: none passed)
    slower_axis: str
    ms: float  # worst sensitivity peak of an axis loop with the CEC along its normal
    rho: float  # worst spectral radius of the coupled loop over the normals
    ms_limit: float
    reason: str = ""

    def as_dict(self) -> dict:
        return {
            "gains": {k: float(f"{v:.6g}") for k, v in self.gains.items()},
            "alpha": round(self.alpha, 4),
            "slower_axis": self.slower_axis.upper(),
            "sensitivity_peak": round(self.ms, 3),
            "ms_limit": self.ms_limit,
            "coupled_spectral_radius": round(self.rho, 7),
            "stable": self.rho < 1.0,
            "reason": self.reason,
        }


def coupled_radius(loops: list, axis_gains: list, cec: dict, normal) -> float:
    """Spectral radius of the sampled closed loop of the axes (plants
    loops[i], PIDs axis_gains[i]) with the CEC's PID on the contour error
    eps = n . E (the tangent estimate, cec.h) and its output added to the
    axes along the normal n: u_i = C_i(E_i) + n_i C_cec(eps). Reference 0
    (E = -y): the loop the CEC closes through both axes. The CEC's integral
    n_i Ki_cec sum(eps) is carried in the axis integrators (tuning.ctrl_ss's
    state 0): with a state of its own, three integrators on a 2-D error
    leave a mode at z = 1 that no input or output sees."""
    t = loops[0].t
    parts = []  # (plant offset, plant order, ctrl offset, ctrl ss)
    off = 0
    for lp, g in zip(loops, axis_gains):
        ss = tuning.ctrl_ss([{k: g[k] for k in ("kp", "ki", "kd", "d_tau")}], t)
        n_p = lp.phi.shape[0]
        parts.append((off, n_p, off + n_p, ss))
        off += n_p + ss[0].shape[0]
    acc, bcc, ccc, dcc = tuning.ctrl_ss([{**cec, "ki": 0.0}], t)
    acc, bcc, ccc = acc[1:, 1:], bcc[1:], ccc[1:]  # without its (unused) integrator
    ki_t = cec.get("ki", 0.0) * t
    oc = off
    size = off + acc.shape[0]
    # e_i = -c_i x_i as rows over the whole state
    e_rows = []
    for (po, n_p, _, _), lp in zip(parts, loops):
        r = np.zeros(size)
        r[po : po + n_p] = -lp.c1[0]
        e_rows.append(r)
    eps = sum(ni * r for ni, r in zip(normal, e_rows))
    m = np.zeros((size, size))
    for i, ((po, n_p, co, (ac, bc, cc, dc)), lp) in enumerate(zip(parts, loops)):
        u = dc * e_rows[i] + normal[i] * ((dcc + ki_t) * eps)
        u[co : co + ac.shape[0]] += cc
        u[oc:] += normal[i] * ccc
        g = lp.gam[:, 0]
        m[po : po + n_p] += np.outer(g, u)
        m[po : po + n_p, po : po + n_p] += lp.phi
        m[co : co + ac.shape[0], co : co + ac.shape[0]] = ac
        m[co : co + ac.shape[0]] += np.outer(bc, e_rows[i])
        m[co] += normal[i] * ki_t * eps  # the CEC's integral, in the axis integrator
    m[oc:, oc:] = acc
    m[oc:] += np.outer(bcc, eps)
    return float(np.abs(np.linalg.eigvals(m)).max())


def tune_cec(axes: dict, ms_limit: float = 2.0, d_tau: float = 1e-3) -> CecTuned:
    """CEC gains from the tuned axes {name: (loops, gains)} (loops: the
    identified model's, and its light-damping variant, model_loop): the
    CEC's PD is alpha times the Kp and Kd of the slower axis (lower
    crossover), with no integral (the axis integrators remove a steady
    contour error; a CEC integral on the turning normal of a circle winds up
    at the quadrant glitches: on commission_xy R10 F6000, 1/4 of X's PI
    took the max contour error from 77 to 90 um, 1/4 of its P to 76 um),
    alpha the largest of CEC_ALPHAS (1 .. 1/16) for which (1) every axis
    loop with the CEC along its own direction (the normal on a path across
    the other axis: the CEC's output adds to that axis's PID) keeps
    Ms <= ms_limit and (2) the coupled sampled loop of two axes
    (coupled_radius) is stable for every normal 0 .. 90 deg (5 deg steps)
    on every model variant. Above the integrators' corner the CEC raises
    the loop gain on the contour error by up to 1 + alpha. No alpha passes:
    zero gains and the reason."""
    names = list(axes)
    wc = {a: axes[a][0][0].margins(axes[a][1]).wc for a in names}
    slow = min(names, key=lambda a: wc[a] if math.isfinite(wc[a]) else math.inf)
    base = axes[slow][1]
    worst_ms = worst_rho = math.inf
    for alpha in CEC_ALPHAS:
        cec = {"kp": alpha * base["kp"], "ki": 0.0, "kd": alpha * base["kd"]}
        cec["d_tau"] = d_tau
        ms = rho = 0.0
        ok = True
        for a in names:
            for lp in axes[a][0]:
                m = lp.margins(axes[a][1], cec)
                ms, rho = max(ms, m.ms), max(rho, m.rho)
                ok = ok and m.stable and m.ms <= ms_limit
        if ok and len(names) >= 2:
            pair = names[:2]
            for k in range(len(axes[pair[0]][0])):
                lps = [axes[a][0][min(k, len(axes[a][0]) - 1)] for a in pair]
                gs = [axes[a][1] for a in pair]
                for th in CEC_THETAS_DEG:
                    n = (math.cos(math.radians(th)), math.sin(math.radians(th)))
                    rho = max(rho, coupled_radius(lps, gs, cec, n))
            ok = rho < 1.0
        if ok:
            return CecTuned(cec, alpha, slow, ms, rho, ms_limit)
        worst_ms, worst_rho = ms, rho
    zero = {"kp": 0.0, "ki": 0.0, "kd": 0.0, "d_tau": d_tau}
    why = (
        f"no CEC gain down to {CEC_ALPHAS[-1]:.4g} x the {slow.upper()} PID keeps "
        f"Ms <= {ms_limit} and the coupled loop stable (Ms {worst_ms:.2f}, radius {worst_rho:.6f})"
    )
    return CecTuned(zero, 0.0, slow, worst_ms, worst_rho, ms_limit, why)
