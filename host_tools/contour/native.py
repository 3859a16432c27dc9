"""Loads the host build of the firmware core (build/host/libcontour.so).

The job-time estimator and the simulator call the same C code as the drive
through this one library; ``make`` (or ``make host``) builds it. Set
CONTOUR_LIB to use another build.

This module is the only place that knows the library's C interface: every
function's ctypes signature (:data:`SIGNATURES`) and every C structure the
host passes through it (:data:`MIRRORS`). :func:`load` binds the signatures
once and compares each mirrored structure with the C layout the library
reports (hil_sim/sim_abi.c), so a field changed on one side only is an
error at load time instead of corrupted memory.
"""

from __future__ import annotations

import contextlib
import ctypes as c
import os
import shutil
import tempfile
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Union

import numpy as np

from contour.errors import UserError

REPO_ROOT = Path(__file__).resolve().parents[2]

AXES = 3  # CORE_AXES (firmware/core/core_config.h)


# --- mirrored C structures -------------------------------------------------


class SimStatus(c.Structure):
    """sim_status_t (hil_sim/sim.h): the drive's status in a fixed layout."""

    _fields_ = [
        ("state", c.c_int),
        ("faults", c.c_uint32),
        ("queue_free", c.c_uint32),
        ("blocks_done", c.c_uint32),
        ("tag", c.c_uint32),
        ("tick", c.c_uint64),
        ("queued_time_ns", c.c_int64),
    ]


class DriveBlock(c.Structure):
    """drive_block_t (firmware/core/drive.h)."""

    _fields_ = [
        ("kind", c.c_int),
        ("tag", c.c_uint32),
        ("target", c.c_int64 * AXES),
        ("feed_nm_s", c.c_int64),
        ("exact_stop", c.c_bool),
        ("plane", c.c_int),
        ("centre_u", c.c_int64),
        ("centre_v", c.c_int64),
        ("sense", c.c_int8),
        ("dwell_ms", c.c_uint32),
    ]


class PlanProfile(c.Structure):
    """plan_profile_t (firmware/core/planner.h)."""

    _fields_ = [
        ("v_max", c.c_int64 * AXES),
        ("a_max", c.c_int64 * AXES),
        ("j_max", c.c_int64 * AXES),
        ("corner_dv", c.c_int64 * AXES),
        ("corner_acc", c.c_int64 * AXES),
        ("junction_dev_nm", c.c_int64),
        ("min_block_ns", c.c_int64),
        ("mbt_window", c.c_uint16),
        ("corner", c.c_uint8),
        ("shape", c.c_uint8),
    ]


class ProtoMsgInfo(c.Structure):
    """proto_msg_info_t (firmware/core/proto_msgs.h, generated)."""

    _fields_ = [
        ("id", c.c_uint8),
        ("dir", c.c_uint8),
        ("reply", c.c_uint8),
        ("can_func", c.c_uint8),
        ("min_len", c.c_uint16),
        ("max_len", c.c_uint16),
        ("name", c.c_char_p),
    ]


class GcodeScan(c.Structure):
    """gcode_scan_t (hil_sim/gcode_scan.h): the G-code reader's plain-line
    fast path (contour.gcode.fastscan)."""

    _fields_ = [
        ("pos", c.c_double * 6),
        ("origin", c.c_double * 6),
        ("scale", c.c_double),
        ("feed", c.c_double),
        ("tol", c.c_double),
        ("row_base", c.c_int64),
        ("motion", c.c_int32),
        ("absolute", c.c_int32),
        ("arc_abs", c.c_int32),
        ("plane", c.c_int32),
        ("stop", c.c_int32),
        ("line", c.c_int32),
        ("rows", c.c_int32),
        ("cap", c.c_int32),
        ("arcs", c.c_int32),
        ("gseen", c.c_int32),
        ("kind", c.c_void_p),
        ("end", c.c_void_p),
        ("feeds", c.c_void_p),
        ("stops", c.c_void_p),
        ("lines", c.c_void_p),
        ("arc_row", c.c_void_p),
        ("arc_centre", c.c_void_p),
    ]


# plan_move_t (firmware/core/planner.h), as a numpy record for whole arrays
PLAN_MOVE_DTYPE = np.dtype(
    [
        ("target", "<i8", (AXES,)),
        ("feed", "<i8"),
        ("dwell_ns", "<i8"),
        ("tag", "<u4"),
        ("flags", "u1"),
    ],
    align=True,
)

