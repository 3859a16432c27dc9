"""Machine profiles: the limits and habits of one machine, in TOML.

A profile has a ``[motion]`` table (path-level settings), one
``[axes.<A>]`` table per linear axis (X, Y, Z), optional tables of the rotary
axes (A, B, C: velocity and acceleration limits) and optional per-model option
tables (``[camargo2017]``). Every field is listed in :data:`MOTION_FIELDS`
and :data:`AXIS_FIELDS` with its unit, its meaning and how to measure it;
``docs/estimation.md`` carries the same table. Unknown keys are an error (a
typo must not silently fall back to a default).

Field names end in their unit: ``_mm_min`` (mm/min), ``_mm_s2`` (mm/s²),
``_mm_s3`` (mm/s³), ``_mm``, ``_s``.
"""

from __future__ import annotations

import copy
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from contour.errors import UserError
from contour.estimation.camargo2017 import OPTIONS as CAMARGO_OPTIONS
from contour.estimation.fields import Field
from contour.planner import PlannerProfile

# the drive's defaults (its generated parameter table): the path rules of a
# profile that does not set them are the drive's
_DRIVE = PlannerProfile()

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python < 3.11
    import tomli as tomllib

AXIS_NAMES = ("X", "Y", "Z")


AXIS_FIELDS = (
    Field(
        "max_velocity_mm_min",
        "mm/min",
        30000.0,
        "Highest speed of the axis (its rapid rate).",
        "Machine data sheet, or time a long G0 move on this axis alone and "
        "divide its length by the time once the speed is constant.",
        low=1e-3,
        high=1e6,
    ),
    Field(
        "max_acceleration_mm_s2",
        "mm/s²",
        2000.0,
        "Acceleration limit of the axis on the path.",
        "Run the reversal test (+S/-S repeated, exp3 of camargo2017) for S of "
        "0.2 to 1 mm: a rest-to-rest move takes about 2*sqrt(S/a). Or fit it "
        "with `contour fit-profile`.",
        low=1e-6,
        high=1e7,
    ),
    Field(
        "max_jerk_mm_s3",
        "mm/s³",
        50000.0,
        "Jerk limit of the axis (S-curve profiles).",
        "The reversal test with S of 0.001 to 0.05 mm: short moves take about (32*S/j)^(1/3).",
        low=1e-6,
        high=1e10,
    ),
    Field(
        "corner_acceleration_mm_s2",
        "mm/s²",
        1000.0,
        "Smoothed-corner rule only: the corner speed is "
        "min_i sqrt(corner_acceleration_i * l / |du_i|), l the mean length of "
        "the two blocks, du_i the change of the unit direction on axis i.",
        "Staircases with small direction changes (exp2 of camargo2017): run "
        "them and fit with `contour fit-profile`.",
        high=1e7,
    ),
    Field(
        "corner_velocity_step_mm_min",
        "mm/min",
        300.0,
        "Velocity-step rule only: the largest step of this axis's velocity "
        "allowed at a corner without slowing down (v = min_i step_i / |du_i|).",
        "The control's data (e.g. grbl-like 'jerk' settings), or fit it on "
        "corner tests with `contour fit-profile`.",
        high=1e6,
    ),
)

ROTARY_NAMES = ("A", "B", "C")

ROTARY_FIELDS = (
    Field(
        "max_velocity_deg_min",
        "deg/min",
        7200.0,
        "Highest speed of the rotary axis (20 rev/min by default). A block that "
        "moves it with X Y Z runs no faster than lets the rotary axis keep up "
        "(machine-axis kinematics: the rotary motion is synchronised with the "
        "linear one, no tool-tip transformation).",
        "Machine data sheet, or time a G0 of several turns and divide.",
        low=1e-3,
        high=1e7,
    ),
    Field(
        "max_acceleration_deg_s2",
        "deg/s²",
        3600.0,
        "Acceleration limit of the rotary axis: a block that moves only rotary "
        "axes is timed rest to rest with it.",
        "Time short indexing moves (G0 C5, G0 C0 ...): a rest-to-rest move of "
        "D degrees takes about 2*sqrt(D/a).",
        low=1e-6,
        high=1e8,
    ),
)

