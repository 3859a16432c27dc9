"""Files of a calibration: the table CSV, LinuxCNC's COMP_FILE, the drive's
compensation record, and the import CSV of a separate instrument.

Table CSV (``--out``): one row per point, the data README's columns plus the
corrections the drive applies (all mm)::

    position_mm,n_pos,n_neg,mean_err_pos_mm,std_pos_mm,mean_err_neg_mm,std_neg_mm,
    systematic_mm,hysteresis_mm,random_95_mm,correction_fwd_mm,correction_rev_mm

LinuxCNC COMP_FILE (``--comp-file``, ``[JOINT_n] COMP_FILE`` with
``COMP_FILE_TYPE``), one line per point ``nominal forward reverse`` in
machine units (mm), increasing nominal:

- type 0: forward / reverse = the true position when the joint was commanded
  to ``nominal`` moving +x / -x, i.e. ``nominal - error``;
- type 1: forward / reverse = the offset true - nominal, i.e. ``-error``.

Import CSV (``contour calibrate --import``): readings of an instrument taken
separately (laser interferometer, grid encoder, gauge), one reading per row::

    # comment lines start with '#'
    position_mm,reading_mm,direction
    -75.000,-74.973,+
    -75.000,-74.971,-

``position_mm`` is where the drive's encoder said the axis was (the commanded
target), ``reading_mm`` what the instrument read there, ``direction`` the
direction of approach: ``+``/``pos``/``1`` (moving +x) or ``-``/``neg``/``-1``.
Several rows per position and direction are several readings. error =
position - reading (encoder - reference). Every position needs both
directions.

Compensation record: the layout of firmware/core/comp.h (32-byte header with
CRC-32s, then i64 position nm, i32 forward and reverse correction nm per
point), built here exactly as comp_record_encode builds it.
"""

from __future__ import annotations

import csv
import math
import struct
import zlib
from collections.abc import Iterable
from pathlib import Path

from contour.calibration.analysis import ErrorMap, analyse, from_summary
from contour.errors import UserError

TABLE_COLUMNS = [
    "position_mm",
    "n_pos",
    "n_neg",
    "mean_err_pos_mm",
    "std_pos_mm",
    "mean_err_neg_mm",
    "std_neg_mm",
    "systematic_mm",
    "hysteresis_mm",
    "random_95_mm",
    "correction_fwd_mm",
    "correction_rev_mm",
]

RECORD_MAGIC = 0x504D4343  # "CCMP"
RECORD_FORMAT = 1
RECORD_HDR = 32
POINT_BYTES = 16
POINTS_MAX = 126  # COMP_POINTS_MAX
CORR_MAX_NM = 1_000_000  # COMP_CORR_MAX_NM
RAMP_MAX_US = 1_000_000


def _fmt(v: float) -> str:
    if isinstance(v, int):
        return str(v)
    if math.isnan(v):
        return ""
    return f"{v:.6f}"


