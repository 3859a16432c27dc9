"""The excitation experiment on a drive over the link, its verification
job and the writing of gains (issue 23; firmware/core/drive_excite.h).

The drive adds a PRBS of +-amp to the axis's command while its PID holds
the axis at rest, checks the user's limits every tick, and records whole
PRBS periods ("windows") of (command, position) when its buffer has room;
the host pulls them with excite_read as calibration pulls its samples
(from_seq releases, CRC-32 per reply, a gap or a bad CRC is read again,
a sample no longer held refuses the record). The windows make a Record
(experiment.Record, segment "periodic") that identify.identify takes as it
takes the simulated drive's multisine record: one piece of identification
and tuning for --sim and --port.
"""

from __future__ import annotations

import contextlib
import os
import struct
import tempfile
import time
from dataclasses import dataclass

import numpy as np

from contour import protocol_gen as pg
from contour.commission.experiment import ExperimentAborted, Limits, Record
from contour.errors import UserError
from contour.link.chunks import SamplePull
from contour.link.client import AXIS_NAMES, DriveError

READ_MAX = 29  # DRIVE_EXCITE_READ_MAX
SAMPLE = struct.Struct("<ii")  # cmd_mv, pos_nm


@dataclass
class PrbsPlan:
    """The drive's PRBS: 2^bits - 1 chips of `hold` ticks per period."""

    tick_hz: float
    bits: int = 10
    hold: int = 1
    amplitude_v: float = 3.0
    windows: int = 16
    settle_periods: int = 3
    host_timeout_ms: int = 500
    f_max_hz: float = 1500.0  # bins used: above, the encoder's counts drown the response

    @property
    def period_ticks(self) -> int:
        return ((1 << self.bits) - 1) * self.hold

    def excited_bins(self) -> np.ndarray:
        """DFT bins (of one period) where the PRBS has power, up to
        f_max_hz: every bin but the multiples of the chip count (the hold's
        sinc nulls)."""
        n = self.period_ticks
        chips = (1 << self.bits) - 1
        k = np.arange(1, min(n // 2, int(self.f_max_hz * n / self.tick_hz)) + 1)
        return k[k % chips != 0] if self.hold > 1 else k


def reason_text(code: int) -> str:
    try:
        return pg.ExciteReason(code).name.lower().replace("_", " ")
    except ValueError:
        return f"reason {code}"


def _refusal(exc: DriveError) -> str:
    f = exc.fields
    if f.get("code") == pg.ErrorCode.EXCITE:
        try:
            why = pg.ExciteRefusal(f["arg"]).name.lower().replace("_", " ")
        except ValueError:
            why = f"refusal {f['arg']}"
        return f"drive refused the excitation: {why} (detail {f['lo']})"
    return str(exc)


def _wait_idle(client, timeout_s: float = 5.0) -> None:
    """Enable if needed and wait until the drive is READY (IDLE) and still."""
    st = client.status()
    if st["state"] == pg.State.DISABLED:
        client.enable(True)
    end = time.monotonic() + timeout_s
    while True:
        st = client.status()
        if st["state"] == pg.State.READY:
            return
        if st["state"] in (pg.State.FAULT, pg.State.ESTOP):
            raise ExperimentAborted(f"drive faulted (state {pg.State(st['state']).name.lower()})")
        if time.monotonic() > end:
            raise ExperimentAborted(f"drive not ready (state {pg.State(st['state']).name.lower()})")
        time.sleep(0.02)


def _wait_still(client, timeout_s: float = 3.0, quiet_nm: int = 2000) -> None:
    """Wait (at most timeout_s) until no axis moved more than quiet_nm over
    three polls 0.1 s apart: a job then starts from the same state each
    time (a soft axis with friction settles for a second after a move)."""
    x0 = client.status()["pos"]
    quiet = 0
    end = time.monotonic() + timeout_s
    while quiet < 3 and time.monotonic() < end:
        time.sleep(0.1)
        x1 = client.status()["pos"]
        quiet = quiet + 1 if max(abs(a - b) for a, b in zip(x0, x1)) < quiet_nm else 0
        x0 = x1


def run(client, axis: int, plan: PrbsPlan, limits: Limits, timeout_s: float = 60.0) -> Record:
    """One experiment on axis index `axis`; the Record of its windows. On
    any way out but success the experiment is aborted (excite_abort), and
    the drive gives its buffer back to the calibration."""
    _wait_idle(client)
    n = plan.period_ticks
    fields = dict(
        axis=axis,
        bits=plan.bits,
        hold=plan.hold,
        reserved=0,
        windows=plan.windows,
        host_timeout_ms=plan.host_timeout_ms,
        amp_mv=round(plan.amplitude_v * 1000),
        skip_ticks=plan.settle_periods * n,
        # the windows, the settling and room for a slow host
        n_ticks=min(
            2**32 - 1, int((plan.settle_periods + 4 * plan.windows) * n + timeout_s * plan.tick_hz)
        ),
        travel_nm=round(limits.travel_m * 1e9),
        cmd_mv=round(limits.command_v * 1000),
        vel_nm_s=round(limits.velocity_m_s * 1e9),
    )
    try:
        client.request("excite_start", **fields)
    except DriveError as exc:
        raise ExperimentAborted(_refusal(exc)) from None
    try:
        data = _collect(client, plan, timeout_s)
    finally:
        with contextlib.suppress(Exception):
            client.request("excite_abort", retries=2)
    u = data[:, 0] * 1e-3
    y = data[:, 1] * 1e-9
    return Record(plan.tick_hz, u, y, plan, {"periodic": (0, u.size)})


def _collect(client, plan: PrbsPlan, timeout_s: float) -> np.ndarray:
    want = plan.windows * plan.period_ticks
    out = np.zeros((want, 2), dtype=np.int64)
    seq = 0
    pull = SamplePull(
        lambda name, **f: client.request(name, **f).fields,
        "excite_read",
        SAMPLE.size,
        READ_MAX,
        lambda: ExperimentAborted("sample batches keep failing their checks"),
    )
    end = time.monotonic() + timeout_s
    while seq < want:
        st = client.request("excite_status").fields
        while seq < st["written"]:
            r = pull.read(seq)
            d, k = r["data"], r["count"]
            for i in range(k):
                out[seq + i] = SAMPLE.unpack_from(d, SAMPLE.size * i)
            seq += k
            if k == 0:
                break
        if seq >= want:
            break
        if st["released"] < seq:  # free what was read: the next window needs the room
            pull.release(seq)
        if st["state"] == pg.ExciteRunState.ABORTED:
            raise ExperimentAborted(
                f"the drive stopped the experiment: {reason_text(st['reason'])}"
            )
        if st["state"] == pg.ExciteRunState.DONE and seq >= st["written"]:
            raise ExperimentAborted(f"experiment done with {seq} of {want} samples")
        if time.monotonic() > end:
            raise ExperimentAborted(f"experiment did not finish within {timeout_s:g} s")
        time.sleep(0.005)
    return out


def run_bounded(client, axis: int, plan: PrbsPlan, limits: Limits, tries: int = 4):
    """`run`, halving the amplitude after each stop at a limit:
    (record, the stops met on the way)."""
    stops = []
    for _ in range(tries):
        try:
            return run(client, axis, plan, limits), stops
        except ExperimentAborted as e:
            if "refused" in str(e):
                raise
            stops.append(f"{plan.amplitude_v:g} V: {e}")
            plan = PrbsPlan(**{**plan.__dict__, "amplitude_v": plan.amplitude_v / 2})
            with contextlib.suppress(Exception):
                if client.status()["state"] in (pg.State.FAULT, pg.State.ESTOP):
                    client.request("fault_reset")
    raise ExperimentAborted("; ".join(stops))


# ---- friction ---------------------------------------------------------------------


FRICTION_SPEEDS_MM_S = (5.0, 10.0)


def friction_legs(
    client,
    axis: int,
    speeds_mm_s=FRICTION_SPEEDS_MM_S,
    leg_s: float = 0.5,
    travel_mm: float = 10.0,
    stats: dict | None = None,
) -> list:
    """Constant-velocity legs for the friction estimate on the drive: per
    speed, lines out and back twice (+v, -v, -v, +v: ends where it started,
    within +-travel_mm) streamed as a job, the motor command and the
    position from the drive's telemetry. Per run of cycles whose reference
    velocity is within 2 % of a leg's, the mean command over its second
    half (past the transient): [(v m/s, u V)] for identify.friction_fit.
    `stats` (a dict) receives vel_noise_m_s: the rms of the measured
    velocity about the reference over those halves (encoder noise and the
    loop's hunting, what friction_band reads)."""
    a = AXIS_NAMES[axis].upper()
    lines = ["G21 G91"]
    for v in speeds_mm_s:
        d = min(v * leg_s, travel_mm)
        for s in (1, -1, -1, 1):
            lines.append(f"G1 {a}{s * d:g} F{v * 60:g}")
    res = run_job(client, "\n".join(lines + ["M2", ""]), "friction legs")
    keys = (f"pos{axis}_nm", f"ferr{axis}_nm", f"cmd{axis}_mv")
    cyc = [c for c in res["cycles"] if all(k in c for k in keys)]
    if len(cyc) < 3:
        return []
    seq = np.unwrap(np.array([c["seq"] for c in cyc], dtype=float), period=65536)
    ref = np.array([c[keys[0]] + c[keys[1]] for c in cyc], dtype=float) * 1e-9
    u = np.array([c[keys[2]] for c in cyc], dtype=float) * 1e-3
    dt = np.diff(seq) * res["telem_period_s"]
    vel = np.diff(ref) / np.maximum(dt, 1e-9)  # over the interval ending at cycle i + 1
    pos = np.array([c[keys[0]] for c in cyc], dtype=float) * 1e-9
    vmeas = np.diff(pos) / np.maximum(dt, 1e-9)
    legs = []
    dev = []
    label = np.zeros(vel.size)
    for v in speeds_mm_s:
        for s in (1, -1):
            label[np.abs(vel - s * v * 1e-3) <= 0.02 * v * 1e-3] = s * v * 1e-3
    i = 0
    while i < label.size:
        j = i
        while j < label.size and label[j] == label[i]:
            j += 1
        if label[i] != 0 and j - i >= 6:
            legs.append((float(label[i]), float(u[1 + i + (j - i) // 2 : 1 + j].mean())))
            dev.append(vmeas[i + (j - i) // 2 : j] - vel[i + (j - i) // 2 : j])
        i = j
    if stats is not None and dev:
        stats["vel_noise_m_s"] = float(np.sqrt(np.mean(np.concatenate(dev) ** 2)))
    return legs


# ---- gains --------------------------------------------------------------------

# drive parameter <- tune.Tuned.gains key (SI units, q32.32 on the wire)
GAIN_PARAMS = {
    "pid_kp": "kp",
    "pid_ki": "ki",
    "pid_kd": "kd",
    "velocity_feedforward": "velocity_feedforward",
    "acceleration_feedforward": "acceleration_feedforward",
}


def read_gains(client, axis: int) -> dict:
    a = AXIS_NAMES[axis]
    return {k: client.get_param(f"{p}.{a}") / 2**32 for p, k in GAIN_PARAMS.items()}


def apply_gains(client, axis: int, gains: dict) -> dict:
    """Write the gains as drive parameters (at rest), save them to flash
    (the drive saves only while disabled: disable, save, enable) and
    return what the drive holds."""
    a = AXIS_NAMES[axis]
    for p, k in GAIN_PARAMS.items():
        client.set_param(f"{p}.{a}", round(gains[k] * 2**32))
    client.enable(False)
    try:
        client.request("param_save")
    finally:
        client.enable(True)
    return read_gains(client, axis)


FRICTION_BAND_MIN_M_S = 1e-4  # 0.1 mm/s
FRICTION_BAND_NOISE = 4.0  # band = this x the legs' velocity noise


def friction_band(vel_noise_m_s: float | None, slowest_leg_m_s: float) -> float:
    """friction_ff_band (m/s) from the friction legs: FRICTION_BAND_NOISE x
    the rms of the measured velocity about the reference (below it the
    record cannot tell the axis's direction, so the full Coulomb term would
    be a guess), within 0.1 mm/s .. half the slowest leg (where the legs
    showed the whole Coulomb friction). None (no legs): the slowest leg /
    5, the drive's default 1 mm/s for legs at 5 mm/s."""
    hi = slowest_leg_m_s / 2
    if vel_noise_m_s is None:
        return slowest_leg_m_s / 5
    return float(min(hi, max(FRICTION_BAND_MIN_M_S, FRICTION_BAND_NOISE * vel_noise_m_s)))


def read_friction(client, axis: int) -> dict:
    a = AXIS_NAMES[axis]
    return {
        "friction_ff_v": client.get_param(f"friction_ff_mv.{a}") / 1000.0,
        "friction_ff_band_m_s": client.get_param("friction_ff_band") * 1e-9,
    }


def apply_friction(client, frictions: dict, band_m_s: float) -> dict | None:
    """Write the identified Coulomb friction as friction_ff_mv.<axis>
    ({axis index: volts}; negative or unknown: 0, off) and the band
    friction_ff_band (one for all axes), save as apply_gains does; what
    the drive holds per axis, or None on a drive without the parameters."""
    try:
        client.get_param("friction_ff_band")
    except (DriveError, UserError, KeyError, ValueError):
        return None
    client.set_param("friction_ff_band", max(1, round(band_m_s * 1e9)))
    for axis, f in frictions.items():
        mv = 0 if f is None or not f > 0 else min(100000, round(f * 1000))
        client.set_param(f"friction_ff_mv.{AXIS_NAMES[axis]}", mv)
    client.enable(False)
    try:
        client.request("param_save")
    finally:
        client.enable(True)
    return {AXIS_NAMES[a].upper(): read_friction(client, a) for a in frictions}


CEC_PARAMS = {"cec_kp": "kp", "cec_ki": "ki", "cec_kd": "kd"}  # q32.32, as the PID's


def cec_mode(client) -> str:
    """The drive's contour-error controller mode (param cec_mode), by name."""
    v = client.get_param("cec_mode")
    try:
        return pg.CecMode(v).name.lower()
    except (ValueError, AttributeError):
        return str(v)


def apply_cec_gains(client, cec) -> dict | None:
    """Write the CEC gains (tune.CecTuned) as the drive parameters cec_kp,
    cec_ki, cec_kd and save them as apply_gains does; what the drive holds,
    or None when the drive has no such parameters (older firmware: nothing
    written)."""
    try:
        client.get_param("cec_kp")
    except (DriveError, UserError, KeyError, ValueError):
        return None
    for p, k in CEC_PARAMS.items():
        client.set_param(p, round(cec.gains[k] * 2**32))
    client.enable(False)
    try:
        client.request("param_save")
    finally:
        client.enable(True)
    return {k: client.get_param(p) / 2**32 for p, k in CEC_PARAMS.items()}


# ---- verification ----------------------------------------------------------------


VERIFY_IN_POSITION_NM = 100_000
VERIFY_TELEM_MS_SERIAL = 2  # the corners pass in a few ms: 10 ms samples missed them


def _telem_ms(client) -> int | None:
    from contour.link.transport import CanTransport

    return None if isinstance(getattr(client, "t", None), CanTransport) else VERIFY_TELEM_MS_SERIAL


def run_job(
    client,
    text: str,
    what: str = "verification job",
    chord_mm: float = 0.001,
    telem_period_ms: int | None = None,
) -> dict:
    """Stream the G-code `text` from where the axes stand, as `contour run`
    streams a program, with the drive's telemetry recorded: its report
    (max_following_error_um, per axis in max_following_error_um_axes) and
    the programmed path and the telemetry cycles (contour_error)."""
    from contour.link.blocks import DriveLimits, blocks_from_gcode
    from contour.link.stream import Streamer
    from contour.link.telemetry import Assembler

    _wait_idle(client)
    _wait_still(client)
    fd, path = tempfile.mkstemp(suffix=".nc")
    info = client.identify()
    asm = Assembler(info["axes"])
    cycles = []

    def telemetry(m) -> None:
        done = asm.add(0.0, m)
        if done is not None:
            cycles.append(done)

    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        st = client.status()
        start = [p / 1e6 for p in st["pos"][:3]]
        limits = DriveLimits.read(client, axes=info["axes"])
        blocks = list(blocks_from_gcode(path, start, chord_mm, None, limits))
        # the end needs no precision: a soft tuned axis with Coulomb friction
        # hunts by tens of um and may take more than 10 s into 5 um
        streamer = Streamer(
            client,
            blocks,
            source=what,
            on_telemetry=telemetry,
            telem_period_ms=telem_period_ms,
            in_position_nm=VERIFY_IN_POSITION_NM,
        )
        res = streamer.run()
    finally:
        os.unlink(path)
    last = asm.flush()
    if last is not None:
        cycles.append(last)
    if res.get("blocks_done", 0) <= 0:
        raise UserError(f"{what}: no block done")
    pts = [tuple(round(v * 1e6) for v in start)]
    pts += [b.target_nm for b in blocks if b.kind != pg.BlockKind.DWELL]
    res["path_nm"] = np.array(pts, dtype=float)
    res["cycles"] = cycles
    res["telem_period_s"] = streamer.telem_period_ms / 1000.0
    return res


def contour_error(res: dict, axes: list[int]) -> dict:
    """Contour error of a job run by run_job over `axes`: the distance of
    each measured position the telemetry sampled (pos_n) from the
    programmed path (the blocks sent, sim.job.path_errors), over the cycles
    from the first to the last in which the reference (pos + ferr) moved;
    and the largest following error |ref - pos| of those cycles, um."""
    from contour.sim.job import path_errors

    keys = [f"pos{a}_nm" for a in axes] + [f"ferr{a}_nm" for a in axes]
    cyc = [c for c in res["cycles"] if all(k in c for k in keys)]
    if len(cyc) < 10:
        raise UserError(f"contour check: {len(cyc)} telemetry samples (< 10)")
    pos = np.array([[c[f"pos{a}_nm"] for a in axes] for c in cyc], dtype=float)
    ferr = np.array([[c[f"ferr{a}_nm"] for a in axes] for c in cyc], dtype=float)
    ref = pos + ferr
    moved = np.flatnonzero(np.any(np.abs(np.diff(ref, axis=0)) > 0.5, axis=1))
    if moved.size == 0:
        raise UserError("contour check: the reference never moved in the telemetry")
    sel = slice(moved[0], moved[-1] + 2)
    e = path_errors(res["path_nm"][:, axes], pos[sel])
    return {
        "max_contour_error_um": round(float(e.max()) / 1e3, 2),
        "rms_contour_error_um": round(float(np.sqrt((e**2).mean())) / 1e3, 2),
        "max_following_error_um": round(float(np.abs(ferr[sel]).max()) / 1e3, 2),
        "samples": int(e.size),
    }


def verify(client, axis: int, distance_mm: float = 20.0, feed_mm_s: float = 100.0) -> dict:
    """The single-axis verification job: a line of `distance_mm` on the axis
    there and back at `feed_mm_s` from where it stands; run_job's report
    (max_following_error_um)."""
    a = AXIS_NAMES[axis].upper()
    text = f"G21 G91\nG1 {a}{distance_mm:g} F{feed_mm_s * 60:g}\nG1 {a}{-distance_mm:g}\nM2\n"
    return run_job(client, text)


PLANES = {(0, 1): "G17", (0, 2): "G18", (1, 2): "G19"}


def square_text(axes: tuple, side_mm: float, feed_mm_s: float) -> str:
    """A square of `side_mm` from where the axes stand (+u, +v, -u, -v):
    four 90 degree corners, lines only (G1 as the drive takes them)."""
    u, v = (AXIS_NAMES[a].upper() for a in axes)
    d = f"{side_mm:g}"
    return (
        f"G21 G91 {PLANES[axes]}\nG1 {u}{d} F{feed_mm_s * 60:g}\nG1 {v}{d}\n"
        f"G1 {u}-{d}\nG1 {v}-{d}\nM2\n"
    )


def verify_contour(client, axes: tuple, side_mm: float = 10.0, feed_mm_s: float = 100.0) -> dict:
    """The two-axis verification job: square_text on `axes` (two axis
    indices, ascending), run with the drive as configured (its cec_mode);
    contour_error of its telemetry, with the path's size and feed. A square,
    not a circle: over the link a circle is G1 chords, and the drive's
    acceleration feed-forward does not see the centripetal acceleration of a
    chorded arc (zero along each chord), so a circle measures that, not the
    tuning (commission_xy, tuned: R10 F6000 as 224 chords 1486 um, as arc
    blocks 78 um, sim circle)."""
    res = run_job(
        client,
        square_text(axes, side_mm, feed_mm_s),
        "contour verification job",
        telem_period_ms=_telem_ms(client),
    )
    out = contour_error(res, list(axes))
    out.update(
        path="square",
        side_mm=side_mm,
        feed_mm_s=feed_mm_s,
        plane="".join(AXIS_NAMES[a] for a in axes),
    )
    return out