# plan_est_t (firmware/core/estimator.h), as a numpy record
PLAN_EST_DTYPE = np.dtype(
    [
        ("len_nm", "<i8"),
        ("v_entry", "<i8"),
        ("v_peak", "<i8"),
        ("v_exit", "<i8"),
        ("v_max", "<i8"),
        ("t_acc_ns", "<i8"),
        ("t_cruise_ns", "<i8"),
        ("t_dec_ns", "<i8"),
        ("t_total_ns", "<i8"),
        ("t_mbt_ns", "<i8"),
        ("tag", "<u4"),
        ("flags", "<u4"),
    ],
    align=True,
)


# C type name -> its Python mirror; the C side of each is in hil_sim/sim_abi.c
class Comp2dMap(c.Structure):
    """comp2d_map_t (firmware/core/comp2d.h): the 2-D compensation map
    (contour.calibration.map2d)."""

    _fields_ = [
        ("version", c.c_uint16),
        ("nx", c.c_uint8),
        ("ny", c.c_uint8),
        ("shift", c.c_uint8),
        ("x0", c.c_int64),
        ("y0", c.c_int64),
        ("dx", c.c_uint32),
        ("dy", c.c_uint32),
        ("inv_dx", c.c_uint32),
        ("inv_dy", c.c_uint32),
        ("g", c.c_int16 * 144 * 3 * 2),
    ]


MIRRORS: dict[str, Union[type, np.dtype]] = {
    "sim_status_t": SimStatus,
    "comp2d_map_t": Comp2dMap,
    "drive_block_t": DriveBlock,
    "plan_profile_t": PlanProfile,
    "plan_move_t": PLAN_MOVE_DTYPE,
    "plan_est_t": PLAN_EST_DTYPE,
    "proto_msg_info_t": ProtoMsgInfo,
    "gcode_scan_t": GcodeScan,
}


@dataclass(frozen=True)
class Layout:
    size: int
    offsets: tuple  # ((field, offset), ...) in declaration order


def mirror_layout(mirror: Union[type, np.dtype]) -> Layout:
    """Size and field offsets of a Python mirror."""
    if isinstance(mirror, np.dtype):
        return Layout(mirror.itemsize, tuple((n, mirror.fields[n][1]) for n in mirror.names))
    return Layout(
        c.sizeof(mirror), tuple((f[0], getattr(mirror, f[0]).offset) for f in mirror._fields_)
    )


def c_layout(lib: c.CDLL, name: str, fields) -> tuple[int, int, tuple]:
    """sizeof, number of fields, and the offsets of `fields` of C type `name`
    as the library reports them (hil_sim/sim_abi.c; SIZE_MAX: no such field)."""
    t = name.encode()
    offs = tuple((f, lib.sim_abi_offsetof(t, f.encode())) for f in fields)
    return lib.sim_abi_sizeof(t), lib.sim_abi_fields(t), offs


# --- function signatures: name -> (restype, argtypes) ----------------------

