"""ctypes binding of the simulator API (hil_sim/sim.h)."""

from __future__ import annotations

import ctypes as c

import numpy as np

from contour import native
from contour.errors import UserError

SIM_E = {
    -1: "bad argument or unknown name",
    -2: "simulator not set up / not started",
    -3: "axis model parameters refused",
    -4: "the drive refused the configuration or command",
    -5: "planner full",
}

DRIVE_RESULT = {
    0: "ok",
    1: "queue full",
    2: "invalid block or parameter",
    3: "drive disabled",
    4: "drive faulted",
    5: "busy (moving)",
    6: "fault cause still present",
}

DRIVE_STATES = {0: "disabled", 1: "idle", 2: "running", 3: "stopping", 4: "fault"}
FAULT_BITS = {
    1: "following_error",
    2: "encoder",
    4: "saturation",
    8: "amplifier",
    16: "estop",
    32: "comm_timeout",
    64: "homing",
    128: "oscillation",
}
CEC_MODES = {
    "off": 0,
    "tangent": 1,
    "curvature": 2,
    "exact": 3,
    "koren": 4,
    "calcr": 5,
    "chuang-liu": 6,
}
# how encoder edges reach the decoder (sim_encoder_model, docs/simulator.md
# "Encoder models"): "fast" (a substep's edges as one run, the same decoder
# state) or "edges" (every edge: the reference)
ENCODER_MODELS = {"edges": 0, "fast": 1}


def lib() -> c.CDLL:
    """The host library, bound and checked (contour.native)."""
    return native.load()


def check(rc: int, what: str) -> int:
    if rc < 0:
        raise UserError(f"simulator: {what}: {SIM_E.get(rc, f'error {rc}')}")
    return rc


Status = native.SimStatus  # sim_status_t (hil_sim/sim.h)


def status() -> Status:
    st = Status()
    check(lib().sim_drive_status(c.byref(st)), "status")
    return st


def fault_names(bits: int) -> list[str]:
    return [name for bit, name in FAULT_BITS.items() if bits & bit]


def run(ticks: int, every: int = 1, trace: bool = True) -> np.ndarray:
    """Run `ticks` control ticks; return the trace rows (one per `every`)."""
    so = lib()
    cols = so.sim_trace_cols()
    if not trace:
        check(so.sim_run(ticks, None, 0, 1), "run")
        return np.zeros((0, cols))
    rows = (ticks + every - 1) // every
    buf = np.zeros((rows, cols), dtype=np.float64)
    n = check(so.sim_run(ticks, buf.ctypes.data, rows, every), "run")
    return buf[:n]


def run_until_free(max_ticks: int, min_free: int) -> np.ndarray:
    """Run up to `max_ticks` ticks, stopping after the first one that leaves
    `min_free` free slots in the drive's host queue; trace rows of every tick."""
    so = lib()
    buf = np.zeros((max_ticks, so.sim_trace_cols()), dtype=np.float64)
    ran = c.c_uint64(0)
    n = check(
        so.sim_run_until_free(max_ticks, min_free, buf.ctypes.data, max_ticks, 1, c.byref(ran)),
        "run",
    )
    return buf[:n]


def run_until_idle(max_ticks: int, step: int) -> np.ndarray:
    """Run up to `max_ticks` ticks in steps of `step`, stopping after the
    first step that ends with the drive idle or faulted (as `run(step)` in a
    loop that polls `status()` after each); trace rows of every tick."""
    so = lib()
    buf = np.zeros((max_ticks, so.sim_trace_cols()), dtype=np.float64)
    ran = c.c_uint64(0)
    n = check(
        so.sim_run_until_idle(max_ticks, step, buf.ctypes.data, max_ticks, 1, c.byref(ran)),
        "run",
    )
    return buf[:n]


# drive_param_t (firmware/core/drive.h)
DRIVE_PARAMS = {
    "v_max": 0,
    "a_max": 1,
    "j_max": 2,
    "corner_dv": 3,
    "corner_acc": 4,
    "junction_dev": 5,
    "corner": 6,
    "shape": 7,
    "min_block_ns": 8,
    "mbt_window": 9,
    "stop_decel": 10,
    "arc_chord": 11,
    "start_delay_ms": 12,
}
DRIVE_QUEUE_DEPTH = 16


def drive_param(name: str, axis: int = 0) -> int:
    """A parameter of the running simulated drive (drive_param_get), in the
    drive's units (nm, nm/s, nm/s^2, nm/s^3, ns, ms)."""
    v = c.c_int64(0)
    if lib().drive_param_get(DRIVE_PARAMS[name], axis, c.byref(v)) != 0:
        raise UserError(f"simulator: drive parameter {name} (axis {axis}) not readable")
    return v.value


DriveBlock = native.DriveBlock  # drive_block_t (firmware/core/drive.h)


def arc_chords(
    start_nm,
    target_nm,
    feed_nm_s: int,
    plane: int,
    centre_u: int,
    centre_v: int,
    sense: int,
    axes: int,
    tick_hz: int,
    chord_nm: int,
) -> np.ndarray:
    """End points (n, 3) in nm of the chords the drive cuts this arc into
    (drive_arc_chords: the drive's own segmentation)."""
    b = DriveBlock(
        kind=2,
        target=(c.c_int64 * 3)(*[int(v) for v in target_nm]),
        feed_nm_s=int(feed_nm_s),
        plane=int(plane),
        centre_u=int(centre_u),
        centre_v=int(centre_v),
        sense=int(sense),
    )
    st = (c.c_int64 * 3)(*[int(v) for v in start_nm])
    so = lib()
    n = so.drive_arc_chords(c.byref(b), st, axes, tick_hz, int(chord_nm), None, 0)
    if n == 0:
        raise UserError("arc refused by the drive (radius mismatch or bad plane/feed)")
    out = np.zeros((n, 3), dtype=np.int64)
    so.drive_arc_chords(c.byref(b), st, axes, tick_hz, int(chord_nm), out.ctypes.data, n)
    return out


def queue_line(target_nm, feed_nm_s: int, tag: int = 0, exact_stop: bool = False) -> int:
    t = (c.c_int64 * 3)(*[int(v) for v in target_nm])
    res = c.c_int(0)
    lib().sim_queue_line(t, int(feed_nm_s), tag, int(exact_stop), c.byref(res))
    return res.value


def queue_arc(
    target_nm, feed_nm_s: int, plane: int, centre_u: int, centre_v: int, sense: int, tag: int = 0
) -> int:
    t = (c.c_int64 * 3)(*[int(v) for v in target_nm])
    res = c.c_int(0)
    lib().sim_queue_arc(
        t, int(feed_nm_s), plane, int(centre_u), int(centre_v), sense, tag, c.byref(res)
    )
    return res.value


def queue_dwell(ms: int, tag: int = 0) -> int:
    res = c.c_int(0)
    lib().sim_queue_dwell(int(ms), tag, c.byref(res))
    return res.value