MOTION_FIELDS = (
    Field(
        "rapid_feed_mm_min",
        "mm/min",
        30000.0,
        "Path speed of G0 moves (each axis is still held to its own limit).",
        "Machine data sheet (rapid traverse), or time a long G0 move.",
        low=1e-3,
        high=1e6,
    ),
    Field(
        "min_block_time_s",
        "s",
        0.001,
        "Minimum block time: the control's block processing time.",
        "Run a long staircase of tiny collinear blocks (0.001 mm at F15000, "
        "exp1 of camargo2017): time / blocks. 0 turns it off.",
        zero_ok=True,
        high=10.0,
    ),
    Field(
        "block_time_rule",
        "",
        "throughput",
        "How the minimum block time acts: 'throughput' (any n consecutive "
        "blocks take at least n times it, the look-ahead smooths single short "
        "blocks) or 'cap' (every block takes at least it: the speed of each "
        "short block is capped).",
        "Compare a run of short blocks between long ones with the same run "
        "alone (exp1 of camargo2017 fits 'throughput').",
        choices=("throughput", "cap"),
    ),
    Field(
        "min_block_time_window_blocks",
        "blocks",
        16,
        "Throughput rule: a block runs no faster than the mean length of its "
        "last this-many blocks per minimum block time (1 is the same as 'cap').",
        "Keep 16 unless a control is known to buffer fewer blocks; it only "
        "matters for short blocks mixed with long ones.",
        high=65.0,
    ),
    Field(
        "corner_rule",
        "",
        _DRIVE.corner,
        "Cornering rule of the planner: 'junction-deviation' (the drive's "
        "default: speed through a corner from the junction deviation and the "
        "acceleration), 'smoothed-corner' (the corner is rounded over half "
        "of each neighbouring block and its speed limited by the per-axis "
        "corner acceleration; imitates controls such as the iTNC530), "
        "'velocity-step' (per-axis velocity step) or 'exact-stop' (stop at "
        "every junction). Every rule stops at an axis reversal.",
        "Choose 'smoothed-corner' to imitate a control measured with the "
        "Camargo experiments; keep the default for this drive.",
        choices=("junction-deviation", "smoothed-corner", "velocity-step", "exact-stop"),
    ),
    Field(
        "junction_deviation_mm",
        "mm",
        _DRIVE.junction_deviation_mm,
        "Cornering tolerance: the deviation from the corner allowed at the "
        "junction speed (junction-deviation rule).",
        "The path tolerance the user accepts (CAM tolerance order); larger is faster.",
        high=1000.0,
    ),
    Field(
        "velocity_profile",
        "",
        _DRIVE.shape,
        "Shape of the speed profile of each block: 's-curve' (jerk-limited), "
        "'trapezoid' (acceleration-limited), 's-curve-at-rest' (jerk-limited "
        "only for a block that starts or ends at rest: job start and end, exact "
        "stop, reversal, dwell; every other block is a trapezoid) or "
        "'s-curve-continuous' (jerk-limited, the acceleration continuous across "
        "blocks: a run of blocks is planned as one profile).",
        "What the drive (or the imitated control) does; 's-curve-continuous' for "
        "this drive (its default; not with the smoothed-corner rule). "
        "'s-curve-at-rest' imitates a control whose acceleration stays "
        "continuous along a path (jerk then shows only at starts and stops: "
        "fit max_jerk_mm_s3 on short reversals, exp3 of camargo2017).",
        choices=("s-curve", "trapezoid", "s-curve-at-rest", "s-curve-continuous"),
    ),
    Field(
        "arc_chord_tolerance_mm",
        "mm",
        0.001,
        "Arcs are split into chords that deviate from the arc by at most this.",
        "The chord tolerance of the drive; CAM tolerance order.",
        high=1000.0,
    ),
    Field(
        "lookahead_blocks",
        "blocks",
        64,
        "Depth of the planner's look-ahead buffer.",
        "Fixed by the drive's build (64); for another control, its data sheet.",
        low=1.0,
        high=65536.0,
    ),
)

