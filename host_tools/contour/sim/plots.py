"""Trace files and ballbar-style plots of circle tests."""

from __future__ import annotations

import math

import numpy as np

from contour.errors import UserError


def write_trace(path: str, trace: np.ndarray) -> None:
    """Scored revolution as CSV: t_s, x_mm, y_mm (about the centre), error_um."""
    out = np.column_stack([trace[:, 0], trace[:, 1] * 1e3, trace[:, 2] * 1e3, trace[:, 3] * 1e6])
    try:
        np.savetxt(
            path,
            out,
            delimiter=",",
            header="t_s,x_mm,y_mm,contour_error_um",
            comments="",
            fmt=["%.6f", "%.6f", "%.6f", "%.4f"],
        )
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from exc


def _amplification(r_mm: float, err_um: np.ndarray) -> float:
    span = float(np.abs(err_um).max()) if err_um.size else 0.0
    if span <= 0:
        return 1.0
    k = 0.3 * r_mm * 1e3 / span  # the largest error shows as 30 % of the radius
    mag = 10 ** math.floor(math.log10(k))
    for step in (5, 2, 1):
        if step * mag <= k:
            return step * mag
    return mag


def ballbar(path: str, trace: np.ndarray, res, ax=None) -> None:
    """Path with the radial error amplified about the nominal circle."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = res.radius_mm
    th = np.arctan2(trace[:, 2], trace[:, 1])
    e_um = trace[:, 3] * 1e6
    k = _amplification(r, e_um)
    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(5.2, 5.2))
    a = np.linspace(0, 2 * math.pi, 361)
    ax.plot(r * np.cos(a), r * np.sin(a), color="0.6", lw=0.8, label="nominal")
    rr = r + k * e_um * 1e-3
    ax.plot(rr * np.cos(th), rr * np.sin(th), lw=1.0, label=f"actual, error x{k:g}")
    ax.set_aspect("equal")
    ax.set_title(
        f"R {r:g} mm, {res.feed_mm_min / 1000:g} m/min, {res.controller}, ff {res.feedforward}\n"
        f"dev {res.circular_deviation_mm * 1e3:.2f} um, "
        f"max {res.max_contour_error_mm * 1e3:.2f} um, {res.tick_hz:g} Hz",
        fontsize=8,
    )
    ax.legend(fontsize=7, loc="lower right")
    ax.tick_params(labelsize=7)
    if own:
        fig.tight_layout()
        try:
            fig.savefig(path, dpi=110)
        except OSError as exc:
            raise UserError(f"cannot write {path}: {exc.strerror}") from exc
        plt.close(fig)
