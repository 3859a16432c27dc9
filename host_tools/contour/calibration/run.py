"""The host side of a calibration run, independent of the transport.

It needs a ``client`` with ``request(name, **fields)`` (contour.link.Client:
retries a request whose reply was lost under the same sequence number and
counts it in ``client.retried``) and a ``wait(seconds)`` callable (wall
clock on a real link, simulated time in process).

Protocol (docs/calibration.md): calib_setup, calib_targets, calib_start;
then poll calib_status and pull samples with calib_read(from_seq) until the
run is DONE and every sample is in. Every batch is checked: sequence
numbers contiguous from from_seq, count and length consistent, CRC-32 of
the sample bytes, point and cycle in range. A batch that fails is read
again (counted in ``reads_repeated``). A sample the drive no longer holds
(calib_status seq error) or a leg with a missing or faulted sample is
measured again with calib_point at the end (``points_repeated``): no leg is
ever analysed with fewer samples than asked for.
"""

from __future__ import annotations

import contextlib
import struct
import time
import zlib
from dataclasses import dataclass, field
from typing import Callable, Optional

from contour import protocol_gen as pg
from contour.calibration.analysis import ErrorMap, analyse
from contour.calibration.tables import corrections_nm, encode_record
from contour.errors import UserError
from contour.link.chunks import SamplePull, write_record
from contour.link.client import DriveError

# calib.h: seq, point, cycle, flags, enc, comp, ref, xenc, xcomp, xref
SAMPLE = struct.Struct("<IHBBiiiiii")
FLAG_NEG, FLAG_NO_REF, FLAG_FAULT, FLAG_NO_XREF = 1, 2, 4, 8
READ_MAX = 7  # CALIB_READ_MAX
SAMPLE_BYTES_V3 = 20  # protocol 3: no cross axis
CHUNK = 224
COMMIT_TIMEOUT_S = 5.0  # comp_commit answers after the flash write (erase: up to 2 s)


@dataclass
class RunConfig:
    axis: int
    targets_nm: list
    cycles: int = 1
    samples: int = 200
    sample_ticks: int = 2
    dwell_ms: int = 400
    overrun_nm: int = 1_000_000
    feed_nm_s: int = 50_000_000
    host_reference: bool = False

    def check(self) -> None:
        t = self.targets_nm
        if len(t) < 1:
            raise UserError("no calibration targets")
        if len(t) > 126:
            raise UserError(f"{len(t)} targets: the drive takes at most 126 per run")
        if any(b <= a for a, b in zip(t, t[1:])):
            raise UserError("calibration targets must increase")
        if not 1 <= self.samples <= 512:
            raise UserError(f"--samples {self.samples}: must be 1..512")
        if not 1 <= self.cycles <= 20:
            raise UserError(f"--cycles {self.cycles}: must be 1..20")


@dataclass
class Sample:
    seq: int
    point: int
    cycle: int
    flags: int
    enc: int  # nm, relative to the target
    comp: int
    ref: int
    # the cross axis (the other of X, Y; calib.h), nm, relative to its
    # held position: both coordinates of the 2-D reference in one reading
    xenc: int = 0
    xcomp: int = 0
    xref: int = 0

    @property
    def direction(self) -> int:
        return -1 if self.flags & FLAG_NEG else 1


@dataclass
class RunResult:
    config: RunConfig
    legs: dict = field(default_factory=dict)  # (point, dir, cycle) -> [Sample]
    frames_repeated: int = 0  # requests resent after a lost or corrupt frame
    reads_repeated: int = 0  # sample batches read again (failed checks)
    points_repeated: int = 0  # legs measured again
    samples_lost: int = 0  # samples the drive no longer held
    seconds: float = 0.0  # wall time

    def readings(self, column: str = "enc") -> list:
        """(position_mm, direction, error_mm) with error = column - ref."""
        out = []
        for (p, d, _c), ss in sorted(self.legs.items()):
            pos_mm = self.config.targets_nm[p] / 1e6
            for s in ss:
                out.append((pos_mm, d, (getattr(s, column) - s.ref) / 1e6))
        return out

    def encoder_means_mm(self) -> dict:
        """(point, direction) -> mean encoder position, mm (host reference)."""
        acc: dict = {}
        for (p, d, _c), ss in self.legs.items():
            a = acc.setdefault((p, d), [])
            a += [(self.config.targets_nm[p] + s.enc) / 1e6 for s in ss]
        return {k: sum(v) / len(v) for k, v in acc.items()}