_p = c.POINTER
SIGNATURES: dict[str, tuple] = {
    # layout of the mirrored structures (hil_sim/sim_abi.h)
    "sim_abi_sizeof": (c.c_size_t, [c.c_char_p]),
    "sim_abi_fields": (c.c_size_t, [c.c_char_p]),
    "sim_abi_offsetof": (c.c_size_t, [c.c_char_p, c.c_char_p]),
    # simulator (hil_sim/sim.h)
    "sim_setup": (c.c_int, [c.c_double, c.c_uint]),
    "sim_axis_set": (c.c_int, [c.c_uint, c.c_char_p, c.c_double]),
    "sim_axis_get": (c.c_int, [c.c_uint, c.c_char_p, _p(c.c_double)]),
    "sim_axis_pitch": (c.c_int, [c.c_uint, c.c_uint, c.c_void_p, c.c_void_p, c.c_void_p]),
    "sim_field2d": (
        c.c_int,
        [c.c_uint, c.c_uint, c.c_double, c.c_double, c.c_double, c.c_double, c.c_void_p]
        + [c.c_void_p, c.c_uint, c.c_double, c.c_double, c.c_void_p, c.c_double],
    ),
    "sim_set_substep": (c.c_int, [c.c_double]),
    "sim_trace_table_mean": (c.c_int, [c.c_int]),
    "sim_table_record": (c.c_int, [c.c_void_p, c.c_size_t, c.c_double]),
    "sim_table_recorded": (c.c_size_t, []),
    "sim_table_record_hz": (c.c_double, []),
    "sim_encoder_model": (c.c_int, [c.c_int]),
    "sim_encoder_model_get": (c.c_int, []),
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
        [c.c_uint64, c.c_uint, c.c_void_p, c.c_size_t, c.c_uint, _p(c.c_uint64)],
    ),
    "sim_run_until_idle": (
        c.c_long,
        [c.c_uint64, c.c_uint, c.c_void_p, c.c_size_t, c.c_uint, _p(c.c_uint64)],
    ),
    "sim_inject": (c.c_int, [c.c_uint, c.c_void_p, c.c_size_t]),
    "sim_inject_left": (c.c_size_t, [c.c_uint]),
    "sim_trace_cols": (c.c_uint, []),
    "sim_tick_hz": (c.c_uint32, []),
    "sim_ticks": (c.c_uint64, []),
    "sim_time_s": (c.c_double, []),
    "sim_edges": (c.c_uint64, []),
    "sim_edge_mismatches": (c.c_uint64, []),
    "sim_run_edges": (c.c_uint64, []),
    "sim_substeps": (c.c_uint, []),
    "sim_table_pos": (c.c_double, [c.c_uint]),
    "sim_queue_line": (c.c_int, [c.c_void_p, c.c_int64, c.c_uint32, c.c_int, _p(c.c_int)]),
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
            _p(c.c_int),
        ],
    ),
    "sim_drive_status": (c.c_int, [_p(SimStatus)]),
    "sim_queue_dwell": (c.c_int, [c.c_uint32, c.c_uint32, _p(c.c_int)]),
    # drive (firmware/core/drive.h)
    "drive_param_get": (c.c_int, [c.c_int, c.c_uint, _p(c.c_int64)]),
    "drive_arc_chords": (
        c.c_uint32,
        [_p(DriveBlock), c.c_void_p, c.c_uint, c.c_uint32, c.c_int64, c.c_void_p, c.c_uint32],
    ),
    # planner over whole arrays (firmware/core/estimator.h)
    "plan_estimate": (
        c.c_int,
        [
            _p(PlanProfile),
            _p(c.c_int64),
            c.c_void_p,
            c.c_uint32,
            c.c_void_p,
            c.c_uint16,
            c.c_void_p,
            _p(c.c_uint32),
        ],
    ),
    "plan_check_profile": (c.c_int, [_p(PlanProfile)]),
    "plan_block_sizeof": (c.c_size_t, []),
    "plan_est_sizeof": (c.c_size_t, []),
    "plan_move_sizeof": (c.c_size_t, []),
    "plan_profile_sizeof": (c.c_size_t, []),
    # host link (firmware/core/proto_link.h, proto_frame.h, proto_msgs.h)
    "proto_link_poll": (None, []),
    "proto_frame_encode": (c.c_size_t, [c.c_char_p, c.c_size_t, c.c_char_p, c.c_size_t]),
    "proto_frame_rx_init": (None, [c.c_void_p]),
    "proto_frame_rx_byte": (
        c.c_bool,
        [c.c_void_p, c.c_uint8, _p(_p(c.c_uint8)), _p(c.c_size_t)],
    ),
    "proto_msg_info": (_p(ProtoMsgInfo), [c.c_uint8]),
    # G-code plain-line fast path (hil_sim/gcode_scan.h)
    "gcode_scan": (c.c_size_t, [c.c_char_p, c.c_size_t, c.c_size_t, _p(GcodeScan)]),
    # compensation tables (firmware/core/comp.h)
    "comp_record_decode": (c.c_int, [c.c_char_p, c.c_size_t, c.c_void_p]),
    # 2-D compensation map (firmware/core/comp2d.h)
    "comp2d_check": (c.c_int, [_p(Comp2dMap), _p(c.c_int64), _p(c.c_int64)]),
    "comp2d_prepare": (None, [_p(Comp2dMap)]),
    "comp2d_correct": (None, [_p(Comp2dMap), _p(c.c_int64), _p(c.c_int32), _p(c.c_int64)]),
    "comp2d_encode": (c.c_uint32, [_p(Comp2dMap), c.c_char_p, c.c_uint32]),
    "comp2d_decode": (c.c_int, [c.c_char_p, c.c_uint32, _p(Comp2dMap)]),
    # bootloader and flash of the simulated drive (firmware/ports/sim)
    "boot_sim_serve_link": (c.c_bool, []),
    "boot_sim_init": (c.c_bool, [c.c_char_p, c.c_uint8, c.c_uint32]),
    "boot_sim_reset": (c.c_int, []),
    "boot_sim_poll": (None, []),
    "boot_sim_mode": (c.c_int, []),
    "boot_sim_reason": (c.c_int, []),
    "boot_sim_resets": (c.c_uint32, []),
    "boot_sim_app_version": (c.c_uint32, []),
    "boot_sim_app_build_id": (c.c_uint32, []),
    "boot_sim_handle": (c.c_size_t, [c.c_char_p, c.c_size_t, c.c_char_p, c.c_size_t]),
    "boot_sim_drive_handle": (c.c_size_t, [c.c_char_p, c.c_size_t, c.c_char_p, c.c_size_t]),
    "flash_sim_configure": (c.c_bool, [c.c_uint32, c.c_uint32, c.c_uint32, c.c_uint32]),
    "flash_sim_power_cut_after": (None, [c.c_long]),
    "flash_sim_powered": (c.c_bool, []),
    # simulated peripherals (firmware/ports/sim/hal_sim.h)
    "hal_sim_take_reset_request": (c.c_bool, []),
    "hal_sim_time_ns": (c.c_uint64, []),
    "hal_sim_set_time_ns": (None, [c.c_uint64]),
    "hal_sim_uart_inject": (c.c_size_t, [c.c_char_p, c.c_size_t]),
    "hal_sim_uart_drain": (c.c_size_t, [c.c_char_p, c.c_size_t]),
    "hal_sim_can_inject": (c.c_bool, [c.c_uint32, c.c_char_p, c.c_uint8]),
    "hal_sim_can_drain": (c.c_bool, [_p(c.c_uint32), c.c_char_p, _p(c.c_uint8)]),
}
del _p


