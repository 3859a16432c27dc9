"""Job-time estimation: four models behind one interface.

``planner`` (default) runs the drive's own C planner (host build, through
:mod:`contour.planner`) with the profile's limits; ``camargo2017`` is the
empirical model of Camargo (2017); ``mrt`` is feed limited by a minimum block
time (Coelho et al. 2009); ``feed`` is distance over feed (what CAM systems
print). Each model module has ``NAME``, ``OPTIONS`` (documented option
fields) and ``estimate(moves, profile, options) -> Estimate``.
"""

from __future__ import annotations

from contour import gcode
from contour.errors import UserError
from contour.estimation import camargo2017, feed, mrt
from contour.estimation import planner as planner_model
from contour.estimation.profile import Profile
from contour.estimation.result import Estimate, Moves

MODELS = {
    "planner": planner_model,
    "camargo2017": camargo2017,
    "mrt": mrt,
    "feed": feed,
}
DEFAULT_MODEL = "planner"

__all__ = ["MODELS", "DEFAULT_MODEL", "Estimate", "Moves", "estimate_moves", "estimate_program"]


def _model(name: str):
    try:
        return MODELS[name]
    except KeyError:
        raise UserError(f"unknown model '{name}' (models: {', '.join(MODELS)})") from None


def parse_options(model: str, pairs) -> dict:
    """``KEY=VALUE`` strings to a checked option dict of ``model``."""
    fields = {f.name: f for f in _model(model).OPTIONS}
    out = {}
    for pair in pairs or ():
        key, sep, text = pair.partition("=")
        key = key.strip()
        if not sep:
            raise UserError(f"option '{pair}' is not KEY=VALUE")
        f = fields.get(key)
        if f is None:
            known = ", ".join(fields) or "none"
            raise UserError(f"model {model} has no option '{key}' (options: {known})")
        text = text.strip()
        if f.choices:
            value = text
        elif isinstance(f.default, bool):
            if text.lower() not in ("true", "false"):
                raise UserError(f"option {key} must be true or false, got '{text}'")
            value = text.lower() == "true"
        else:
            try:
                value = float(text)
            except ValueError:
                raise UserError(f"option {key} must be a number ({f.unit}), got '{text}'") from None
        from contour.estimation.profile import _check_value

        out[key] = _check_value(f, value, "--option")
    return out


def estimate_moves(moves: Moves, profile: Profile, model: str = DEFAULT_MODEL, options=None):
    return _model(model).estimate(moves, profile, options or {})


def estimate_program(
    program: gcode.Program, profile: Profile, model: str = DEFAULT_MODEL, options=None
) -> Estimate:
    seg = gcode.segments(program, profile.motion["arc_chord_tolerance_mm"])
    moves = Moves.from_segments(seg, profile.motion["rapid_feed_mm_min"])
    return estimate_moves(moves, profile, model, options)
