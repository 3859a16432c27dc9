"""The 2-D compensation map on the host (issue 22): from per-node
corrections to the drive's fixed-point map (firmware/core/comp2d.h),
evaluated by the drive's own code, and its CSV file.

Model (comp2d.h): the correction of axis c at (x, y) is

    corr_c = mid_c(x, y) + w_x * hx_c(x, y) + w_y * hy_c(x, y)

with w_x, w_y = +1 / -1 for the direction of approach of X and Y. From the
four corrections measured at a node, one per combination of directions
(sx, sy) in {+, -}^2: mid = mean of the four, hx = half the difference of
+x and -x (mean over sy), hy the same for Y. Correction = reference -
encoder = -(calibration error), in um here, nm on the drive.

CSV (docs/calibration.md "2-D map file"): a `# comp2d v1 ...` header line,
then one row per node, y outer, x inner:
`x_mm,y_mm,x_mid_um,x_hx_um,x_hy_um,y_mid_um,y_hx_um,y_hy_um`.
"""

from __future__ import annotations

import ctypes as c
from dataclasses import dataclass

import numpy as np

from contour import native
from contour.errors import UserError

VERSION = 1
NODES_MAX = 144
ERRORS = {1: "version", 2: "memory", 3: "step", 4: "field"}
HEADER = "x_mm,y_mm,x_mid_um,x_hx_um,x_hy_um,y_mid_um,y_hx_um,y_hy_um"


@dataclass
class Map2D:
    x0: float  # mm, first node
    dx: float  # mm
    y0: float
    dy: float
    g: np.ndarray  # [axis][mid, hx, hy][iy][ix], um

    @property
    def nx(self) -> int:
        return self.g.shape[3]

    @property
    def ny(self) -> int:
        return self.g.shape[2]


def from_corrections(x0, dx, y0, dy, corr: np.ndarray) -> Map2D:
    """corr[axis][sx][sy][iy][ix], um (sx, sy: 0 moving +, 1 moving -)."""
    corr = np.asarray(corr, dtype=float)
    mid = corr.mean(axis=(1, 2))
    hx = 0.5 * (corr[:, 0].mean(axis=1) - corr[:, 1].mean(axis=1))
    hy = 0.5 * (corr[:, :, 0].mean(axis=1) - corr[:, :, 1].mean(axis=1))
    return Map2D(x0, dx, y0, dy, np.stack([mid, hx, hy], axis=1))


def to_c(m: Map2D) -> native.Comp2dMap:
    """The drive's map: int16 nodes in 2^shift nm, the smallest shift that
    holds the largest value."""
    nm = m.g * 1000.0
    big = float(np.abs(nm).max()) if nm.size else 0.0
    shift = 0
    while big / (1 << shift) > 32767 and shift < 9:
        shift += 1
    cm = native.Comp2dMap()
    cm.version = VERSION
    cm.nx, cm.ny, cm.shift = m.nx, m.ny, shift
    if m.nx * m.ny > NODES_MAX or m.nx > 255 or m.ny > 255:
        cm.nx, cm.ny = min(m.nx, 255), min(m.ny, 255)  # comp2d_check refuses it
        return cm
    cm.x0, cm.y0 = round(m.x0 * 1e6), round(m.y0 * 1e6)
    cm.dx, cm.dy = round(m.dx * 1e6), round(m.dy * 1e6)
    q = np.clip(np.rint(nm / (1 << shift)), -32768, 32767).astype(np.int16)
    for a in range(2):
        for k in range(3):
            flat = q[a, k].reshape(-1)
            for i, v in enumerate(flat):
                cm.g[a][k][i] = int(v)
    return cm


RECORD_MAX = 36 + 12 * NODES_MAX


def encode_record(cm: native.Comp2dMap) -> bytes:
    """The drive's record bytes of a map (comp2d_encode: what comp2d_write
    uploads and the flash stores)."""
    buf = c.create_string_buffer(RECORD_MAX)
    n = native.load().comp2d_encode(c.byref(cm), buf, RECORD_MAX)
    if n == 0:
        raise UserError(f"{cm.nx} x {cm.ny} nodes: the drive holds at most {NODES_MAX}")
    return buf.raw[:n]