def library_path() -> Path:
    env = os.environ.get("CONTOUR_LIB")
    if env:
        return Path(env)
    return REPO_ROOT / "build" / "host" / "libcontour.so"


def bind(lib: c.CDLL) -> None:
    """Give every function of :data:`SIGNATURES` its ctypes signature."""
    for name, (res, args) in SIGNATURES.items():
        fn = getattr(lib, name, None)
        if fn is None:
            raise UserError(f"{library_path()} lacks {name}: rebuild it with `make host`")
        fn.restype = res
        fn.argtypes = args


def layout_mismatches(lib: c.CDLL, mirrors=None) -> list[str]:
    """One line per mirrored structure whose Python layout differs from C."""
    out = []
    for name, mirror in (MIRRORS if mirrors is None else mirrors).items():
        have = mirror_layout(mirror)
        size, nfields, offs = c_layout(lib, name, [f for f, _ in have.offsets])
        if size == 0:
            out.append(f"{name}: the library does not describe it (sim_abi.c)")
            continue
        diff = [
            f"{f} at {o} (C: {'none' if co == c.c_size_t(-1).value else co})"
            for (f, o), (_, co) in zip(have.offsets, offs)
            if o != co
        ]
        if size != have.size or nfields != len(have.offsets) or diff:
            out.append(
                f"{name}: C has {size} bytes and {nfields} fields, the Python mirror "
                f"{have.size} bytes and {len(have.offsets)} fields"
                + (" (" + ", ".join(diff) + ")" if diff else "")
            )
    return out


_current: list = []  # instance() stack: the library load() returns while set


def load() -> c.CDLL:
    """The library, every signature bound, its structures checked (or the
    drive instance an :func:`instance` block selected)."""
    if _current:
        return _current[-1]
    return _load()


@contextlib.contextmanager
def instance(lib: c.CDLL):
    """Within the block, :func:`load` (and everything built on it, e.g.
    ``contour.sim.machine.apply``) uses `lib`: one of several simulated
    drives in this process (:func:`load_instance`). Not thread-safe: set up
    drives from one thread."""
    _current.append(lib)
    try:
        yield lib
    finally:
        _current.pop()


def load_instance(i: int) -> c.CDLL:
    """Drive instance `i` of the library: 0 is :func:`load`'s; any other is
    a private copy of the file, loaded apart (RTLD_LOCAL), so its firmware
    state (static variables: drive, link, CANopen node) is its own. Several
    simulated drives on one bus run in one process this way (`sim serve
    --drives N`)."""
    if i == 0:
        return _load()
    path = library_path()
    if not path.exists():
        raise UserError(f"{path} not found: run `make` to build the host library")
    with tempfile.TemporaryDirectory(prefix="contour-drive-") as d:
        copy = Path(d) / f"libcontour-{i}.so"
        shutil.copyfile(path, copy)
        lib = c.CDLL(str(copy), mode=os.RTLD_LOCAL)  # the file may go once mapped
    bind(lib)
    return lib


@lru_cache(maxsize=1)
def _load() -> c.CDLL:
    path = library_path()
    if not path.exists():
        raise UserError(f"{path} not found: run `make` to build the host library")
    lib = c.CDLL(str(path))
    bind(lib)
    bad = layout_mismatches(lib)
    if bad:
        raise UserError(
            f"{path}: C structures do not match contour.native (rebuild with `make host`, "
            "or update the mirror): " + "; ".join(bad)
        )
    return lib
