"""The error map as a PNG (matplotlib, no display needed)."""

from __future__ import annotations

from typing import Optional

from contour.calibration.analysis import ErrorMap
from contour.errors import UserError


def plot_error_map(
    path: str,
    errmap: ErrorMap,
    residual: Optional[ErrorMap] = None,
    title: str = "",
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = 2 if residual is not None else 1
    fig, axes = plt.subplots(rows, 1, figsize=(8, 3.6 * rows), squeeze=False, sharex=True)

    def draw(ax, em: ErrorMap, label: str) -> None:
        x = [p.position_mm for p in em.points]
        fwd = [1000 * p.mean_err_pos_mm for p in em.points]
        rev = [1000 * p.mean_err_neg_mm for p in em.points]
        sysv = [1000 * p.systematic_mm for p in em.points]
        half = [1000 * p.random_95_mm for p in em.points]  # +-2 s: 95 % of the readings
        ax.fill_between(
            x,
            [s - h for s, h in zip(sysv, half)],
            [s + h for s, h in zip(sysv, half)],
            color="0.85",
            label="systematic +- random (95 %)",
        )
        ax.plot(x, fwd, "o-", color="tab:red", label="approached +x")
        ax.plot(x, rev, "s-", color="tab:blue", label="approached -x")
        ax.plot(x, sysv, "k--", label="systematic")
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_ylabel("error = encoder - reference (um)")
        ax.set_title(label)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="best")

    s = errmap.summary()
    draw(
        axes[0][0],
        errmap,
        f"{title or 'calibration'}: systematic {s['max_systematic_um']:.1f} um, "
        f"hysteresis {s['max_hysteresis_um']:.1f} um, random {s['max_random_95_um']:.1f} um (max)",
    )
    if residual is not None:
        r = residual.summary()
        draw(
            axes[1][0],
            residual,
            f"after compensation: systematic {r['max_systematic_um']:.2f} um, "
            f"hysteresis {r['max_hysteresis_um']:.2f} um (max)",
        )
    axes[-1][0].set_xlabel("position (mm)")
    fig.tight_layout()
    try:
        fig.savefig(path, dpi=110)
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from None
    finally:
        plt.close(fig)


def plot_field(path: str, before: list, after: Optional[list] = None) -> None:
    """The error field as vectors: systematic (X, Y) error at each node before
    compensation and, when given, the residual at the verification points
    after it (each panel scaled to its own largest vector; the scale bar
    says how long 10 um or 1 um is)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [(before, "before compensation", 10.0)]
    if after is not None:
        panels.append((after, "after: between the grid lines", 1.0))
    fig, axes = plt.subplots(1, len(panels), figsize=(6.2 * len(panels), 5.6), squeeze=False)
    for ax, (rows, title, ref_um) in zip(axes[0], panels):
        x = [r["x_mm"] for r in rows]
        y = [r["y_mm"] for r in rows]
        u = [r["x_systematic_um"] for r in rows]
        v = [r["y_systematic_um"] for r in rows]
        big = max(max(abs(a), abs(b)) for a, b in zip(u, v)) or 1.0
        q = ax.quiver(x, y, u, v, angles="xy", scale_units="width", scale=big * 12, color="tab:red")
        ax.quiverkey(q, 0.85, 1.03, ref_um, f"{ref_um:g} um", labelpos="E")
        ax.plot(x, y, ".", color="0.4", ms=3)
        ax.set_title(f"{title}: largest {big:.2f} um", fontsize=10)
        ax.set_xlabel("X (mm)")
        ax.set_ylabel("Y (mm)")
        ax.set_aspect("equal")
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    try:
        fig.savefig(path, dpi=110)
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from None
    finally:
        plt.close(fig)
