"""Job-time estimation: four models behind one interface.

``planner`` (default) runs the drive's own C planner (host build, through
:mod:`contour.planner`) with the profile's limits; ``camargo2017`` is the
empirical model of Camargo (2017); ``mrt`` is feed limited by a minimum block
time (Coelho et al. 2009); ``feed`` is distance over feed (what CAM systems
print). Each model module has ``NAME``, ``OPTIONS`` (documented option
fields) and ``estimate(moves, profile, options) -> Estimate``.
"""

from __future__ import annotations

import math

import numpy as np

from contour import gcode
from contour.errors import UserError
from contour.estimation import camargo2017, feed, mrt
from contour.estimation import planner as planner_model
from contour.estimation.profile import Profile
from contour.estimation.result import CsvWriter, Estimate, Moves, merge_summaries

MODELS = {
    "planner": planner_model,
    "camargo2017": camargo2017,
    "mrt": mrt,
    "feed": feed,
}
DEFAULT_MODEL = "planner"

__all__ = [
    "MODELS",
    "DEFAULT_MODEL",
    "Estimate",
    "Moves",
    "estimate_file",
    "estimate_moves",
    "estimate_program",
]


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
    return estimate_moves(program_moves(program, profile), profile, model, options)


def program_moves(program: gcode.Program, profile: Profile) -> Moves:
    """The segments of `program` as the models read them (arcs split at the
    profile's chord tolerance, rapids at its rapid feed, rotary caps)."""
    seg = gcode.segments(program, profile.motion["arc_chord_tolerance_mm"])
    return Moves.from_segments(
        seg,
        profile.motion["rapid_feed_mm_min"],
        profile.rotary_values("max_velocity_deg_min"),
    )


def _last_flagged(items):
    """(item, is_last) for each item of an iterator."""
    it = iter(items)
    try:
        prev = next(it)
    except StopIteration:
        return
    for item in it:
        yield prev, False
        prev = item
    yield prev, True


def estimate_file(
    path,
    profile: Profile,
    model: str = DEFAULT_MODEL,
    options=None,
    default_feed=None,
    per_block_csv=None,
    tool_table=None,
):
    """Estimate a G-code file chunk by chunk (:func:`contour.program.chunks`:
    the program is never held whole). Returns (summary, report).

    Chunks overlap so that a chunk's end is no stop: the last ``OVERLAP``
    segments of a chunk are held back and planned again at the head of the
    next chunk, after ``OVERLAP`` segments of warm-up whose times are
    dropped (four look-ahead depths: the planner sees no further)."""
    from contour.program import Report, chunks

    report = Report()
    end = [0.0] * 6
    parts = []
    blocks = 0
    overlap = 4 * int(profile.motion["lookahead_blocks"])
    carry = None  # (warm-up, held back) segments of the chunk before
    writer = CsvWriter(per_block_csv) if per_block_csv else None
    if writer is not None:
        writer.__enter__()

    def emit(est: Estimate) -> None:
        if len(est.moves) == 0:
            return
        parts.append(est.summary())
        _rotary_notes(est, report)
        if writer is not None:
            writer.write(est)

    try:
        flagged = _last_flagged(chunks(path, default_feed=default_feed, tool_table=tool_table))
        for prog, last in flagged:
            report.take(prog)
            if len(prog) == 0:
                if last and carry is not None:
                    emit(
                        estimate_moves(Moves.concat(carry), profile, model, options).take(
                            slice(len(carry[0]), None)
                        )
                    )
                continue
            _check_positions(path, prog)
            end = [float(v) for v in prog.end[-1]]
            blocks += len(prog)
            moves = program_moves(prog, profile)
            skip = 0
            if carry is not None:
                skip = len(carry[0])
                moves = Moves.concat([*carry, moves])
            est = estimate_moves(moves, profile, model, options)
            n = len(moves)
            if last or n < skip + 2 * overlap:
                emit(est.take(slice(skip, None)))
                carry = None
            else:
                emit(est.take(slice(skip, n - overlap)))
                carry = (
                    moves.take(slice(n - 2 * overlap, n - overlap)),
                    moves.take(slice(n - overlap, None)),
                )
            del est, moves
    finally:
        if writer is not None:
            writer.__exit__(None, None, None)
    if not parts:
        parts.append(
            estimate_moves(
                Moves.from_arrays(np.zeros((0, 3)), 1.0), profile, model, options
            ).summary()
        )
    summary = merge_summaries(parts)
    if not math.isfinite(summary["total_s"]):
        raise UserError(
            f"{path}: the estimate is not a finite time with this profile "
            "(a limit too close to zero?)"
        )
    summary["blocks"] = blocks
    summary["end_mm"] = end
    return summary, report


def _check_positions(path, prog) -> None:
    """Targets beyond the drive's position range are refused here as by
    ``contour run`` (contour.link.blocks.check_position)."""
    from contour.link.blocks import POS_MAX_NM, check_position

    lin = np.abs(prog.end[:, :3])
    bad = ~(lin <= POS_MAX_NM / 1e6)
    if np.any(bad):
        i, a = (int(k[0]) for k in np.nonzero(bad))
        check_position(f"{path}:{int(prog.line[i])}", a, float(prog.end[i, a]))


def _rotary_notes(est: Estimate, report) -> None:
    """Say how the model timed blocks that move rotary axes."""
    m = est.moves
    if m.rotary is None:
        return
    moved = np.any(np.abs(m.rotary) > 1e-9, axis=1)
    if not np.any(moved):
        return
    mixed = moved & (np.einsum("ij,ij->i", m.delta, m.delta) > 0)
    notes = {
        "rotary+linear": "rotary axes moved with X Y Z: machine-axis kinematics, the feed is "
        "the X Y Z path speed, capped so that each rotary axis stays within its velocity "
        "limit; no tool-tip transformation",
        "rotary only": "rotary axes alone: the feed in deg/min within the rotary velocity "
        + ("and acceleration limits, rest to rest" if est.model == "planner" else "limits"),
    }
    for kind, sel in (("rotary+linear", mixed), ("rotary only", moved & ~mixed)):
        idx = np.nonzero(sel)[0]
        if idx.size:
            report.note(kind, int(m.line[idx[0]]), notes[kind])
            report.items[kind].count += int(idx.size) - 1
