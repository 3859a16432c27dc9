"""`contour info [--json]`: identify the drive and show its state."""

from __future__ import annotations

import json

from contour import protocol_gen as pg
from contour.image import build_id_prefix
from contour.link.options import connect_from_args, link_options
from contour.operator import state_name


def _bits(value: int, enum) -> list[str]:
    return [e.name.lower() for e in enum if value & (1 << int(e))]


def in_bootloader(ident: dict) -> bool:
    """A bootloader identifies itself with no axes and only the bootloader
    capability (firmware/core/boot/boot.c)."""
    return ident["axes"] == 0 and ident["capabilities"] == 1 << pg.Capability.BOOTLOADER


def gather(client) -> dict:
    ident = client.identify()
    fw = ident["fw_version"]
    if in_bootloader(ident):  # no status to ask for: say so, disturb nothing
        return {
            "state": "bootloader",
            "bootloader_version": f"{fw >> 16}.{(fw >> 8) & 0xFF}.{fw & 0xFF}",
            "protocol_version": ident["protocol_version"],
            "host_protocol_version": pg.PROTOCOL_VERSION,
            "board_id": ident["board_id"],
            "node_id": ident["node_id"],
            "capabilities": _bits(ident["capabilities"], pg.Capability),
        }
    st = client.status()
    axes = ident["axes"]
    return {
        "firmware_version": f"{fw >> 16}.{(fw >> 8) & 0xFF}.{fw & 0xFF}",
        "build_id": build_id_prefix(ident["build_id"]),
        "protocol_version": ident["protocol_version"],
        "host_protocol_version": pg.PROTOCOL_VERSION,
        "board_id": ident["board_id"],
        "node_id": ident["node_id"],
        "axes": axes,
        "capabilities": _bits(ident["capabilities"], pg.Capability),
        "tick_hz": ident["tick_hz"],
        "planner_slots": ident["planner_slots"],
        "max_payload": ident["max_payload"],
        "state": state_name(st["state"]),
        "faults": _bits(st["faults"], pg.Fault),
        "free_slots": st["free_slots"],
        "queued_s": st["queued_us"] / 1e6,
        "blocks_done": st["blocks_done"],
        "position_mm": [p / 1e6 for p in st["pos"][:axes]],
        "link_rx_errors": st["rx_errors"],
        "link_replayed": st["replayed"],
    }


def run(args) -> int:
    with connect_from_args(args) as client:
        info = gather(client)
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    width = max(len(k) for k in info)
    for k, v in info.items():
        if isinstance(v, list):
            v = ", ".join(f"{x:.6f}" if isinstance(x, float) else str(x) for x in v) or "-"
        print(f"{k:<{width}}  {v}")
    if info["state"] == "bootloader":
        print("the drive runs its bootloader: flash an application with `contour flash`")
    if info["protocol_version"] != pg.PROTOCOL_VERSION:
        print(
            f"warning: drive speaks protocol {info['protocol_version']}, "
            f"this host {pg.PROTOCOL_VERSION}"
        )
    return 0


def register(sub) -> None:
    p = sub.add_parser(
        "info", help="identify the drive (versions, axes, state)", parents=[link_options()]
    )
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)