def write_table_csv(path: str, errmap: ErrorMap) -> None:
    try:
        with open(path, "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f)
            w.writerow(TABLE_COLUMNS)
            for p in errmap.points:
                d = p.as_dict()
                w.writerow([_fmt(d[c]) for c in TABLE_COLUMNS])
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from None


def read_table_csv(path: str) -> ErrorMap:
    """A table CSV written by write_table_csv (or by hand with at least
    position_mm, mean_err_pos_mm, mean_err_neg_mm)."""
    rows = _read_csv(path)
    pts = []
    for line, r in rows:
        try:
            pos = float(r["position_mm"])
            mp = float(r["mean_err_pos_mm"])
            mn = float(r["mean_err_neg_mm"])
            sp = float(r["std_pos_mm"]) if r.get("std_pos_mm") else math.nan
            sn = float(r["std_neg_mm"]) if r.get("std_neg_mm") else math.nan
            npos = int(r["n_pos"]) if r.get("n_pos") else 0
            nneg = int(r["n_neg"]) if r.get("n_neg") else 0
        except KeyError as exc:
            raise UserError(f"{path}: missing column {exc.args[0]}") from None
        except ValueError as exc:
            raise UserError(f"{path}:{line}: {exc}") from None
        pts.append(from_summary(pos, mp, sp, mn, sn, npos, nneg))
    _check_positions(path, [p.position_mm for p in pts])
    return ErrorMap(points=pts, source=path)


def _check_positions(path: str, pos: list) -> None:
    if not pos:
        raise UserError(f"{path}: no points")
    for a, b in zip(pos, pos[1:]):
        if not b > a:
            raise UserError(f"{path}: positions must increase ({a:g} then {b:g})")


def _read_csv(path: str) -> list:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise UserError(f"{path}: not a text (UTF-8) file") from None
    lines = [(i + 1, ln) for i, ln in enumerate(text.splitlines())]
    body = [(i, ln) for i, ln in lines if ln.strip() and not ln.lstrip().startswith("#")]
    if not body:
        raise UserError(f"{path}: empty (no header line)")
    reader = csv.reader([ln for _, ln in body])
    header = [h.strip() for h in next(reader)]
    out = []
    for (line, _), row in zip(body[1:], reader):
        if len(row) != len(header):
            raise UserError(f"{path}:{line}: {len(row)} fields, the header has {len(header)}")
        out.append((line, {h: v.strip() for h, v in zip(header, row)}))
    return out


DIRECTIONS = {"+": 1, "pos": 1, "1": 1, "+1": 1, "-": -1, "neg": -1, "-1": -1}


def read_import_csv(path: str) -> list:
    """Readings of the import CSV as (position_mm, direction, error_mm)."""
    rows = _read_csv(path)
    out = []
    for line, r in rows:
        for col in ("position_mm", "reading_mm", "direction"):
            if col not in r:
                raise UserError(
                    f"{path}: missing column {col!r} (expected position_mm,reading_mm,direction)"
                )
        try:
            pos = float(r["position_mm"])
            reading = float(r["reading_mm"])
        except ValueError:
            raise UserError(f"{path}:{line}: position_mm and reading_mm must be numbers") from None
        if not (math.isfinite(pos) and math.isfinite(reading)):
            raise UserError(f"{path}:{line}: not a finite number")
        d = DIRECTIONS.get(r["direction"].lower())
        if d is None:
            raise UserError(f"{path}:{line}: direction {r['direction']!r} is not + or -")
        out.append((pos, d, pos - reading))
    if not out:
        raise UserError(f"{path}: no readings")
    return out


def import_errmap(path: str, axis: str = "") -> ErrorMap:
    return analyse(read_import_csv(path), axis=axis, source=path)


def write_comp_file(path: str, errmap: ErrorMap, comp_type: int = 0) -> None:
    """LinuxCNC COMP_FILE of COMP_FILE_TYPE comp_type (0 or 1), mm."""
    if comp_type not in (0, 1):
        raise UserError(f"--comp-type {comp_type}: LinuxCNC knows types 0 and 1")
    lines = []
    for p in errmap.points:
        if comp_type == 0:
            fwd = p.position_mm - p.mean_err_pos_mm
            rev = p.position_mm - p.mean_err_neg_mm
        else:
            fwd = -p.mean_err_pos_mm
            rev = -p.mean_err_neg_mm
        lines.append(f"{p.position_mm:.6f} {fwd:.6f} {rev:.6f}")
    try:
        Path(path).write_text("\n".join(lines) + "\n", encoding="ascii")
    except OSError as exc:
        raise UserError(f"cannot write {path}: {exc.strerror}") from None


def read_thesis_table(path: str, table: str) -> ErrorMap:
    """One table of encoder_calibration_kgm101.csv as an ErrorMap (its own
    systematic/hysteresis/random columns are recomputed from the means and
    standard deviations; see tests)."""
    rows = _read_csv(path)
    pts = []
    for _, r in rows:
        if r["table"] != table:
            continue
        pts.append(
            from_summary(
                float(r["position_mm"]),
                float(r["mean_err_pos_mm"]),
                float(r["std_pos_mm"]),
                float(r["mean_err_neg_mm"]),
                float(r["std_neg_mm"]),
            )
        )
    if not pts:
        raise UserError(f"{path}: no rows of table {table}")
    pts.sort(key=lambda p: p.position_mm)
    return ErrorMap(points=pts, source=f"{path} table {table}")


# ---- the drive's compensation record (firmware/core/comp.h) -------------------


def corrections_nm(errmap: ErrorMap) -> list:
    """(position nm, forward correction nm, reverse correction nm) per point."""
    out = []
    for p in errmap.points:
        pos = round(p.position_mm * 1e6)
        fwd = round(-p.mean_err_pos_mm * 1e6)
        rev = round(-p.mean_err_neg_mm * 1e6)
        for what, v in (("forward", fwd), ("reverse", rev)):
            if abs(v) > CORR_MAX_NM:
                raise UserError(
                    f"{what} correction {v / 1000:.1f} um at {p.position_mm:g} mm exceeds the "
                    f"drive's limit of {CORR_MAX_NM / 1000:.0f} um: is the reference right?"
                )
        out.append((pos, fwd, rev))
    return out


def encode_record(
    points: Iterable, axis: int, ramp_us: int = 20000, version: int = 0, flags: int = 0
) -> bytes:
    pts = list(points)
    if len(pts) > POINTS_MAX:
        raise UserError(f"{len(pts)} points: the drive's table holds at most {POINTS_MAX}")
    if not 0 <= ramp_us <= RAMP_MAX_US:
        raise UserError(f"reversal ramp {ramp_us} us outside 0..{RAMP_MAX_US}")
    for a, b in zip(pts, pts[1:]):
        if not b[0] > a[0]:
            raise UserError("compensation positions must increase")
    data = b"".join(struct.pack("<qii", int(p), int(f), int(r)) for p, f, r in pts)
    hdr = struct.pack(
        "<IHBBIHHIII",
        RECORD_MAGIC,
        RECORD_FORMAT,
        axis,
        flags,
        version,
        len(pts),
        0,
        ramp_us,
        zlib.crc32(data),
        0,
    )
    hdr += struct.pack("<I", zlib.crc32(hdr))
    return hdr + data


def decode_record(buf: bytes) -> dict:
    if len(buf) < RECORD_HDR:
        raise UserError("compensation record shorter than its header")
    magic, fmt, axis, flags, version, n, _, ramp, dcrc, _, hcrc = struct.unpack_from(
        "<IHBBIHHIIII", buf
    )
    if magic != RECORD_MAGIC or fmt != RECORD_FORMAT:
        raise UserError("not a compensation record")
    if zlib.crc32(buf[:28]) != hcrc:
        raise UserError("compensation record header CRC mismatch")
    if len(buf) != RECORD_HDR + POINT_BYTES * n:
        raise UserError("compensation record length mismatch")
    data = buf[RECORD_HDR:]
    if zlib.crc32(data) != dcrc:
        raise UserError("compensation record data CRC mismatch")
    pts = [struct.unpack_from("<qii", data, POINT_BYTES * i) for i in range(n)]
    return {"axis": axis, "version": version, "ramp_us": ramp, "data_crc": dcrc, "points": pts}
