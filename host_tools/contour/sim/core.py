"""ctypes binding of the simulator API (hil_sim/sim.h)."""

from __future__ import annotations

import ctypes as c
from functools import lru_cache

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
}
CEC_MODES = {"off": 0, "tangent": 1, "curvature": 2, "exact": 3}

_PROTOS = {
    "sim_setup": (c.c_int, [c.c_double, c.c_uint]),
    "sim_axis_set": (c.c_int, [c.c_uint, c.c_char_p, c.c_double]),
    "sim_axis_get": (c.c_int, [c.c_uint, c.c_char_p, c.POINTER(c.c_double)]),
    "sim_axis_pitch": (
        c.c_int,
        [c.c_uint, c.c_uint, c.c_void_p, c.c_void_p, c.c_void_p],
    ),
    "sim_set_substep": (c.c_int, [c.c_double]),
    "sim_gain_set": (c.c_int, [c.c_int, c.c_char_p, c.c_double]),
    "sim_servo_set": (c.c_int, [c.c_uint, c.c_char_p, c.c_double]),
    "sim_plan_set": (c.c_int, [c.c_uint, c.c_char_p, c.c_double]),
    "sim_cec_mode": (c.c_int, [c.c_int]),
    "sim_set_link": (
        c.c_int,
        [c.c_uint, c.c_int, c.c_int, c.c_uint32, c.c_uint32, c.c_uint32, c.c_int],
    ),
    "sim_start": (c.c_int, []),
    "sim_enable": (c.c_int, [c.c_int]),
    "sim_run": (c.c_long, [c.c_uint64, c.c_void_p, c.c_size_t, c.c_uint]),
    "sim_run_until_free": (
        c.c_long,
        [c.c_uint64, c.c_uint, c.c_void_p, c.c_size_t, c.c_uint, c.POINTER(c.c_uint64)],
    ),
    "drive_param_get": (c.c_int, [c.c_int, c.c_uint, c.POINTER(c.c_int64)]),
    "drive_arc_chords": (
        c.c_uint32,
        [c.c_void_p, c.c_void_p, c.c_uint, c.c_uint32, c.c_int64, c.c_void_p, c.c_uint32],
    ),
    "sim_trace_cols": (c.c_uint, []),
    "sim_tick_hz": (c.c_uint32, []),
    "sim_ticks": (c.c_uint64, []),
    "sim_time_s": (c.c_double, []),
    "sim_edges": (c.c_uint64, []),
    "sim_edge_mismatches": (c.c_uint64, []),
    "sim_substeps": (c.c_uint, []),
    "sim_table_pos": (c.c_double, [c.c_uint]),
    "sim_queue_line": (
        c.c_int,
        [c.c_void_p, c.c_int64, c.c_uint32, c.c_int, c.POINTER(c.c_int)],
    ),
    "sim_queue_arc": (
        c.c_int,
        [
            c.c_void_p,
            c.c_int64,
            c.c_int,
            c.c_int64,
            c.c_int64,
            c.c_int,
            c.c_uint32,
            c.POINTER(c.c_int),
        ],
    ),
    "sim_drive_status": (c.c_int, [c.c_void_p]),
    "sim_queue_dwell": (c.c_int, [c.c_uint32, c.c_uint32, c.POINTER(c.c_int)]),
}


@lru_cache(maxsize=1)
def lib() -> c.CDLL:
    so = native.load()
    for name, (res, args) in _PROTOS.items():
        fn = getattr(so, name, None)
        if fn is None:
            raise UserError(f"{native.library_path()} lacks {name}: rebuild it with `make host`")
        fn.restype = res
        fn.argtypes = args
    return so


def check(rc: int, what: str) -> int:
    if rc < 0:
        raise UserError(f"simulator: {what}: {SIM_E.get(rc, f'error {rc}')}")
    return rc


class Status(c.Structure):
    """The part of drive_status_t that sim_drive_status copies (sim.h)."""

    _fields_ = [
        ("state", c.c_int),
        ("faults", c.c_uint32),
        ("queue_free", c.c_uint32),
        ("blocks_done", c.c_uint32),
        ("tag", c.c_uint32),
        ("tick", c.c_uint64),
        ("queued_time_ns", c.c_int64),
    ]


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


class DriveBlock(c.Structure):
    """drive_block_t of firmware/core/drive.h (arc fields used here)."""

    _fields_ = [
        ("kind", c.c_int),
        ("tag", c.c_uint32),
        ("target", c.c_int64 * 3),
        ("feed_nm_s", c.c_int64),
        ("exact_stop", c.c_bool),
        ("plane", c.c_int),
        ("centre_u", c.c_int64),
        ("centre_v", c.c_int64),
        ("sense", c.c_int8),
        ("dwell_ms", c.c_uint32),
    ]


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