def reason_text(code: int) -> str:
    try:
        return pg.CalibStatus(code).name.lower().replace("_", " ")
    except ValueError:
        return f"reason {code}"


class Calibrator:
    def __init__(
        self,
        client,
        wait: Callable[[float], None],
        progress: Optional[Callable[[int, int], None]] = None,
        poll_s: float = 0.02,
        timeout_s: float = 600.0,
    ) -> None:
        self.c = client
        self.wait = wait
        self.progress = progress
        self.poll_s = poll_s
        self.timeout_s = timeout_s
        self.pull = SamplePull(
            self._read_req,
            "calib_read",
            SAMPLE.size,
            READ_MAX,
            lambda: UserError("sample batches keep failing their checks: link too noisy"),
        )

    # ---- pieces ----------------------------------------------------------------

    def _req(self, name: str, **fields):
        try:
            return self.c.request(name, **fields).fields
        except DriveError as exc:
            f = exc.fields
            if f.get("code") == pg.ErrorCode.CALIB:
                raise DriveError(
                    name, f, f"drive refused {name}: {reason_text(f['arg'])} (detail {f['lo']})"
                ) from None
            raise

    def setup(self, cfg: RunConfig) -> None:
        cfg.check()
        self._req(
            "calib_setup",
            axis=cfg.axis,
            flags=1 if cfg.host_reference else 0,
            points=len(cfg.targets_nm),
            cycles=cfg.cycles,
            samples=cfg.samples,
            sample_ticks=cfg.sample_ticks,
            dwell_ms=cfg.dwell_ms,
            overrun=cfg.overrun_nm,
            feed=cfg.feed_nm_s,
        )
        per = 30
        for first in range(0, len(cfg.targets_nm), per):
            chunk = cfg.targets_nm[first : first + per]
            data = b"".join(struct.pack("<q", int(t)) for t in chunk)
            st = self._req("calib_targets", first=first, data=data)
        if st["targets_loaded"] != len(cfg.targets_nm):
            raise UserError(
                f"the drive holds {st['targets_loaded']} of {len(cfg.targets_nm)} targets"
            )

    def _read_req(self, name: str, **fields) -> dict:
        r = self._req(name, **fields)
        data, n = r["data"], r["count"]
        if n > 0 and len(data) == SAMPLE_BYTES_V3 * n and zlib.crc32(data) == r["crc"]:
            # an intact reply in the layout before the cross axis: not a
            # transmission error (session_open refuses such a drive first)
            raise UserError(
                f"the drive sends calibration samples of {SAMPLE_BYTES_V3} bytes (protocol 3),"
                f" this host reads {SAMPLE.size} (protocol {pg.PROTOCOL_VERSION}):"
                " update the drive's firmware (contour flash)"
            )
        return r

    def _read_batch(self, cfg: RunConfig, next_seq: int) -> list:
        """The samples of one intact calib_read from next_seq (read again
        while a chunk fails a check: SamplePull), or [("lost", oldest)]
        when the drive no longer holds next_seq."""

        def parse(r: dict) -> Optional[list]:
            out = []
            for i in range(r["count"]):
                s = Sample(*SAMPLE.unpack_from(r["data"], SAMPLE.size * i))
                if s.seq != next_seq + i or s.point >= len(cfg.targets_nm) or s.cycle >= cfg.cycles:
                    return None
                out.append(s)
            return out

        try:
            return self.pull.read(next_seq, parse)
        except DriveError as exc:
            if exc.fields.get("code") == pg.ErrorCode.CALIB and exc.fields.get("arg") == int(
                pg.CalibStatus.SEQ
            ):
                oldest = int(exc.fields["lo"])
                if oldest > next_seq:  # lost for good: legs are repeated later
                    return [("lost", oldest)]
            raise

    def _collect(self, cfg: RunConfig, res: RunResult, next_seq: int, legs_base: int) -> int:
        """Poll and read until the drive's run is DONE and all samples are in.
        Returns the next sequence number."""
        end = time.monotonic() + self.timeout_s
        while True:
            st = self._req("calib_status")
            if st["state"] == pg.CalibRunState.ERROR:
                raise UserError(
                    f"calibration stopped by the drive: {reason_text(st['reason'])}"
                    f" (detail {st['detail']})"
                )
            if self.progress is not None:
                self.progress(min(st["legs_done"] - legs_base, 10**9), st["legs_total"])
            got_any = False
            while next_seq < st["seq_next"]:
                repeated0 = self.pull.repeated
                try:
                    batch = self._read_batch(cfg, next_seq)
                finally:
                    res.reads_repeated += self.pull.repeated - repeated0
                if batch and isinstance(batch[0], tuple):
                    res.samples_lost += batch[0][1] - next_seq
                    next_seq = batch[0][1]
                    continue
                for s in batch:
                    res.legs.setdefault((s.point, s.direction, s.cycle), []).append(s)
                next_seq += len(batch)
                got_any = True
                if not batch:
                    break
            if st["state"] == pg.CalibRunState.DONE and next_seq >= st["seq_next"]:
                return next_seq
            if not got_any and st["seq_oldest"] < next_seq == st["seq_next"]:
                # release what was read: a leg of CALIB_RING samples waits for
                # the whole ring (a read from seq_next returns nothing)
                self.pull.release(next_seq)
            if time.monotonic() > end:
                raise UserError(f"calibration did not finish within {self.timeout_s:g} s")
            if not got_any:
                self.wait(self.poll_s)

    def _incomplete(self, cfg: RunConfig, res: RunResult) -> list:
        bad = []
        for c in range(cfg.cycles):
            for p in range(len(cfg.targets_nm)):
                for d in (1, -1):
                    ss = res.legs.get((p, d, c), [])
                    if len(ss) != cfg.samples or any(s.flags & FLAG_FAULT for s in ss):
                        bad.append((p, d, c))
        return bad

    # ---- the whole run -----------------------------------------------------------

    def run(self, cfg: RunConfig) -> RunResult:
        """The whole run. On any way out but success (an error, Ctrl-C,
        SIGTERM) the drive's run is aborted (calib_abort: the axes stop), so
        it never waits for a host that is gone; a host killed outright is
        covered by the drive's own watchdog (CALIB_HOST_TIMEOUT_MS)."""
        try:
            return self._run(cfg)
        except BaseException:
            self._abort()
            raise

    def _abort(self) -> None:
        with contextlib.suppress(Exception):  # best effort: the link may be the problem
            self.c.request("calib_abort", retries=2)

    def _run(self, cfg: RunConfig) -> RunResult:
        t0 = time.monotonic()
        retried0 = getattr(self.c, "retried", 0)
        res = RunResult(config=cfg)
        self.setup(cfg)
        for attempt in range(100):  # the drive may still be applying an enable
            try:
                st = self._req("calib_start")
                break
            except DriveError as exc:
                f = exc.fields
                busy = f.get("code") == pg.ErrorCode.CALIB and f.get("arg") == int(
                    pg.CalibStatus.DRIVE_DISABLED
                )
                if not busy or attempt == 99:
                    raise
                self.wait(self.poll_s)
        next_seq = self._collect(cfg, res, 0, 0)
        for _attempt in range(3):
            bad = self._incomplete(cfg, res)
            if not bad:
                break
            for p, d, c in bad:
                res.legs.pop((p, d, c), None)
                res.points_repeated += 1
                st = self._req("calib_point", point=p, dir=d, cycle=c)
                next_seq = self._collect(cfg, res, next_seq, st["legs_done"])
        else:
            bad = self._incomplete(cfg, res)
            if bad:
                raise UserError(f"{len(bad)} legs still incomplete after 3 repeats: refusing")
        res.frames_repeated = getattr(self.c, "retried", 0) - retried0
        res.seconds = time.monotonic() - t0
        return res


