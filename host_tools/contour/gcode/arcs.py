"""Arc geometry: the centre of a G2/G3 block, and the chords that split it.

Every failure is a message for :class:`~contour.gcode.GcodeError` (the
caller adds ``file:line``): an arc whose numbers overflow (``R1e300``), whose
centre is not finite, or that would need more than :data:`MAX_CHORDS`
chords, never a Python exception.
"""

from __future__ import annotations

import math

import numpy as np

from contour.gcode.moves import PLANE_AXES

# ``P`` full turns of one arc (``G2 ... P3000000`` would otherwise be read).
MAX_TURNS = 1000
# Chords of one arc in segments(); a bound on memory whatever the radius,
# the turns and the chord tolerance.
MAX_CHORDS = 1_000_000


# A centre beyond this (mm) is no arc a machine can cut (I1e15, R1e300).
MAX_CENTRE = 1e9


class ArcError(ValueError):
    """A message for the caller to turn into a file:line error."""


def centre_ijk(su, sv, eu, ev, ou, ov, absolute, tol):
    """Centre (cu, cv) from I J K offsets (already in mm)."""
    if absolute:
        cu, cv = ou, ov
    else:
        cu, cv = su + ou, sv + ov
    if not (abs(cu) < MAX_CENTRE and abs(cv) < MAX_CENTRE):
        raise ArcError(f"arc centre out of range (beyond {MAX_CENTRE:g} mm)")
    r0 = math.hypot(su - cu, sv - cv)
    r1 = math.hypot(eu - cu, ev - cv)
    if r0 < 1e-9:
        raise ArcError("arc of zero radius (centre on the start point)")
    if abs(r0 - r1) > max(tol, 1e-3 * r0):
        raise ArcError(
            f"arc end point is not on the circle: radius {r0:.4f} at the start, {r1:.4f} at the end"
        )
    return cu, cv


def centre_r(su, sv, eu, ev, r_signed, ccw, tol):
    """Centre (cu, cv) from a signed radius (mm); negative: more than half a turn."""
    r = abs(r_signed)
    du, dv = eu - su, ev - sv
    d = math.hypot(du, dv)
    if not (r < MAX_CENTRE and d < MAX_CENTRE):
        raise ArcError(f"arc radius out of range (beyond {MAX_CENTRE:g} mm)")
    if d < 1e-9:
        raise ArcError("R-form arc with identical start and end points")
    if d > 2 * r + tol:
        raise ArcError(f"arc radius {r:.4f} too small for a chord of {d:.4f}")
    half = d / 2.0
    # sqrt((r - d/2)(r + d/2)) does not overflow where r*r would.
    h = math.sqrt(max(r - half, 0.0)) * math.sqrt(r + half)
    s = 1.0 if ccw == (r_signed > 0) else -1.0  # centre left of the chord
    cu = su + du / 2 - s * h * dv / d
    cv = sv + dv / 2 + s * h * du / d
    if not (abs(cu) < MAX_CENTRE and abs(cv) < MAX_CENTRE):
        raise ArcError(f"arc centre out of range (beyond {MAX_CENTRE:g} mm)")
    return cu, cv


def chord_count(radius: float, sweep: float, tol: float) -> int:
    """Chords needed so that none deviates more than ``tol`` from the arc."""
    if tol >= radius:
        step = 2 * math.pi / 3
    else:
        # 2 acos(1 - tol/r), written so that a tiny tol/r does not round to 0.
        step = 4 * math.asin(math.sqrt(tol / (2 * radius)))
    k = sweep / step if step > 0 else math.inf
    if not k <= MAX_CHORDS:
        raise ArcError(
            f"arc needs more than {MAX_CHORDS} chords at a chord tolerance of {tol:g} mm "
            f"(radius {radius:.6g} mm, {sweep / (2 * math.pi):.6g} turns)"
        )
    return max(1, int(math.ceil(k)))


def arc_points(start, end, centre, plane, clockwise, turns, tol):
    """The chord end points (k, 3) of one arc, the last one exactly ``end``."""
    u, v = PLANE_AXES[plane]
    w = 3 - u - v
    cu, cv = centre[u], centre[v]
    a0 = math.atan2(start[v] - cv, start[u] - cu)
    a1 = math.atan2(end[v] - cv, end[u] - cu)
    r = math.hypot(start[u] - cu, start[v] - cv)
    sweep = (a0 - a1) if clockwise else (a1 - a0)
    sweep %= 2 * math.pi
    if sweep < 1e-12:
        sweep = 2 * math.pi
    sweep += 2 * math.pi * turns
    k = chord_count(r, sweep, tol)
    sgn = -1.0 if clockwise else 1.0
    t = np.arange(1, k + 1) / k
    ang = a0 + sgn * sweep * t
    pts = np.empty((k, 3))
    pts[:, u] = cu + r * np.cos(ang)
    pts[:, v] = cv + r * np.sin(ang)
    pts[:, w] = start[w] + (end[w] - start[w]) * t
    pts[-1] = end  # exact end point
    return pts
