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


SCALES_UM = (0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000)
RING_DIVS = 4  # the nominal circle is drawn on ring 4; rings 0..8 are -4..+4 div


def scale_for(err_um_max: float) -> float:
    """The smallest scale (um per division) of the 1-2-5 ladder that keeps a
    radial deviation of err_um_max within the plot's +-4 divisions."""
    for sc in SCALES_UM:
        if err_um_max <= RING_DIVS * sc:
            return float(sc)
    return float(SCALES_UM[-1])


def plot_name(prefix: str, res) -> str:
    """File name carrying the test conditions: radius, feed, controller, tick."""
    return (
        f"{prefix}_R{res.radius_mm:g}mm_F{res.feed_mm_min:g}_{res.controller}_"
        f"ff-{res.feedforward}_{res.tick_hz:g}Hz.png"
    )


def ballbar(path: str, runs, scale_um: float | None = None, ax=None) -> float:
    """Ballbar report plot (ISO 230-4 / ballbar software conventions) of one
    or more runs of the same test, e.g. ccw and cw overlaid: the radial
    deviation about the nominal centre on a polar chart whose rings are one
    division apart at a fixed, stated scale (um per division, 1-2-5 ladder,
    chosen from the largest deviation unless given), the nominal circle the
    heavy middle ring. Only the scored revolution is drawn: the lead-in,
    start and stop arcs are left out (stated in the plot). `runs` is a list
    of (trace, result) or one CircleRun-like pair. Returns the scale."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if isinstance(runs, tuple):
        runs = [runs]
    res0 = runs[0][1]
    emax = max(float(np.abs(tr[:, 3]).max()) * 1e6 for tr, _ in runs)
    sc = float(scale_um) if scale_um else scale_for(emax)
    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(6.0, 6.6))
    a = np.linspace(0, 2 * math.pi, 721)
    for k in range(0, 2 * RING_DIVS + 1):
        heavy = k == RING_DIVS
        ax.plot(
            k * np.cos(a), k * np.sin(a), color="0.3" if heavy else "0.85", lw=1.2 if heavy else 0.6
        )
        if k % 2 == 0:
            ax.text(
                0.05, k + 0.05, f"{(k - RING_DIVS) * sc:+g} um", fontsize=6, color="0.4", ha="left"
            )
    for d in range(0, 360, 45):
        ax.plot(
            [0, 2 * RING_DIVS * math.cos(math.radians(d))],
            [0, 2 * RING_DIVS * math.sin(math.radians(d))],
            color="0.9",
            lw=0.5,
        )
    colours = {"ccw": "tab:blue", "cw": "tab:red"}
    for tr, res in runs:
        th = np.arctan2(tr[:, 2], tr[:, 1])
        rho = np.clip(RING_DIVS + tr[:, 3] * 1e6 / sc, 0, 2 * RING_DIVS)
        clipped = bool(np.any(np.abs(tr[:, 3] * 1e6) > RING_DIVS * sc))
        ax.plot(
            rho[0] * np.cos(th[0]),
            rho[0] * np.sin(th[0]),
            "o",
            ms=3,
            mfc="none",
            color=colours.get(res.direction),
        )  # start (= end) of the scored revolution
        ax.plot(
            rho * np.cos(th),
            rho * np.sin(th),
            lw=1.0,
            color=colours.get(res.direction),
            label=(
                f"{res.direction}: circular dev. {res.circular_deviation_mm * 1e3:.2f} um, "
                f"max |e| {res.max_contour_error_mm * 1e3:.2f} um"
                + (" (clipped)" if clipped else "")
                + (
                    f"; NOT AT STATED FEED (min {res.min_feed_mm_min:.0f})"
                    if res.limited_by
                    else ""
                )
            ),
        )
    ax.set_aspect("equal")
    ax.set_xlim(-2 * RING_DIVS - 0.5, 2 * RING_DIVS + 0.5)
    ax.set_ylim(-2 * RING_DIVS - 0.5, 2 * RING_DIVS + 0.5)
    ax.set_xticks([])
    ax.set_yticks([])
    for side in ax.spines.values():
        side.set_visible(False)
    ax.set_title(
        f"Circular test (ISO 230-4): R {res0.radius_mm:g} mm, F {res0.feed_mm_min:g} mm/min\n"
        f"{res0.controller}, feed-forward {res0.feedforward}, tick {res0.tick_hz:g} Hz "
        f"({res0.machine})\nscale {sc:g} um/div, rings -{RING_DIVS}..+{RING_DIVS} div about "
        "the nominal circle (heavy)",
        fontsize=8,
    )
    ax.set_xlabel(
        "radial deviation about the nominal centre; scored revolution only "
        "(lead-in, settling revolutions, lead-out omitted; o: start/end of it)",
        fontsize=7,
    )
    ax.xaxis.label.set_visible(True)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.04), frameon=False)
    if own:
        fig.tight_layout()
        try:
            fig.savefig(path, dpi=110, bbox_inches="tight")
        except OSError as exc:
            raise UserError(f"cannot write {path}: {exc.strerror}") from exc
        plt.close(fig)
    return sc