def errmap_from_run(res: RunResult, column: str = "enc", axis: str = "") -> ErrorMap:
    """Error map of a run against the drive's reference scale (column 'enc'
    before compensation, 'comp' after it)."""
    if res.config.host_reference:
        raise UserError("this run has no reference-scale readings (host reference)")
    return analyse(res.readings(column), axis=axis, source="reference scale")


def errmap_with_host_reference(res: RunResult, readings: list, axis: str = "") -> ErrorMap:
    """Error map of a host-reference run: the instrument's readings
    (position_mm, direction, reading_mm) matched to the drive's points by
    position (within 1 um) and direction; error = mean encoder - reading."""
    means = res.encoder_means_mm()
    targets = [t / 1e6 for t in res.config.targets_nm]
    out = []
    for pos, d, reading in readings:
        idx = min(range(len(targets)), key=lambda i: abs(targets[i] - pos))
        if abs(targets[idx] - pos) > 1e-3:
            raise UserError(f"reference reading at {pos:g} mm matches no calibration target")
        out.append((targets[idx], d, means[(idx, d)] - reading))
    return analyse(out, axis=axis, source="host reference")


def _drive_state(client) -> pg.State:
    return pg.State(client.status()["state"])


def _disable_for_write(client, wait: Callable[[float], None], timeout_s: float) -> None:
    """Disable the drive and wait until its tick has switched the axes off."""
    client.enable(False)
    polls = max(1, round(timeout_s / 0.005))
    for _ in range(polls):
        if _drive_state(client) == pg.State.DISABLED:
            return
        wait(0.005)
    raise UserError(f"the drive did not disable within {timeout_s:g} s")