# Options of the camargo2017 model (``[camargo2017]`` table).
CAMARGO_FIELDS = CAMARGO_OPTIONS


def _field_map(fields) -> dict:
    return {f.name: f for f in fields}


@dataclass
class Profile:
    """A loaded and validated profile. ``data`` is the nested dict."""

    data: dict
    path: Optional[str] = None

    @property
    def name(self) -> str:
        return str(self.data.get("name", ""))

    @property
    def motion(self) -> dict:
        return self.data["motion"]

    def axis(self, name: str) -> dict:
        return self.data["axes"][name]

    def axis_values(self, key: str) -> list:
        return [self.data["axes"][a][key] for a in AXIS_NAMES]

    def rotary_values(self, key: str) -> list:
        """A rotary field of A, B, C (``max_velocity_deg_min`` ...)."""
        return [self.data["axes"][a][key] for a in ROTARY_NAMES]

    def options(self, table: str) -> dict:
        return dict(self.data.get(table, {}))

    def get(self, path: str):
        node = self.data
        for part in path.split("."):
            node = node[part]
        return node

    def with_values(self, values: dict) -> Profile:
        """A copy with dotted-path values replaced (``axes.X.max_jerk_mm_s3``)."""
        data = copy.deepcopy(self.data)
        for path, value in values.items():
            parts = path.split(".")
            node = data
            for part in parts[:-1]:
                node = node[part]
            node[parts[-1]] = value
        return Profile(validate(data, self.path or "<profile>"), self.path)


