"""Fitting profile parameters to measured run times.

A fitted parameter is a profile field, possibly shared by several axes:
``motion.min_block_time_s``, ``axes.Y.corner_acceleration_mm_s2`` or
``axes.XZ.corner_acceleration_mm_s2`` (one value for X and Z). Every
parameter is positive and fitted in log space (relative steps), between
bounds of 1/1000 and 1000 times its starting value unless given.

The residuals are relative errors ``predicted / measured - 1``. The fit runs
Levenberg-Marquardt on their squares, then (objective ``mean-abs``, the
default) Nelder-Mead on their mean absolute value, the figure the
validation reports.

Identifiability: before fitting, the sensitivity matrix J (d residual /
d log parameter, forward differences) is computed at the start values. A fit
is refused when there are more parameters than measurements, when a
parameter changes no prediction (a zero column), or when J is rank-deficient
(a combination of parameters changes nothing; its singular vector names
them). After the fit, J at the solution gives approximate relative standard
errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np

from contour.errors import UserError
from contour.estimation.profile import AXIS_FIELDS, AXIS_NAMES, MOTION_FIELDS, Profile


@dataclass
class Param:
    name: str  # as the user wrote it
    paths: tuple  # profile paths set to this value
    start: float
    low: float
    high: float


def parse_param(spec: str, profile: Profile) -> Param:
    """``[axes.<AXES>.|motion.]<field>[=start][:low:high]`` to a Param."""
    text = spec.strip()
    bounds = None
    if ":" in text:
        text, _, b = text.partition(":")
        lo, sep, hi = b.partition(":")
        try:
            bounds = (float(lo), float(hi))
        except ValueError:
            raise UserError(f"fit parameter '{spec}': bounds must be LOW:HIGH numbers") from None
        if not sep or not (0 < bounds[0] < bounds[1]):
            raise UserError(f"fit parameter '{spec}': bounds must be 0 < LOW < HIGH")
    start = None
    if "=" in text:
        text, _, s = text.partition("=")
        try:
            start = float(s)
        except ValueError:
            raise UserError(f"fit parameter '{spec}': start value must be a number") from None
    parts = text.strip().split(".")
    numeric = lambda fields: {f.name for f in fields if not f.choices and type(f.default) is float}  # noqa: E731
    if len(parts) == 2 and parts[0] == "motion" and parts[1] in numeric(MOTION_FIELDS):
        paths = (text.strip(),)
    elif len(parts) == 3 and parts[0] == "axes" and parts[2] in numeric(AXIS_FIELDS):
        axes = parts[1]
        if not axes or any(a not in AXIS_NAMES for a in axes) or len(set(axes)) != len(axes):
            raise UserError(f"fit parameter '{spec}': '{axes}' is not a set of axes (e.g. Y or XZ)")
        paths = tuple(f"axes.{a}.{parts[2]}" for a in axes)
    else:
        raise UserError(
            f"cannot fit '{spec}': name a numeric profile field, motion.<field> or "
            "axes.<AXES>.<field> (AXES one or more of X Y Z, tied)"
        )
    if start is None:
        start = float(profile.get(paths[0]))
    if not (start > 0 and math.isfinite(start)):
        raise UserError(f"fit parameter '{spec}': start value must be positive")
    low, high = bounds if bounds else (start / 1000.0, start * 1000.0)
    if not (low <= start <= high):
        raise UserError(f"fit parameter '{spec}': start {start:g} outside [{low:g}, {high:g}]")
    return Param(text.strip(), paths, start, low, high)


def check_overlap(params) -> None:
    seen = {}
    for p in params:
        for path in p.paths:
            if path in seen:
                raise UserError(f"{path} is fitted twice ({seen[path]} and {p.name})")
            seen[path] = p.name


def values_of(params, x) -> dict:
    out = {}
    for p, xi in zip(params, x):
        v = float(math.exp(xi))
        for path in p.paths:
            out[path] = v
    return out


@dataclass
class FitResult:
    values: dict  # param name -> value
    residuals: np.ndarray
    rel_std: dict  # param name -> approximate relative standard error
    singular_values: np.ndarray
    evaluations: int
    objective: str
    history: list = field(default_factory=list)


class Refused(UserError):
    """The data cannot identify the parameters asked for."""


def jacobian(fun, x, r0, step=0.02):
    """Forward differences in log space (``step`` ~ 2 % relative)."""
    J = np.empty((r0.size, x.size))
    for j in range(x.size):
        xj = x.copy()
        xj[j] += step
        J[:, j] = (fun(xj) - r0) / step
    return J


def identifiability(params, J, rtol=1e-3) -> Optional[str]:
    """Reason the parameters are not identifiable from J, or None."""
    n, p = J.shape
    if p > n:
        return f"{p} parameters but only {n} measurements"
    norms = np.linalg.norm(J, axis=0)
    scale = float(norms.max()) if norms.size else 0.0
    if scale == 0.0:
        return "no measurement depends on any of the parameters"
    for j, prm in enumerate(params):
        if norms[j] <= rtol * scale:
            return f"no measurement depends on {prm.name} (its sensitivity is {norms[j]:.2g})"
    _, s, vt = np.linalg.svd(J / norms, full_matrices=False)
    if s[-1] <= rtol * s[0]:
        v = vt[-1]
        names = [params[j].name for j in np.argsort(-np.abs(v)) if abs(v[j]) > 0.2]
        return (
            "the data only constrain a combination of "
            + ", ".join(names)
            + " (tie them or fix all but one)"
        )
    return None


def _lm(fun, x0, lo, hi, max_iter=40, log=None):
    x = x0.copy()
    r = fun(x)
    cost = float(r @ r)
    lam = 1e-2
    for _ in range(max_iter):
        J = jacobian(fun, x, r)
        g = J.T @ r
        A = J.T @ J
        improved = False
        for _ in range(8):
            step = np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-12), -g)
            xn = np.clip(x + step, lo, hi)
            rn = fun(xn)
            cn = float(rn @ rn)
            if cn < cost:
                improved = True
                break
            lam *= 10
        if not improved:
            break
        rel = (cost - cn) / max(cost, 1e-300)
        x, r, cost = xn, rn, cn
        lam = max(lam / 10, 1e-9)
        if log:
            log(f"  least squares: rms {math.sqrt(cost / r.size) * 100:.3f} %")
        if rel < 1e-4:
            break
    return x


def _nelder_mead(f, x0, lo, hi, max_eval=400, scale=0.1, log=None):
    n = x0.size
    pts = [np.clip(x0, lo, hi)]
    for j in range(n):
        y = x0.copy()
        y[j] += scale
        pts.append(np.clip(y, lo, hi))
    vals = [f(p) for p in pts]
    evals = n + 1
    while evals < max_eval:
        order = np.argsort(vals)
        pts = [pts[i] for i in order]
        vals = [vals[i] for i in order]
        if vals[-1] - vals[0] <= 1e-7 * max(abs(vals[0]), 1e-12):
            break
        c = np.mean(pts[:-1], axis=0)
        xr = np.clip(c + (c - pts[-1]), lo, hi)
        fr = f(xr)
        evals += 1
        if fr < vals[0]:
            xe = np.clip(c + 2 * (c - pts[-1]), lo, hi)
            fe = f(xe)
            evals += 1
            pts[-1], vals[-1] = (xe, fe) if fe < fr else (xr, fr)
        elif fr < vals[-2]:
            pts[-1], vals[-1] = xr, fr
        else:
            xc = np.clip(c + 0.5 * (pts[-1] - c), lo, hi)
            fc = f(xc)
            evals += 1
            if fc < vals[-1]:
                pts[-1], vals[-1] = xc, fc
            else:
                for i in range(1, n + 1):
                    pts[i] = pts[0] + 0.5 * (pts[i] - pts[0])
                    vals[i] = f(pts[i])
                evals += n
    best = int(np.argmin(vals))
    if log:
        log(f"  mean abs: {vals[best] * 100:.3f} % after {evals} evaluations")
    return pts[best]


def fit(
    params,
    residuals: Callable[[dict], np.ndarray],
    objective: str = "mean-abs",
    log: Optional[Callable[[str], None]] = None,
) -> FitResult:
    """Fit ``params``; ``residuals(values)`` gives the relative errors."""
    if objective not in ("mean-abs", "least-squares"):
        raise UserError(f"unknown objective '{objective}' (mean-abs, least-squares)")
    check_overlap(params)
    count = [0]

    def fun(x):
        count[0] += 1
        r = np.asarray(residuals(values_of(params, x)), dtype=float)
        if not np.all(np.isfinite(r)):
            return np.full(r.shape, 1e3)
        return r

    x0 = np.log([p.start for p in params])
    lo = np.log([p.low for p in params])
    hi = np.log([p.high for p in params])
    r0 = fun(x0)
    J0 = jacobian(fun, x0, r0)
    why = identifiability(params, J0)
    if why:
        raise Refused(f"refusing to fit: {why}")
    x = _lm(fun, x0, lo, hi, log=log)
    if objective == "mean-abs":
        x = _nelder_mead(lambda y: float(np.mean(np.abs(fun(y)))), x, lo, hi, log=log)
    r = fun(x)
    J = jacobian(fun, x, r)
    s = np.linalg.svd(J, compute_uv=False)
    rel_std = {}
    dof = max(r.size - x.size, 1)
    sigma2 = float(r @ r) / dof
    try:
        cov = np.linalg.inv(J.T @ J) * sigma2
        for p, v in zip(params, np.sqrt(np.maximum(np.diag(cov), 0.0))):
            rel_std[p.name] = float(math.expm1(v))
    except np.linalg.LinAlgError:
        rel_std = {p.name: math.inf for p in params}
    values = {p.name: float(math.exp(xi)) for p, xi in zip(params, x)}
    return FitResult(values, r, rel_std, s, count[0], objective)
