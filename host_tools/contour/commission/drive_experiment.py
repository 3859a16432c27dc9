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
import zlib
from dataclasses import dataclass

import numpy as np

from contour import protocol_gen as pg
from contour.commission.experiment import ExperimentAborted, Limits, Record
from contour.errors import UserError
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
    bad = 0
    end = time.monotonic() + timeout_s
    while seq < want:
        st = client.request("excite_status").fields
        while seq < st["written"]:
            r = client.request("excite_read", from_seq=seq, max=READ_MAX).fields
            d, k = r["data"], r["count"]
            if r["from_seq"] != seq or len(d) != SAMPLE.size * k or zlib.crc32(d) != r["crc"]:
                bad += 1
                if bad > 20:
                    raise ExperimentAborted("sample batches keep failing their checks")
                continue
            for i in range(k):
                out[seq + i] = SAMPLE.unpack_from(d, SAMPLE.size * i)
            seq += k
            if k == 0:
                break
        if seq >= want:
            break
        if st["released"] < seq:  # free what was read: the next window needs the room
            client.request("excite_read", from_seq=seq, max=1)
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


# ---- verification ----------------------------------------------------------------


def verify(client, axis: int, distance_mm: float = 20.0, feed_mm_s: float = 100.0) -> dict:
    """The verification job: a line of `distance_mm` on the axis there and
    back at `feed_mm_s` from where it stands, streamed as `contour run`
    streams a program; its report (max_following_error_um)."""
    from contour.link.blocks import DriveLimits, blocks_from_gcode
    from contour.link.stream import Streamer

    _wait_idle(client)
    a = AXIS_NAMES[axis].upper()
    text = f"G21 G91\nG1 {a}{distance_mm:g} F{feed_mm_s * 60:g}\nG1 {a}{-distance_mm:g}\nM2\n"
    fd, path = tempfile.mkstemp(suffix=".nc")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        st = client.status()
        start = [p / 1e6 for p in st["pos"][:3]]
        limits = DriveLimits.read(client, axes=client.identify()["axes"])
        blocks = blocks_from_gcode(path, start, 0.001, None, limits)
        res = Streamer(client, blocks, source="verification job").run()
    finally:
        os.unlink(path)
    if res.get("blocks_done", 0) <= 0:
        raise UserError("verification job: no block done")
    return res