def _check_value(f: Field, value, where: str):
    if f.choices:
        if value not in f.choices:
            raise UserError(
                f"{where}: {f.name} must be one of {', '.join(f.choices)}, got {value!r}"
            )
        return value
    if isinstance(f.default, bool):
        if not isinstance(value, bool):
            raise UserError(f"{where}: {f.name} must be true or false")
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserError(f"{where}: {f.name} must be a number ({f.unit}), got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and (f.low < v < f.high or (f.zero_ok and v == 0))):
        raise UserError(
            f"{where}: {f.name} must be a {'non-negative' if f.zero_ok else 'positive'} "
            f"finite number ({f.unit}), got {value!r}"
        )
    if isinstance(f.default, int):
        if v != int(v):
            raise UserError(f"{where}: {f.name} must be a whole number, got {value!r}")
        return int(v)
    return v


def _check_table(table, fields, where: str, fill: bool) -> dict:
    if not isinstance(table, dict):
        raise UserError(f"{where} must be a table")
    known = _field_map(fields)
    out = {}
    for key, value in table.items():
        f = known.get(key)
        if f is None:
            raise UserError(f"{where}: unknown field '{key}' (known: {', '.join(known)})")
        out[key] = _check_value(f, value, where)
    if fill:
        for f in fields:
            out.setdefault(f.name, f.default)
    return out


def validate(data: dict, where: str) -> dict:
    """Checked copy of a profile dict with every default filled in."""
    if not isinstance(data, dict):
        raise UserError(f"{where}: a profile is a TOML table")
    out: dict = {}
    for key, value in data.items():
        if key in ("name", "description"):
            if not isinstance(value, str):
                raise UserError(f"{where}: {key} must be a string")
            out[key] = value
        elif key == "motion":
            out[key] = _check_table(value, MOTION_FIELDS, f"{where} [motion]", False)
        elif key == "axes":
            if not isinstance(value, dict):
                raise UserError(f"{where}: [axes] must hold one table per axis")
            axes = {}
            for axis, table in value.items():
                if axis in ROTARY_NAMES:
                    axes[axis] = _check_table(table, ROTARY_FIELDS, f"{where} [axes.{axis}]", True)
                    continue
                if axis not in AXIS_NAMES:
                    names = ", ".join(AXIS_NAMES + ROTARY_NAMES)
                    raise UserError(f"{where}: unknown axis '{axis}' (profiles describe {names})")
                axes[axis] = _check_table(table, AXIS_FIELDS, f"{where} [axes.{axis}]", True)
            out[key] = axes
        elif key == "camargo2017":
            out[key] = _check_table(value, CAMARGO_FIELDS, f"{where} [camargo2017]", False)
        else:
            raise UserError(
                f"{where}: unknown table or key '{key}' (known: name, description, motion, "
                "axes, camargo2017)"
            )
    out["motion"] = _check_table(out.get("motion", {}), MOTION_FIELDS, f"{where} [motion]", True)
    axes = out.setdefault("axes", {})
    for axis in AXIS_NAMES:
        if axis not in axes:
            axes[axis] = _check_table({}, AXIS_FIELDS, f"{where} [axes.{axis}]", True)
    for axis in ROTARY_NAMES:
        if axis not in axes:
            axes[axis] = _check_table({}, ROTARY_FIELDS, f"{where} [axes.{axis}]", True)
    out["camargo2017"] = _check_table(
        out.get("camargo2017", {}), CAMARGO_FIELDS, f"{where} [camargo2017]", True
    )
    return out


def load(path) -> Profile:
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise UserError(f"cannot read profile {p}: {exc.strerror}") from exc
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise UserError(f"{p}: not a valid TOML file: {exc}") from exc
    return Profile(validate(data, str(p)), str(p))


def default() -> Profile:
    return Profile(validate({}, "<defaults>"), None)


# ---- writing ----------------------------------------------------------------


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(float(f"{v:.6g}"))
    s = str(v).replace("\\", "\\\\").replace('"', '\\"')
    return f'"{s}"'


def _comment_lines(text: str, width: int = 88) -> list:
    words = text.split()
    lines, cur = [], "#"
    for w in words:
        if len(cur) + 1 + len(w) > width:
            lines.append(cur)
            cur = "#"
        cur += " " + w
    if cur != "#":
        lines.append(cur)
    return lines


def _table(lines: list, header: str, values: dict, fields, comments: bool) -> None:
    lines.append("")
    lines.append(f"[{header}]")
    for f in fields:
        if f.name not in values:
            continue
        if comments:
            unit = f" [{f.unit}]" if f.unit else ""
            lines.extend(_comment_lines(f"{f.name}{unit}: {f.doc}"))
        lines.append(f"{f.name} = {_toml_value(values[f.name])}")


def dumps(profile: Profile, header: str = "", comments: bool = True) -> str:
    """TOML text of a profile; ``header`` is written as leading comments."""
    data = profile.data
    lines = []
    for h in header.splitlines():
        lines.append(("# " + h) if h else "#")
    if header:
        lines.append("")
    if data.get("name"):
        lines.append(f"name = {_toml_value(data['name'])}")
    if data.get("description"):
        lines.append(f"description = {_toml_value(data['description'])}")
    _table(lines, "motion", data["motion"], MOTION_FIELDS, comments)
    for axis in AXIS_NAMES:
        _table(lines, f"axes.{axis}", data["axes"][axis], AXIS_FIELDS, comments and axis == "X")
    for axis in ROTARY_NAMES:
        _table(lines, f"axes.{axis}", data["axes"][axis], ROTARY_FIELDS, comments and axis == "A")
    _table(lines, "camargo2017", data["camargo2017"], CAMARGO_FIELDS, comments)
    return "\n".join(lines) + "\n"


def save(profile: Profile, path, header: str = "") -> None:
    try:
        Path(path).write_text(dumps(profile, header), encoding="utf-8")
    except OSError as exc:
        raise UserError(f"cannot write profile {path}: {exc.strerror}") from exc
