"""Canonical moves: what the interpreter hands to cutter compensation and
to the program columns.

A :class:`Move` is one motion or dwell in machine coordinates (mm for X Y Z,
degrees for A B C), after units, offsets and canned-cycle expansion. The
start of a move is the end of the one before it. Arcs carry their centre in
the three linear axes (NaN on the axes outside the plane), their plane and
their extra full turns.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

# Move kinds (also Program.kind).
RAPID = 0
LINEAR = 1
ARC_CW = 2
ARC_CCW = 3
DWELL = 4
KIND_NAMES = {
    RAPID: "rapid",
    LINEAR: "linear",
    ARC_CW: "arc_cw",
    ARC_CCW: "arc_ccw",
    DWELL: "dwell",
}

# Planes (Move.plane): the two in-plane axes, in the order of the arc's
# sense (G17 XY, G18 ZX, G19 YZ).
PLANE_AXES = ((0, 1), (2, 0), (1, 2))


@dataclass
class Move:
    kind: int
    start: tuple  # 6 floats
    end: tuple  # 6 floats
    feed: float  # mm/min; NaN for rapids and dwells
    line: int  # 1-based source line
    centre: Optional[tuple] = None  # 3 floats (arcs only)
    plane: int = 0  # 0 G17, 1 G18, 2 G19
    turns: int = 0  # extra full turns (arcs only)
    exact_stop: bool = False
    dwell_s: float = 0.0