def decode_record(data: bytes) -> native.Comp2dMap:
    """The map of a record read back from the drive (comp2d_decode)."""
    cm = native.Comp2dMap()
    rc = native.load().comp2d_decode(bytes(data), len(data), c.byref(cm))
    if rc != 0:
        raise UserError(f"not a 2-D map record (comp2d error {rc})")
    return cm


def check(cm: native.Comp2dMap, lo_mm, hi_mm) -> None:
    """comp2d_check on the drive's code; UserError naming the refusal."""
    lib = native.load()
    lo = (c.c_int64 * 2)(*(round(v * 1e6) for v in lo_mm))
    hi = (c.c_int64 * 2)(*(round(v * 1e6) for v in hi_mm))
    rc = lib.comp2d_check(c.byref(cm), lo, hi)
    if rc != 0:
        why = {
            "version": f"map version {cm.version}, the drive reads version {VERSION}",
            "memory": f"{cm.nx} x {cm.ny} nodes: the drive holds at most {NODES_MAX} (2 <= nx, ny)",
            "step": "node spacing outside 0.066 mm .. 1 m, or values beyond +-8.4 mm",
            "field": f"the map does not fit the drive's field {list(lo_mm)} .. {list(hi_mm)} mm",
        }[ERRORS[rc]]
        raise UserError(f"2-D map refused ({ERRORS[rc]}): {why}")
    lib.comp2d_prepare(c.byref(cm))


def correct(cm: native.Comp2dMap, x_mm: float, y_mm: float, wx: float, wy: float):
    """(corr_x, corr_y) in um as the drive computes them (comp2d_correct)."""
    lib = native.load()
    raw = (c.c_int64 * 2)(round(x_mm * 1e6), round(y_mm * 1e6))
    w = (c.c_int32 * 2)(round(wx * (1 << 30)), round(wy * (1 << 30)))
    out = (c.c_int64 * 2)()
    lib.comp2d_correct(c.byref(cm), raw, w, out)
    return (out[0] - raw[0]) * 1e-3, (out[1] - raw[1]) * 1e-3


def write_csv(m: Map2D, path: str) -> None:
    with open(path, "w") as fh:
        fh.write(
            f"# comp2d v{VERSION} nx={m.nx} ny={m.ny} x0_mm={m.x0:g} dx_mm={m.dx:g}"
            f" y0_mm={m.y0:g} dy_mm={m.dy:g}\n{HEADER}\n"
        )
        for iy in range(m.ny):
            for ix in range(m.nx):
                v = [m.g[a, k, iy, ix] for a in range(2) for k in range(3)]
                fh.write(
                    f"{m.x0 + ix * m.dx:.3f},{m.y0 + iy * m.dy:.3f},"
                    + ",".join(f"{e:.3f}" for e in v)
                    + "\n"
                )


def read_csv(path: str) -> Map2D:
    rows = []
    with open(path) as fh:
        lines = [ln.strip() for ln in fh if ln.strip() and not ln.startswith("#")]
    if not lines or lines[0] != HEADER:
        raise UserError(f"{path}: not a 2-D map file (header {HEADER})")
    for n, ln in enumerate(lines[1:], 2):
        try:
            rows.append([float(v) for v in ln.split(",")])
        except ValueError:
            raise UserError(f"{path}: line {n}: not numbers") from None
        if len(rows[-1]) != 8:
            raise UserError(f"{path}: line {n}: 8 values expected")
    a = np.array(rows)
    a = a[np.lexsort((a[:, 0], a[:, 1]))]  # y outer, x inner
    xs, ys = np.unique(a[:, 0]), np.unique(a[:, 1])
    if len(xs) < 2 or len(ys) < 2 or len(a) != len(xs) * len(ys):
        raise UserError(f"{path}: the nodes are not a full grid")
    dx, dy = xs[1] - xs[0], ys[1] - ys[0]
    if not (np.allclose(np.diff(xs), dx) and np.allclose(np.diff(ys), dy)):
        raise UserError(f"{path}: the nodes are not evenly spaced")
    g = a[:, 2:].reshape(len(ys), len(xs), 2, 3).transpose(2, 3, 0, 1)
    return Map2D(float(xs[0]), float(dx), float(ys[0]), float(dy), np.ascontiguousarray(g))
