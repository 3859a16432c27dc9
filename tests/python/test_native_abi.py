"""contour.native: every mirrored C structure has the C layout, and a mirror
that lost a field is refused (hil_sim/sim_abi.c)."""

from __future__ import annotations

import ctypes

import numpy as np
import pytest
from contour import native
from contour.errors import UserError


def _without(mirror, field: str):
    """A copy of a Python mirror with one field removed."""
    if isinstance(mirror, np.dtype):
        return np.dtype([(n, mirror.fields[n][0]) for n in mirror.names if n != field], align=True)
    fields = [f for f in mirror._fields_ if f[0] != field]
    return type(f"Broken{mirror.__name__}", (ctypes.Structure,), {"_fields_": fields})


def _field_names(mirror) -> list[str]:
    if isinstance(mirror, np.dtype):
        return list(mirror.names)
    return [f[0] for f in mirror._fields_]


@pytest.mark.parametrize("name", sorted(native.MIRRORS))
def test_mirror_matches_c(name):
    lib = native.load()
    have = native.mirror_layout(native.MIRRORS[name])
    size, nfields, offs = native.c_layout(lib, name, [f for f, _ in have.offsets])
    assert size > 0, f"{name} missing from hil_sim/sim_abi.c"
    assert (size, nfields, offs) == (have.size, len(have.offsets), have.offsets)


def test_every_c_structure_passed_is_mirrored():
    # every POINTER(Structure) in a signature (result or argument) is checked
    mirrored = {m for m in native.MIRRORS.values() if not isinstance(m, np.dtype)}
    for fn, (res, args) in native.SIGNATURES.items():
        for a in [res, *args]:
            target = getattr(a, "_type_", None)
            if isinstance(target, type) and issubclass(target, ctypes.Structure):
                assert target in mirrored, f"{fn}: {target.__name__} is not in MIRRORS"


@pytest.mark.parametrize(
    "name,field",
    [(n, f) for n in sorted(native.MIRRORS) for f in _field_names(native.MIRRORS[n])],
)
def test_a_removed_field_is_caught(name, field):
    lib = native.load()
    broken = {name: _without(native.MIRRORS[name], field)}
    bad = native.layout_mismatches(lib, broken)
    assert len(bad) == 1 and bad[0].startswith(name), bad


def test_unknown_structure_is_reported():
    lib = native.load()
    bad = native.layout_mismatches(lib, {"no_such_t": native.SimStatus})
    assert bad and "does not describe" in bad[0]


def test_load_refuses_a_mismatch(monkeypatch):
    broken = dict(native.MIRRORS)
    broken["sim_status_t"] = _without(native.SimStatus, "queued_time_ns")
    monkeypatch.setattr(native, "MIRRORS", broken)
    with pytest.raises(UserError, match="sim_status_t: C has 40 bytes and 7 fields"):
        native._load.__wrapped__()  # uncached (load() is instance-aware)


def test_load_binds_every_signature():
    lib = native.load()
    for name, (res, args) in native.SIGNATURES.items():
        fn = getattr(lib, name)
        assert fn.restype is res and list(fn.argtypes) == list(args), name


def test_drive_instances_keep_their_own_firmware_state():
    """sim serve --drives: every instance but 0 is a private copy of the
    library, so its static state (here the simulator's tick rate) is its own."""
    a = native.load_instance(0)
    b, c2 = native.load_instance(1), native.load_instance(2)
    assert a is native.load() and b is not a and c2 is not b
    assert b.sim_setup(2000, 1) == 0 and c2.sim_setup(4000, 1) == 0
    assert (b.sim_tick_hz(), c2.sim_tick_hz()) == (2000, 4000)
    with native.instance(b):
        assert native.load() is b
    assert native.load() is a
