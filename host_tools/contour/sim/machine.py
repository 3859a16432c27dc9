"""Machine descriptions (TOML) for the simulator, and applying one to it.

A machine file selects the axis model and its parameters, the control tick,
the planner limits, the gain sets and the feed-forward. Layout (every key is
optional except where noted; units SI unless the name says otherwise)::

    name = "default"
    tick_hz = 10000                 # control tick, Hz (the thesis ran 333 Hz = 3 ms)
    axes = 3                        # 1..3
    encoder_model = "fast"          # fast|edges: how encoder edges reach the
                                    # decoder (docs/simulator.md, "Encoder models")

    [axis.all]                      # applied to every axis, then [axis.x] etc.
    model = "lacerda1998"           # the only model so far (5th-order two-inertia)
    lead_mm = 5.0                   # screw lead: l = lead / (2 pi)
    B = 2.1e-6  K = 110.0  kb = 0.21  kt = 0.2  La = 6.7e-3  I1 = 2.7e-5
    I2 = 8.3e-6  Ra = 9.0  kx = 16.0  vmax = 160.0
    encoder_lines = 1000            # quadrature counting: 4 counts per line
    encoder_noise_counts = 0.0      # rms reading noise, counts (0: off)
    ref_resolution_nm = 1.0         # reference scale (true table position)
    ref_noise_nm = 0.0              # rms reading noise of the reference scale, nm
    load_torque = 0.0               # N m, motor side
    coulomb_motor = 0.0             # N m (0: off)
    coulomb_table = 0.0             # N (0: off)
    backlash_um = 0.0               # total lost motion, um (0: off)
    pitch_map = [[pos_mm, err_fwd_um, err_rev_um], ...]   # (absent: off)
    pitch_dir_band_um = 1.0
    seed = 1                        # noise generator
    home_switch_mm = -21.3          # home switch edge, table position (hal_home_switch)
    home_side = -1                  # -1: active at <= the edge, +1: at >=, 0: no switch
    encoder_index = 1               # 1: one index pulse per motor turn, 0: none
    index_phase_counts = 0          # counts from position 0 to an index pulse

    [planner]                       # per-axis limits (same for every axis)
    v_max = 1.0   a_max = 20.0   j_max = 2000.0   junction_dev = 1e-5
    arc_chord = 1e-7

    [servo]
    ferr_limit_mm = 50.0            # following-error fault limit (0: off)
    sat_limit_s = 0.5               # output saturated this long: fault (0: off)
    stop_decel = 1.0                # controlled stop, m/s^2
    encoder_mean = 0                # 1: the loops see each encoder's mean over the
                                    # tick, the reference at the same mean time
                                    # (drive.h enc_mean; docs/simulator.md)
    encoder_interp = 0              # 1: the position below the count from the
                                    # edge times (drive.h enc_interp, enc_interp.h)
    cec_thesis_form = 0             # 1: the curvature CEC uses the thesis's series
                                    # E.n + s r (sec g - 1) instead of the distance
                                    # from the circle of curvature (cec.h)

    [gains.axis]                    # axis PIDs (every axis) ...
    kp = 1500.0  ki = 8000.0  kd = 5.0  d_tau = 1e-4  d_on_measurement = false
    [gains.axis_y]                  # ... per-axis overrides (axis_x, axis_y, axis_z)
    [gains.cec]                     # the contour-error controller's PID
    kp = 0.0  ki = 0.0  kd = 0.0  d_tau = 0.0
    [gains.cec_line]                # optional: the CEC's gains on straight path
                                    # (the thesis's line/curve switching, cec.h)

    [feedforward]                   # used by --feedforward velocity|full
    mode = "none"                   # none|velocity|full: used when the caller
                                    # gives none (sim serve without --feedforward)
    # model values when absent: kvff = kb / (kx l), kaff = Ra (I1 + I2) / (kt kx l)
    scale = 1.0                     # all feed-forward gains times this
    scale_x = 1.0                   # per-axis factor on top (scale_y, scale_z)
    kvff_x = ...  kaff_x = ...      # per-axis gains (kvff_y ...), before kvff / kaff
    friction = 0.0                  # fraction of the Coulomb friction fed forward
    friction_band = 1.0             # mm/s: the friction feed-forward's sign ramp
    advance_ticks = 0.0             # velocity feed-forward taken this many ticks
                                    # ahead (0.5: the zero-order hold's delay; drive.h)
    quadrant_comp = 0               # 1: quadrant-glitch compensation (drive.h qg_comp;
                                    # needs friction > 0)
    learn_rate = 0.0                # 1/s: with a CEC, the feed-forward scale per
                                    # axis learned from the contour error (servo.h)

    [disturbance]                   # load forces on the tables (sim.h, "Disturbances");
                                    # all 0 (the default): off, traces bit-identical
    f_at = 0.0                      # N, F_at sgn(v_ref) on X and on Y (thesis eq. 4.3)
    f_w = 0.0                       # N, cutting force F_w (eq. 4.3), or from
    k_s = 0.0                       #   F_w = k_s s^0.73 p: k_s in N/mm^1.73,
    feed_per_tooth_mm = 0.0         #   s (mm per tooth) and
    depth_mm = 0.0                  #   p (depth of cut, mm)
    phi_deg = 45.0                  # the thesis's phi
    spring_x = 0.0                  # N/mm, a spring on the X table (spring_y, spring_z),
    spring_x0_mm = 0.0              # relaxed at this table position (spring_y0_mm, ...)

Gains are in volts at the amplifier input per metre (the thesis's units).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

from contour.errors import UserError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

REPO = Path(__file__).resolve().parents[3]
MACHINES = REPO / "hil_sim" / "machines"
AXES = "xyz"

LACERDA = {
    "B": 2.10e-6,
    "K": 1.10e2,
    "kb": 2.10e-1,
    "kt": 2.00e-1,
    "La": 6.70e-3,
    "I1": 2.70e-5,
    "Ra": 9.00,
    "kx": 16.0,
    "vmax": 160.0,
}
I2 = {"x": 8.30e-6, "y": 3.50e-6, "z": 8.30e-6}

AXIS_KEYS = {
    "model",
    "lead_mm",
    *LACERDA,
    "I2",
    "encoder_lines",
    "encoder_noise_counts",
    "ref_resolution_nm",
    "ref_noise_nm",
    "load_torque",
    "coulomb_motor",
    "coulomb_table",
    "backlash_um",
    "pitch_map",
    "pitch_dir_band_um",
    "seed",
    "home_switch_mm",
    "home_side",
    "encoder_index",
    "index_phase_counts",
}
# Physical ranges of the axis keys (inclusive): beyond them the model or the
# drive's fixed-point scales (encoder counts, lead in pm) overflow, or the
# model's time constants become so short that setting it up never ends
# (I1 = 1e-308).
AXIS_RANGES = {
    "lead_mm": (1e-3, 1e6),
    "B": (0.0, 1e3),
    "K": (0.0, 1e9),
    "kb": (1e-6, 1e3),
    "kt": (1e-6, 1e3),
    "La": (1e-7, 1e3),
    "I1": (1e-9, 1e3),
    "I2": (1e-9, 1e3),
    "Ra": (1e-4, 1e6),
    "kx": (1e-6, 1e6),
    "vmax": (1e-3, 1e6),
    "encoder_lines": (1.0, 2.5e11),
    "encoder_noise_counts": (0.0, 1e6),
    "ref_resolution_nm": (1e-6, 1e6),
    "ref_noise_nm": (0.0, 1e6),
    "load_torque": (-1e6, 1e6),
    "coulomb_motor": (0.0, 1e6),
    "coulomb_table": (0.0, 1e9),
    "backlash_um": (0.0, 1e6),
    "pitch_dir_band_um": (0.0, 1e6),
    "seed": (0.0, 2.0**53),
    "home_switch_mm": (-1e6, 1e6),
    "home_side": (-1.0, 1.0),
    "encoder_index": (0.0, 1.0),
    "index_phase_counts": (0.0, 1e12),
}
PLAN_MAX = {"v_max": 4.29, "a_max": 1e6, "j_max": 1e8, "junction_dev": 1.0, "arc_chord": 1.0}
GAIN_MAX = 1e12
GAIN_KEYS = {"kp", "ki", "kd", "d_tau", "d_on_measurement", "kt", "i_max", "out_max"}
PLAN_KEYS = {"v_max", "a_max", "j_max", "junction_dev", "arc_chord"}
FF_KEYS = {
    "kvff",
    "kaff",
    "scale",
    "scale_x",
    "scale_y",
    "scale_z",
    "friction",
    "mode",
    "advance_ticks",
    "friction_band",
    "learn_rate",
    "quadrant_comp",
}
FF_KEYS |= {f"{k}_{ax}" for k in ("kvff", "kaff") for ax in "xyz"}
FF_MODES = ("none", "velocity", "full")
SERVO_KEYS = {
    "ferr_limit_mm",
    "sat_limit_s",
    "stop_decel",
    "encoder_mean",
    "encoder_interp",
    "cec_thesis_form",
}
TOP_KEYS = {
    "name",
    "description",
    "tick_hz",
    "axes",
    "axis",
    "planner",
    "servo",
    "gains",
    "feedforward",
    "encoder_model",
    "field2d",
    "disturbance",
}
DIST_KEYS = {
    "f_at",
    "f_w",
    "k_s",
    "feed_per_tooth_mm",
    "depth_mm",
    "phi_deg",
    *(f"spring_{a}" for a in AXES),
    *(f"spring_{a}0_mm" for a in AXES),
}


@dataclass
class Machine:
    name: str
    path: str
    tick_hz: float = 10000.0
    axes: int = 3
    axis: dict = field(default_factory=dict)  # "x" -> params
    planner: dict = field(default_factory=dict)
    servo: dict = field(default_factory=dict)
    gains: dict = field(default_factory=dict)  # "x"/"y"/"z"/"cec" -> gains
    feedforward: dict = field(default_factory=dict)
    ff_mode: str = "none"  # [feedforward] mode: apply()'s default
    encoder_model: str = "fast"  # sim_encoder_model: "fast" or "edges" (the reference)
    description: str = ""
    disturbance: dict = field(default_factory=dict)  # [disturbance], SI after from_dict

    def cutting_f_w(self) -> float:
        """F_w of eq. 4.3 in N: f_w, or k_s s^0.73 p when f_w is absent."""
        d = self.disturbance
        if "f_w" in d:
            return d["f_w"]
        return d.get("k_s", 0.0) * d.get("feed_per_tooth_mm", 0.0) ** 0.73 * d.get("depth_mm", 0.0)

    field2d: dict = field(default_factory=dict)  # [field2d]: lines, band_um (empty: off)

    def l(self, ax: str) -> float:  # noqa: E743 - the model's name for it
        return self.axis[ax]["lead_mm"] * 1e-3 / (2 * math.pi)

    def ff_gains(self, ax: str, mode: str) -> tuple[float, float]:
        """(kvff, kaff) of axis `ax` for --feedforward none|velocity|full."""
        if mode == "none":
            return 0.0, 0.0
        p = self.axis[ax]
        ff = self.feedforward
        scale = ff.get("scale", 1.0) * ff.get(f"scale_{ax}", 1.0)
        kv = ff.get(f"kvff_{ax}", ff.get("kvff", p["kb"] / (p["kx"] * self.l(ax)))) * scale
        ka = ff.get(
            f"kaff_{ax}",
            ff.get("kaff", p["Ra"] * (p["I1"] + p["I2"]) / (p["kt"] * p["kx"] * self.l(ax))),
        )
        return kv, (ka * scale if mode == "full" else 0.0)

    def friction_ff_volts(self, ax: str) -> float:
        """Friction feed-forward at the amplifier input, V (with
        --feedforward full; the drive applies it through the acceleration
        feed-forward channel)."""
        p = self.axis[ax]
        torque = p.get("coulomb_motor", 0.0) + p.get("coulomb_table", 0.0) * self.l(ax)
        return self.feedforward.get("friction", 0.0) * torque * p["Ra"] / (p["kt"] * p["kx"])


def _check_keys(d: dict, allowed: set, where: str, path: str) -> None:
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise UserError(f"{path}: unknown key(s) in {where}: {', '.join(unknown)}")


def _bool(v, key: str, path: str) -> bool:
    if not isinstance(v, bool):
        raise UserError(f"{path}: {key} must be true or false, got {v!r}")
    return v


def _table(v, where: str, path: str) -> dict:
    if not isinstance(v, dict):
        raise UserError(f"{path}: {where} must be a table")
    return v


def _num(v, key: str, path: str, lo: float = -math.inf, hi: float = math.inf) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise UserError(f"{path}: {key} must be a number, got {v!r}")
    if not lo <= v <= hi:
        raise UserError(f"{path}: {key} = {v} is outside {lo:g}..{hi:g}")
    return float(v)


def resolve(name_or_path: str | None) -> Path:
    """A machine file by path, or by name in hil_sim/machines/."""
    if name_or_path is None:
        return MACHINES / "default.toml"
    p = Path(name_or_path)
    if p.exists():
        return p
    q = MACHINES / (name_or_path if name_or_path.endswith(".toml") else f"{name_or_path}.toml")
    if q.exists():
        return q
    raise UserError(f"machine file {name_or_path} not found (nor {q})")


def load(name_or_path: str | None = None) -> Machine:
    path = resolve(name_or_path)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except OSError as exc:
        raise UserError(f"cannot read {path}: {exc.strerror}") from exc
    except UnicodeDecodeError as exc:
        raise UserError(
            f"{path}: not a text (UTF-8) TOML file: {exc.reason} at byte {exc.start}"
        ) from exc
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{path}: invalid TOML: {exc}") from exc
    return from_dict(data, str(path))


def check_encoder_model(name, where: str) -> str:
    from contour.sim.core import ENCODER_MODELS

    if name not in ENCODER_MODELS:
        raise UserError(
            f"{where}: encoder_model must be one of {', '.join(ENCODER_MODELS)}, got {name!r}"
        )
    return str(name)


def add_encoder_model_argument(parser) -> None:
    """--encoder-model of `sim circle`, `sim run` and `sim serve`."""
    parser.add_argument(
        "--encoder-model",
        choices=("fast", "edges"),
        default=None,
        help="how encoder edges reach the drive's decoder: fast (a substep's edges as one "
        "update, the same decoder state) or edges (every edge: the reference); default: the "
        "machine file's, fast if it says nothing",
    )


def from_dict(data: dict, path: str = "<machine>") -> Machine:
    _check_keys(data, TOP_KEYS, "the top level", path)
    m = Machine(name=str(data.get("name", Path(path).stem)), path=path)
    m.description = str(data.get("description", ""))
    m.tick_hz = _num(data.get("tick_hz", 10000), "tick_hz", path, 100, 100000)
    m.axes = int(_num(data.get("axes", 3), "axes", path, 1, 3))
    m.encoder_model = check_encoder_model(data.get("encoder_model", "fast"), path)
    axis = data.get("axis", {})
    if not isinstance(axis, dict):
        raise UserError(f"{path}: [axis] must be a table")
    _check_keys(axis, {"all", *AXES}, "[axis]", path)
    for ax in AXES[: m.axes]:
        p = dict(LACERDA)
        p.update({"I2": I2[ax], "lead_mm": 5.0, "encoder_lines": 1000, "model": "lacerda1998"})
        for src in (
            _table(axis.get("all", {}), "[axis.all]", path),
            _table(axis.get(ax, {}), f"[axis.{ax}]", path),
        ):
            _check_keys(src, AXIS_KEYS, f"[axis.{ax}]", path)
            p.update(src)
        if p["model"] != "lacerda1998":
            raise UserError(f"{path}: unknown axis model {p['model']!r} (known: lacerda1998)")
        for k, v in p.items():
            if k not in ("model", "pitch_map"):
                lo, hi = AXIS_RANGES.get(k, (-math.inf, math.inf))
                p[k] = _num(v, f"axis.{ax}.{k}", path, lo, hi)
        for k in ("lead_mm", "I1", "I2", "La", "Ra", "kt", "kb", "kx", "vmax", "encoder_lines"):
            if p[k] <= 0:
                raise UserError(f"{path}: axis.{ax}.{k} must be positive, got {p[k]}")
        if p["encoder_lines"] != int(p["encoder_lines"]):
            raise UserError(f"{path}: axis.{ax}.encoder_lines must be a whole number")
        if p.get("home_side", -1) not in (-1, 0, 1):
            raise UserError(f"{path}: axis.{ax}.home_side must be -1, 0 or 1")
        if p.get("encoder_index", 1) not in (0, 1):
            raise UserError(f"{path}: axis.{ax}.encoder_index must be 0 or 1")
        if "pitch_map" in p:
            pm = p["pitch_map"]
            if not isinstance(pm, list) or not all(isinstance(r, list) and len(r) == 3 for r in pm):
                raise UserError(
                    f"{path}: axis.{ax}.pitch_map must be a list of [pos_mm, fwd_um, rev_um]"
                )
            pos = [_num(r[0], "pitch_map position", path, -1e6, 1e6) for r in pm]
            for r in pm:
                for e in r[1:]:
                    _num(e, "pitch_map error", path, -1e4, 1e4)
            if any(b <= a for a, b in zip(pos, pos[1:])):
                raise UserError(f"{path}: axis.{ax}.pitch_map positions must increase")
            if len(pm) > 64:
                raise UserError(f"{path}: axis.{ax}.pitch_map has more than 64 points")
        m.axis[ax] = p
    planner = _table(data.get("planner", {}), "[planner]", path)
    _check_keys(planner, PLAN_KEYS, "[planner]", path)
    m.planner = {"v_max": 1.0, "a_max": 20.0, "j_max": 2000.0, "junction_dev": 1e-5}
    m.planner.update({k: _num(v, f"planner.{k}", path, 0, PLAN_MAX[k]) for k, v in planner.items()})
    servo = _table(data.get("servo", {}), "[servo]", path)
    _check_keys(servo, SERVO_KEYS, "[servo]", path)
    m.servo = {"ferr_limit_mm": 50.0, "sat_limit_s": 0.5, "stop_decel": 1.0}
    m.servo.update({k: _num(v, f"servo.{k}", path, 0, 1e6) for k, v in servo.items()})
    gains = _table(data.get("gains", {}), "[gains]", path)
    _check_keys(gains, {"axis", "axis_x", "axis_y", "axis_z", "cec", "cec_line"}, "[gains]", path)
    base = {"kp": 1500.0, "ki": 8000.0, "kd": 5.0, "d_tau": 1e-4, "d_on_measurement": False}
    base.update(_table(gains.get("axis", {}), "[gains.axis]", path))
    for ax in AXES[: m.axes]:
        g = dict(base)
        g.update(_table(gains.get(f"axis_{ax}", {}), f"[gains.axis_{ax}]", path))
        _check_keys(g, GAIN_KEYS, f"[gains.axis_{ax}]", path)
        m.gains[ax] = {
            k: (
                _bool(v, f"gains.{ax}.{k}", path)
                if k == "d_on_measurement"
                else _num(v, f"gains.{ax}.{k}", path, 0, GAIN_MAX)
            )
            for k, v in g.items()
        }
    cec = {"kp": 0.0, "ki": 0.0, "kd": 0.0, "d_tau": 0.0}
    cec.update(_table(gains.get("cec", {}), "[gains.cec]", path))
    _check_keys(cec, GAIN_KEYS, "[gains.cec]", path)
    m.gains["cec"] = {
        k: (
            _bool(v, f"gains.cec.{k}", path)
            if k == "d_on_measurement"
            else _num(v, f"gains.cec.{k}", path, 0, GAIN_MAX)
        )
        for k, v in cec.items()
    }
    if "cec_line" in gains:  # the thesis's line/curve gain switching (cec.h)
        cl = {"kp": 0.0, "ki": 0.0, "kd": 0.0, "d_tau": 0.0}
        cl.update(_table(gains["cec_line"], "[gains.cec_line]", path))
        _check_keys(cl, GAIN_KEYS, "[gains.cec_line]", path)
        m.gains["cec_line"] = {
            k: (
                _bool(v, f"gains.cec_line.{k}", path)
                if k == "d_on_measurement"
                else _num(v, f"gains.cec_line.{k}", path, 0, GAIN_MAX)
            )
            for k, v in cl.items()
        }
    if "field2d" in data:
        m.field2d = _field2d(_table(data["field2d"], "[field2d]", path), m.axes, path)
    ff = _table(data.get("feedforward", {}), "[feedforward]", path)
    _check_keys(ff, FF_KEYS, "[feedforward]", path)
    ff = dict(ff)
    mode = ff.pop("mode", "none")
    if mode not in FF_MODES:
        raise UserError(
            f"{path}: feedforward.mode must be one of {', '.join(FF_MODES)}, got {mode!r}"
        )
    m.ff_mode = mode
    m.feedforward = {k: _num(v, f"feedforward.{k}", path, 0, 1e6) for k, v in ff.items()}
    dist = _table(data.get("disturbance", {}), "[disturbance]", path)
    _check_keys(dist, DIST_KEYS, "[disturbance]", path)
    m.disturbance = {
        k: _num(v, f"disturbance.{k}", path, -1e9 if "0_mm" in k else 0.0, 1e9)
        for k, v in dist.items()
    }
    return m


def _field2d(fd: dict, axes: int, path: str) -> dict:
    """[field2d]: the 2-D error field of X and Y (contour.sim.field2d)."""
    from contour.sim import field2d

    _check_keys(fd, {"lines", "band_um"}, "[field2d]", path)
    if axes < 2:
        raise UserError(f"{path}: [field2d] needs axes >= 2")
    lines = fd.get("lines")
    if not isinstance(lines, list) or not all(
        isinstance(r, list) and len(r) == 8 and r[0] in ("X", "Y") and r[1] in ("X", "Y")
        for r in lines
    ):
        raise UserError(
            f"{path}: field2d.lines must be a list of [X|Y, X|Y, line_mm, pos_mm,"
            " mean_pos_um, std_pos_um, mean_neg_um, std_neg_um]"
        )
    rows = [r[:2] + [_num(v, "field2d.lines value", path, -1e6, 1e6) for v in r[2:]] for r in lines]
    try:
        built = field2d.build(rows)
    except ValueError as e:
        raise UserError(f"{path}: [field2d]: {e}") from None
    if built.col[0][0].size > 256 or len(built.rs) > 64:
        raise UserError(f"{path}: [field2d] is larger than the simulator's 256 x 64 nodes")
    return {
        "field": built,
        "band_um": _num(fd.get("band_um", 0.5), "field2d.band_um", path, 0, 1e6),
    }


def apply(
    m: Machine,
    tick_hz: float | None = None,
    feedforward: str | None = "none",
    controller: str = "pid",
    link: SimLink | None = None,
    encoder_model: str | None = None,
) -> None:
    """Set up the simulator with machine `m` (sim_setup ... sim_start); with
    `link`, the simulated drive also serves its host link (sim_set_link).
    `feedforward` None: the machine file's [feedforward] mode;
    `encoder_model` None: the machine file's (default "fast")."""
    from contour.sim import core

    if feedforward is None:
        feedforward = m.ff_mode

    so = core.lib()
    hz = float(tick_hz if tick_hz is not None else m.tick_hz)
    if not 100 <= hz <= 100000:
        raise UserError(f"tick rate {hz:g} Hz is outside 100..100000")
    core.check(so.sim_setup(hz, m.axes), "setup")
    enc = check_encoder_model(
        m.encoder_model if encoder_model is None else encoder_model, "encoder model"
    )
    core.check(so.sim_encoder_model(core.ENCODER_MODELS[enc]), "encoder model")

    def axset(i: int, key: str, v: float) -> None:
        core.check(so.sim_axis_set(i, key.encode(), float(v)), f"axis {AXES[i]} {key}")

    for i, ax in enumerate(AXES[: m.axes]):
        p = m.axis[ax]
        for k in LACERDA:
            axset(i, k, p[k])
        axset(i, "I2", p["I2"])
        axset(i, "lead", p["lead_mm"] * 1e-3)
        axset(i, "enc_counts_per_rev", 4 * p["encoder_lines"])
        axset(i, "enc_noise_counts", p.get("encoder_noise_counts", 0.0))
        axset(i, "ref_resolution", p.get("ref_resolution_nm", 1.0) * 1e-9)
        axset(i, "ref_noise", p.get("ref_noise_nm", 0.0) * 1e-9)
        axset(i, "load_torque", p.get("load_torque", 0.0))
        axset(i, "coulomb_motor", p.get("coulomb_motor", 0.0))
        axset(i, "coulomb_table", p.get("coulomb_table", 0.0))
        axset(i, "backlash", p.get("backlash_um", 0.0) * 1e-6)
        axset(i, "pitch_dir_band", p.get("pitch_dir_band_um", 1.0) * 1e-6)
        axset(i, "seed", p.get("seed", 1 + i))
        axset(i, "home_switch", p.get("home_switch_mm", -21.3) * 1e-3)
        axset(i, "home_side", p.get("home_side", -1))
        axset(i, "enc_index", p.get("encoder_index", 1))
        axset(i, "index_phase", p.get("index_phase_counts", 0))
        pm = p.get("pitch_map")
        if pm:
            import numpy as np

            arr = np.array(pm, dtype=float)
            pos = np.ascontiguousarray(arr[:, 0] * 1e-3)
            fwd = np.ascontiguousarray(arr[:, 1] * 1e-6)
            rev = np.ascontiguousarray(arr[:, 2] * 1e-6)
            core.check(
                so.sim_axis_pitch(i, len(pos), pos.ctypes.data, fwd.ctypes.data, rev.ctypes.data),
                f"axis {ax} pitch map",
            )
        for k in ("v_max", "a_max", "j_max"):
            core.check(so.sim_plan_set(i, k.encode(), m.planner[k]), f"planner {k}")
        core.check(
            so.sim_servo_set(i, b"ferr_limit", m.servo["ferr_limit_mm"] * 1e-3), "ferr_limit"
        )
        core.check(so.sim_servo_set(i, b"stop_decel", m.servo["stop_decel"]), "stop_decel")
        fv = m.friction_ff_volts(ax) if feedforward == "full" else 0.0
        core.check(so.sim_servo_set(i, b"friction_ff", fv), "friction_ff")
        if i == 0:
            band = m.feedforward.get("friction_band", 1.0) * 1e-3
            core.check(so.sim_servo_set(0, b"friction_ff_band", band), "friction_band")
            adv = m.feedforward.get("advance_ticks", 0.0) if feedforward != "none" else 0.0
            core.check(so.sim_servo_set(0, b"ff_advance", adv / hz), "advance_ticks")
            lr = m.feedforward.get("learn_rate", 0.0) if feedforward != "none" else 0.0
            core.check(so.sim_servo_set(0, b"ffl_rate", lr), "learn_rate")
            qg = m.feedforward.get("quadrant_comp", 0.0) if feedforward == "full" else 0.0
            core.check(so.sim_servo_set(0, b"qg_comp", qg), "quadrant_comp")
        g = m.gains[ax]
        kv, ka = m.ff_gains(ax, feedforward)
        _gains(so, i, {**g, "kvff": kv, "kaff": ka}, f"axis {ax}")
    dist = m.disturbance
    if m.axes >= 2:
        core.check(so.sim_axis_set(0, b"cut_f_w", m.cutting_f_w()), "disturbance f_w")
        core.check(
            so.sim_axis_set(0, b"cut_phi", math.radians(dist.get("phi_deg", 45.0))), "phi_deg"
        )
    for i, ax in enumerate(AXES[: m.axes]):
        axset(i, "cut_f_at", dist.get("f_at", 0.0) if i < 2 else 0.0)
        axset(i, "spring_k", dist.get(f"spring_{ax}", 0.0) * 1e3)
        axset(i, "spring_x0", dist.get(f"spring_{ax}0_mm", 0.0) * 1e-3)
    for k in ("junction_dev", "arc_chord"):
        if k in m.planner:
            core.check(so.sim_plan_set(0, k.encode(), m.planner[k]), f"planner {k}")
    if m.field2d:
        from contour.sim import field2d

        core.check(field2d.apply(so, m.field2d["field"], m.field2d["band_um"]), "2-D field")
    core.check(so.sim_servo_set(0, b"sat_limit", m.servo["sat_limit_s"]), "sat_limit")
    core.check(
        so.sim_servo_set(0, b"enc_mean", 1.0 if m.servo.get("encoder_mean", 0) else 0.0),
        "encoder_mean",
    )
    core.check(
        so.sim_servo_set(0, b"enc_interp", 1.0 if m.servo.get("encoder_interp", 0) else 0.0),
        "encoder_interp",
    )
    core.check(
        so.sim_servo_set(0, b"cec_thesis_form", 1.0 if m.servo.get("cec_thesis_form", 0) else 0.0),
        "cec_thesis_form",
    )
    core.check(so.sim_plan_set(0, b"stop_decel", m.servo["stop_decel"]), "stop_decel")
    _gains(so, -1, m.gains["cec"], "cec")
    if "cec_line" in m.gains:
        _gains(so, -2, m.gains["cec_line"], "cec_line")
    mode = {"pid": "off", "cec-tangent": "tangent", "cec-curvature": "curvature"}.get(
        controller, controller.replace("cec-", "")
    )
    if mode not in core.CEC_MODES:
        raise UserError(f"unknown controller {controller!r}")
    core.check(so.sim_cec_mode(core.CEC_MODES[mode]), "controller")
    if link is not None:
        link.apply(so)
    core.check(so.sim_start(), "start")


@dataclass(frozen=True)
class SimLink:
    """The simulated drive's host link, built by the firmware's composition
    root (firmware/core/app.h) at sim_start: which links it serves, its CAN
    node id, the version it reports without a flash image, and whether the
    simulated bootloader's slot holds the application."""

    node: int = 1
    serial: bool = True
    can: bool = False
    fw_version: int = 0
    build_id: int = 0
    boot: bool = False

    def apply(self, so) -> None:
        from contour.sim import core

        rc = so.sim_set_link(
            self.node, self.serial, self.can, 0, self.fw_version, self.build_id, self.boot
        )
        core.check(rc, "host link")


def _gains(so, loop: int, g: dict, what: str) -> None:
    from contour.sim import core

    for k, v in g.items():
        core.check(so.sim_gain_set(loop, k.encode(), float(v)), f"{what} gain {k}")
