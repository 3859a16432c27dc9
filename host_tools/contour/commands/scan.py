"""`contour scan --can IFACE:CHANNEL`: list the drives on a CAN bus.

Listens only: every drive sends a heartbeat frame (function 31, default 1 Hz,
on its 29-bit id; docs/canopen.md) and possibly status frames; the scan reads
them for ``--time`` seconds and transmits nothing, so running drives are not
disturbed. It also lists the CANopen nodes it hears (heartbeat or boot-up on
0x700 + n: ``canopen`` with the NMT state) and drives of protocol 2, whose
frames were 11-bit (heartbeat 0x7C0 + n): those need a firmware update
before this host can talk to them.
"""

from __future__ import annotations

import json
import time

from contour import protocol_gen as pg
from contour.errors import UsageError
from contour.link import codec
from contour.link.options import link_options, target_from_args
from contour.link.transport import open_can_bus

OLD_NODE_BITS = 6  # protocol 2: 11-bit id = func << 6 | node
NMT_STATES = {0x00: "boot-up", 0x04: "stopped", 0x05: "operational", 0x7F: "pre-operational"}


def scan(bus_config, seconds: float) -> dict[int, dict]:
    """Drives heard on the bus (python-can config dict, CanBus or
    ``INTERFACE:CHANNEL``) in `seconds`, by node."""
    bus = open_can_bus(bus_config)
    found: dict[int, dict] = {}
    hb = pg.CAN_FUNC["heartbeat"]
    try:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            f = bus.recv(timeout=max(0.0, min(0.1, end - time.monotonic())))
            if f is None or f.is_remote_frame or f.is_error_frame:
                continue
            if not f.is_extended_id:
                _standard(found, f)
                continue
            split = pg.can_split(f.arbitration_id)
            if split is None or split[1] == 0:
                continue
            func, node = split
            entry = found.setdefault(node, {"node": node, "frames": 0})
            entry["frames"] += 1
            if func == hb and len(f.data) == 8:
                d = codec.decode_cyclic(func, bytes(f.data)).fields
                fw = d["fw_version"]
                try:
                    state = pg.State(d["state"]).name.lower()
                except ValueError:
                    state = str(d["state"])
                entry.update(
                    state=state,
                    axes=d["axes"],
                    protocol_version=d["protocol_version"],
                    firmware_version=f"{fw >> 16}.{(fw >> 8) & 0xFF}.{fw & 0xFF}",
                )
    finally:
        bus.shutdown()
    return dict(sorted(found.items()))


def _standard(found: dict, f) -> None:
    """An 11-bit frame: a CANopen heartbeat / boot-up, or an old drive's."""
    cid = f.arbitration_id
    if 0x701 <= cid <= 0x77F and len(f.data) == 1:
        entry = found.setdefault(cid - 0x700, {"node": cid - 0x700, "frames": 0})
        entry["frames"] += 1
        entry["canopen"] = NMT_STATES.get(f.data[0], hex(f.data[0]))
        return
    if cid >> OLD_NODE_BITS == pg.CAN_FUNC["heartbeat"] and len(f.data) == 8:
        node = cid & ((1 << OLD_NODE_BITS) - 1)
        d = codec.decode_cyclic(pg.CAN_FUNC["heartbeat"], bytes(f.data)).fields
        entry = found.setdefault(node, {"node": node, "frames": 0})
        entry["frames"] += 1
        entry["protocol_version"] = d["protocol_version"]
        entry["state"] = "old-ids"  # speaks 11-bit ids: update its firmware


def run(args) -> int:
    if not 0 < args.time <= 60:
        raise UsageError("--time must be in (0, 60] seconds")
    target = target_from_args(args, can_only=True)
    found = scan(target.can, args.time)
    if args.json:
        print(json.dumps(list(found.values()), indent=2))
        return 0
    if not found:
        bus = f"{target.can['interface']}:{target.can['channel']}"
        print(f"no drives heard on {bus} in {args.time:g} s")
        return 1
    print(f"{'node':>4}  {'state':<10} {'axes':>4}  {'firmware':<9} {'protocol':>8}  canopen")
    old = []
    for e in found.values():
        print(
            f"{e['node']:>4}  {e.get('state', '-'):<10} {e.get('axes', '-'):>4}  "
            f"{e.get('firmware_version', '-'):<9} {e.get('protocol_version', '-'):>8}  "
            f"{e.get('canopen', '-')}"
        )
        if e.get("state") == "old-ids":
            old.append(e)
    for e in old:
        print(
            f"node {e['node']}: protocol {e['protocol_version']} on 11-bit ids; this host "
            f"speaks {pg.PROTOCOL_VERSION} on 29-bit ids: flash this firmware over serial"
        )
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "scan", help="list the drives on a CAN bus (listen only)", parents=[link_options()]
    )
    p.add_argument("--time", type=float, default=2.5, help="listen time, s (default 2.5)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)
