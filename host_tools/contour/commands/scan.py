"""`contour scan --can IFACE:CHANNEL`: list the drives on a CAN bus.

Listens only: every drive sends a heartbeat frame (function 31, default 1 Hz)
and possibly status frames; the scan reads them for ``--time`` seconds and
transmits nothing, so running drives are not disturbed.
"""

from __future__ import annotations

import json
import time

from contour import protocol_gen as pg
from contour.errors import UsageError
from contour.link import codec
from contour.link.options import link_options, target_from_args
from contour.link.transport import open_can_bus


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
            if f is None or f.is_extended_id or f.arbitration_id > 0x7FF:
                continue
            func = f.arbitration_id >> pg.CAN_NODE_BITS
            node = f.arbitration_id & pg.CAN_NODE_MAX
            if node == 0:
                continue
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
    print(f"{'node':>4}  {'state':<10} {'axes':>4}  {'firmware':<9} {'protocol':>8}")
    for e in found.values():
        print(
            f"{e['node']:>4}  {e.get('state', '?'):<10} {e.get('axes', '?'):>4}  "
            f"{e.get('firmware_version', '?'):<9} {e.get('protocol_version', '?'):>8}"
        )
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "scan", help="list the drives on a CAN bus (listen only)", parents=[link_options()]
    )
    p.add_argument("--time", type=float, default=2.5, help="listen time, s (default 2.5)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)
