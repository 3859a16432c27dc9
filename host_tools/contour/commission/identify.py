"""Identification of an axis from an excitation record (experiment.Record).

1. Frequency response at the excited bins: the record's multisine part is
   cut into its periods (the first is dropped: transient), the DFTs of
   command and position are averaged over the periods and G = Y / U (closed
   loop: the excitation is periodic, the noise is not, so the average of
   each converges to its periodic part and Y / U to the plant at those
   bins). The spread between periods gives the standard deviation of each
   point (its weight, and the confidence intervals).
2. Parametric fit of the command (V) -> motor position (m) model, discretised
   exactly (zero-order hold) at the tick, by Levenberg-Marquardt on the
   complex log error (log-magnitude and phase) weighted by 1 / sigma:
   - two-inertia (the 5th-order model of lacerda1998.md seen from the
     motor): k (s^2/wa^2 + 2 za s/wa + 1) / (s (s/p1 + 1) (s/p2 + 1)
     (s^2/wr^2 + 2 zr s/wr + 1)), wr resonance, wa anti-resonance;
   - rigid body: k / (s (s/p1 + 1) (s/p2 + 1)).
   Parameters are fitted in log form; confidence intervals (95 %) from the
   Jacobian at the optimum, scaled by the residual's variance.
3. Friction from the constant-velocity legs: mean command per leg,
   u = u0 + f sign(v) + c v by least squares (f: Coulomb friction as
   command volts, c: viscous + back-EMF, V s/m, u0: constant load).

Refusals (IdentifyError): fewer than two periods after the transient, no
excited bins, a rigid fit whose rms error exceeds `max_rms_log` (the data
are noise). The two-inertia model is taken only when its four more parameters
lower the weighted residual significantly (F statistic
((S_rigid - S_two) / 4) / (S_two / dof_two) >= `min_f`; the weights come
from the spread between periods, which does not see the periodic
distortion of friction, so the F statistic is large on every record and
the threshold is a floor, not a test level), its
resonance lies inside the excited band, its 95 % interval is narrower
than +-`max_ci_rel` of the value, and the resonance and anti-resonance
are apart by more than their intervals (a pole pair cancelled by a zero
pair is no mode: the simulated drive's records are clean enough for such
a pair to pass the F floor on a rigid axis); otherwise the result is the rigid model
with `resonance_hz` None and the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from contour.sim import tuning

from .experiment import Record

TWO_INERTIA = ("k", "p1", "p2", "wa", "za", "wr", "zr")
RIGID = ("k", "p1", "p2")


class IdentifyError(ValueError):
    pass


@dataclass
class Fit:
    model: str
    params: dict  # name -> value (SI: rad/s, V -> m gain)
    ci95: dict  # name -> half-width of the 95 % interval
    rms_log: float  # weighted rms of the complex log error
    chi2: float  # weighted residual per degree of freedom
    dof: int = 1


@dataclass
class Identification:
    model: str  # "two_inertia" or "rigid"
    fit: Fit
    rigid: Fit
    two_inertia: Fit | None
    resonance_hz: float | None
    resonance_ci_hz: float | None
    antiresonance_hz: float | None
    friction_v: float | None
    viscous_v_s_m: float | None
    load_v: float | None
    reason: str = ""
    freq_hz: np.ndarray = field(default_factory=lambda: np.zeros(0))
    g_meas: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def as_dict(self) -> dict:
        def r(x, n=4):
            return None if x is None else round(float(x), n)

        return {
            "model": self.model,
            "resonance_hz": r(self.resonance_hz, 2),
            "resonance_ci95_hz": r(self.resonance_ci_hz, 2),
            "antiresonance_hz": r(self.antiresonance_hz, 2),
            "friction_v": r(self.friction_v),
            "viscous_v_s_m": r(self.viscous_v_s_m, 2),
            "load_v": r(self.load_v),
            "params": {k: float(f"{v:.6g}") for k, v in self.fit.params.items()},
            "ci95": {k: float(f"{v:.3g}") for k, v in self.fit.ci95.items()},
            "rms_log": r(self.fit.rms_log),
            "rigid_rms_log": r(self.rigid.rms_log),
            "reason": self.reason,
        }


def frequency_response(rec: Record):
    """(freq Hz, G at the excited bins, sigma of G) of the periodic part:
    the simulated drive's multisine (its first period is the transient) or
    the drive's PRBS windows (segment "periodic", each window one period
    recorded after the loop settled: `rec.plan` gives the period and the
    excited bins, drive_experiment.PrbsPlan)."""
    plan = rec.plan
    n = plan.period_ticks
    if "periodic" in rec.segments:
        start, stop = rec.segments["periodic"]
        periods = (stop - start) // n
        start -= n  # no transient period in the record
    else:
        start, stop = rec.segments.get("multisine", (0, 0))
        periods = (stop - start) // n - 1
    if periods < 2:
        raise IdentifyError(f"{periods} excitation periods after the transient: need 2 or more")
    bins = plan.excited_bins()
    if bins.size == 0:
        raise IdentifyError("no excited frequency below the Nyquist frequency")
    seg = slice(start + n, start + n * (periods + 1))
    u = rec.u[seg].reshape(periods, n)
    y = rec.y[seg].reshape(periods, n)
    y = y - y.mean(axis=1, keepdims=True)
    uf = np.fft.rfft(u, axis=1)[:, bins]
    yf = np.fft.rfft(y, axis=1)[:, bins]
    g = yf.mean(axis=0) / uf.mean(axis=0)
    gp = yf / uf
    sigma = np.sqrt(np.mean(np.abs(gp - g) ** 2, axis=0) / (periods - 1) + 1e-300)
    return bins * rec.tick_hz / n, g, sigma


def _series_ss(theta: dict, model: str):
    """Continuous (A, B, C) of the model: biquad -> lag p1 -> lag p2 -> k/s."""
    k, p1, p2 = theta["k"], theta["p1"], theta["p2"]
    if model == "two_inertia":
        wa, za, wr, zr = theta["wa"], theta["za"], theta["wr"], theta["zr"]
        c0 = wr * wr / (wa * wa)
        a = np.zeros((5, 5))
        b = np.zeros(5)
        # biquad states x0, x1: x0' = x1, x1' = -wr^2 x0 - 2 zr wr x1 + u
        a[0, 1] = 1.0
        a[1, 0] = -wr * wr
        a[1, 1] = -2 * zr * wr
        b[1] = 1.0
        bq_c = c0 * np.array([wa * wa - wr * wr, 2 * za * wa - 2 * zr * wr])
        bq_d = c0
        # lag p1: x2' = p1 (v - x2), v = bq_c x + bq_d u
        a[2, 0:2] = p1 * bq_c
        a[2, 2] = -p1
        b[2] = p1 * bq_d
        a[3, 2] = p2
        a[3, 3] = -p2
        a[4, 3] = k
        c = np.zeros(5)
        c[4] = 1.0
        return a, b, c
    a = np.zeros((3, 3))
    b = np.zeros(3)
    a[0, 0] = -p1
    b[0] = p1
    a[1, 0] = p2
    a[1, 1] = -p2
    a[2, 1] = k
    c = np.zeros(3)
    c[2] = 1.0
    return a, b, c


def model_frd(theta: dict, model: str, freq_hz: np.ndarray, tick_hz: float) -> np.ndarray:
    """Frequency response of the model discretised by zero-order hold."""
    a, b, c = _series_ss(theta, model)
    t = 1.0 / tick_hz
    phi, gam = tuning.zoh(a, b[:, None], t)
    lam, v = np.linalg.eig(phi)
    cv = c @ v
    vg = np.linalg.solve(v, gam[:, 0])
    z = np.exp(2j * math.pi * freq_hz * t)
    # modal sum: C (zI - Phi)^-1 Gamma with Phi = V diag(lam) V^-1
    return np.sum((cv * vg)[None, :] / (z[:, None] - lam[None, :]), axis=1)


ZETA_FLOOR = 1e-5  # damping ratios are fitted as ZETA_FLOOR + e^x


def _values(x, names) -> np.ndarray:
    v = np.exp(x)
    return np.array([vi + ZETA_FLOOR if n.startswith("z") else vi for vi, n in zip(v, names)])


def _residual(x, names, model, f, g, w, tick_hz):
    theta = dict(zip(names, _values(x, names)))
    gm = model_frd(theta, model, f, tick_hz)
    e = np.log(gm / g)
    e = np.where(np.isfinite(e), e, 50.0)
    return np.concatenate([e.real * w, e.imag * w])


def _lm(x0, names, model, f, g, w, tick_hz, iters=200):
    x = np.array(x0, float)
    r = _residual(x, names, model, f, g, w, tick_hz)
    cost = float(r @ r)
    lam = 1e-3
    jac = None
    for _ in range(iters):
        jac = np.empty((r.size, x.size))
        for i in range(x.size):
            dx = np.zeros_like(x)
            dx[i] = 1e-6
            jac[:, i] = (_residual(x + dx, names, model, f, g, w, tick_hz) - r) / 1e-6
        jtj = jac.T @ jac
        grad = jac.T @ r
        improved = False
        for _ in range(20):
            step = np.linalg.solve(jtj + lam * np.diag(np.diag(jtj) + 1e-12), -grad)
            xn = x + np.clip(step, -1.0, 1.0)
            rn = _residual(xn, names, model, f, g, w, tick_hz)
            cn = float(rn @ rn)
            if cn < cost:
                improved = True
                done = (cost - cn) < 1e-10 * cost
                x, r, cost = xn, rn, cn
                lam = max(lam / 3, 1e-12)
                break
            lam *= 4
        if not improved or done:
            break
    return x, r, cost, jac


def _fit(model, x0, f, g, w, tick_hz) -> Fit:
    names = TWO_INERTIA if model == "two_inertia" else RIGID
    x0 = [max(v - ZETA_FLOOR, ZETA_FLOOR) if n.startswith("z") else v for v, n in zip(x0, names)]
    x, r, cost, jac = _lm(np.log(x0), names, model, f, g, w, tick_hz)
    dof = max(1, r.size - x.size)
    chi2 = cost / dof
    # a direction the data do not see (a damping at its floor) has an
    # infinite variance: pinv would report it as 0, so invert and let inf be
    cov = np.linalg.pinv(jac.T @ jac, rcond=1e-15) * chi2
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    vals = _values(x, names)
    params = dict(zip(names, vals))
    # 95 % half-width, linearised: 1.96 sd of log(value - floor) * (value - floor)
    ci = {n: 1.96 * s * np.exp(xi) for n, s, xi in zip(names, sd, x)}
    e = np.log(model_frd(params, model, f, tick_hz) / g)
    rms = float(np.sqrt(np.sum(w * w * np.abs(e) ** 2) / np.sum(w * w)))
    return Fit(model, params, ci, rms, chi2, dof)


def _rigid_start(f, g):
    w = 2 * math.pi * f
    # low-frequency gain: |G| w ~ k at the lowest bins
    k0 = float(np.median((np.abs(g) * w)[: max(3, w.size // 20)]))
    return [k0, 2 * math.pi * 5.0, 2 * math.pi * 100.0]


def friction(rec: Record):
    """(f, c, u0) from the constant-velocity legs, or Nones without legs."""
    legs = []
    for name, (a, b) in rec.segments.items():
        if not name.startswith("leg"):
            continue
        v = float(name.split(":")[1])
        mid = slice(a + (b - a) // 2, b)  # second half: past the transient
        legs.append((v, float(np.mean(rec.u[mid]))))
    return friction_fit(legs)


def friction_fit(legs):
    """(f, c, u0) of u = u0 + f sign(v) + c v by least squares over the
    legs [(v m/s, mean command V)], or Nones with fewer than three legs or
    one speed only (f and c would not be separable)."""
    if len(legs) < 3 or len({abs(v) for v, _ in legs}) < 2:
        return None, None, None
    rows = [[1.0, math.copysign(1.0, v), v] for v, _ in legs]
    sol, *_ = np.linalg.lstsq(np.array(rows), np.array([u for _, u in legs]), rcond=None)
    return float(sol[1]), float(sol[2]), float(sol[0])


def identify(
    rec: Record, max_rms_log: float = 0.5, min_f: float = 10.0, max_ci_rel: float = 0.05
) -> Identification:
    f, g, sigma = frequency_response(rec)
    w = np.abs(g) / np.maximum(sigma, 1e-12 * np.abs(g))  # 1 / relative sigma
    w = np.minimum(w, np.median(w) * 10)
    rigid = min(
        (_fit("rigid", s, f, g, w, rec.tick_hz) for s in _rigid_starts(f, g)),
        key=lambda ft: ft.chi2,
    )
    if rigid.rms_log > max_rms_log * 4:
        raise IdentifyError(
            f"rigid-body fit error {rigid.rms_log:.2f} (log units): the data carry no model"
        )
    # two-inertia starts: dip and peak of the measured response over the rigid fit
    ratio = np.abs(g / model_frd(rigid.params, "rigid", f, rec.tick_hz))
    lr = np.log(ratio)
    best = None
    starts = []
    ipk = int(np.argmax(lr))
    idip = int(np.argmin(lr[: ipk + 1])) if ipk > 0 else 0
    for wr0 in {f[ipk], f[ipk] * 1.02}:
        for wa0 in {f[idip], wr0 * 0.85}:
            if wa0 >= wr0:
                continue
            for z0 in (0.01, 0.1):
                starts.append(
                    [
                        rigid.params["k"],
                        rigid.params["p1"],
                        rigid.params["p2"],
                        2 * math.pi * wa0,
                        z0,
                        2 * math.pi * wr0,
                        z0,
                    ]
                )
    for s in starts:
        try:
            ft = _fit("two_inertia", s, f, g, w, rec.tick_hz)
        except (np.linalg.LinAlgError, FloatingPointError):
            continue
        if best is None or ft.chi2 < best.chi2:
            best = ft
    fr, c, u0 = friction(rec)
    reason = ""
    model, fit = "rigid", rigid
    res = res_ci = anti = None
    if best is None:
        reason = "two-inertia fit failed"
    else:
        wr, wa = best.params["wr"], best.params["wa"]
        ci_rel = best.ci95["wr"] / wr
        ftest = (rigid.chi2 * rigid.dof - best.chi2 * best.dof) / 4 / best.chi2
        if not ftest >= min_f:
            reason = (
                f"two-inertia fit: F statistic {ftest:.1f} against the rigid fit "
                f"(< {min_f}): no resonance in the data"
            )
        elif not (f[0] <= wr / (2 * math.pi) <= f[-1]):
            reason = f"resonance {wr / (2 * math.pi):.0f} Hz outside the excited band"
        elif not ci_rel <= max_ci_rel:
            reason = f"resonance 95 % interval +-{100 * ci_rel:.0f} % (> {100 * max_ci_rel:.0f} %)"
        elif not abs(wr - wa) > best.ci95["wr"] + best.ci95["wa"]:
            reason = (
                f"resonance {wr / (2 * math.pi):.0f} Hz and anti-resonance "
                f"{wa / (2 * math.pi):.0f} Hz within their intervals: they cancel"
            )
        elif rigid.rms_log > max_rms_log and best.rms_log > max_rms_log:
            reason = f"fit error {best.rms_log:.2f} > {max_rms_log}"
        else:
            model, fit = "two_inertia", best
            res = wr / (2 * math.pi)
            res_ci = best.ci95["wr"] / (2 * math.pi)
            anti = wa / (2 * math.pi)
    if model == "rigid" and rigid.rms_log > max_rms_log:
        raise IdentifyError(
            f"rigid-body fit error {rigid.rms_log:.2f} > {max_rms_log} "
            f"and {reason or 'no better model'}"
        )
    return Identification(model, fit, rigid, best, res, res_ci, anti, fr, c, u0, reason, f, g)


def _rigid_starts(f, g):
    s = _rigid_start(f, g)
    return [s, [s[0], s[1] * 4, s[2] * 4], [s[0], s[1] / 4, s[2] * 10]]