def upload(
    client,
    axis: int,
    errmap: ErrorMap,
    ramp_us: int = 20000,
    wait: Callable[[float], None] = time.sleep,
    timeout_s: float = 2.0,
    notify: Optional[Callable[[str], None]] = None,
) -> dict:
    """Send the compensation table and make it active (comp_write chunks,
    comp_commit with the record's CRC-32); checks what the drive reports.

    The drive writes tables to flash only while disabled (a flash write
    stalls a single-bank MCU's control tick): a drive enabled at rest is
    disabled for the commit and enabled again afterwards, also when the
    commit is refused (``notify`` gets a line before the axes go off). A
    moving or faulted drive is refused before anything is sent."""
    record = encode_record(corrections_nm(errmap), axis, ramp_us=ramp_us)
    state = _drive_state(client)
    if state in (pg.State.RUNNING, pg.State.STOPPING):
        raise UserError(
            "the drive is moving: wait until it is at rest before writing a compensation table"
        )
    if state in (pg.State.FAULT, pg.State.ESTOP):
        raise UserError(
            f"the drive is in {state.name.lower()}: reset the fault before writing a"
            " compensation table"
        )
    write_record(
        lambda name, **f: client.request(name, **f).fields, "comp_write", record, CHUNK, axis=axis
    )
    was_enabled = state == pg.State.READY
    if was_enabled and notify is not None:
        notify(
            "disabling the drive for the flash write: the axes are unpowered until it is"
            " enabled again (up to a few seconds on a single-bank MCU)"
        )
    try:
        if was_enabled:
            _disable_for_write(client, wait, timeout_s)
        # the reply comes after the flash write (a sector erase takes up to 2 s)
        info = client.request(
            "comp_commit",
            axis=axis,
            length=len(record),
            crc=zlib.crc32(record),
            timeout=COMMIT_TIMEOUT_S,
        ).fields
    except (DriveError, UserError) as exc:
        err = exc
        if isinstance(exc, DriveError) and exc.fields.get("code") == pg.ErrorCode.CALIB:
            f = exc.fields
            err = UserError(
                f"drive refused the compensation table: {reason_text(f['arg'])} (detail {f['lo']});"
                " the previous table stays active"
            )
        if was_enabled:
            try:
                client.enable(True)
            except (DriveError, UserError) as exc2:
                raise UserError(f"{err}; enabling the drive again failed too: {exc2}") from None
        raise err from None
    if was_enabled:
        try:
            client.enable(True)
        except (DriveError, UserError) as exc:
            raise UserError(
                f"the table was written and is active, but enabling the drive again failed: {exc}"
            ) from None
    data_crc = zlib.crc32(record[32:])
    n = (len(record) - 32) // 16
    if info["n"] != n or info["data_crc"] != data_crc or info["ramp_us"] != ramp_us:
        raise UserError(
            f"the drive's active table ({info['n']} points, CRC {info['data_crc']:08X}) is not the"
            f" one sent ({n} points, CRC {data_crc:08X})"
        )
    return info
