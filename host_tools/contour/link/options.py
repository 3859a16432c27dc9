"""The drive-link options, the same on every command, and the link they name.

Every command that talks to a drive takes its options from one argparse
parent, :func:`link_options` (``sub.add_parser(..., parents=[link_options()])``):

    --port PATH            serial device or pyserial URL
    --can IFACE:CHANNEL    short form of --interface IFACE --channel CHANNEL;
                           the channel is python-can's text verbatim, so
                           slcan:/dev/ttyACM0@115200 is the adapter's serial baud
    --interface NAME       python-can interface (socketcan, slcan, pcan, virtual ...)
    --channel NAME         python-can channel
    --bitrate N            CAN bitrate, bit/s (python-can's ``bitrate``)
    --node N               CAN node id of the drive
    --timeout S            reply timeout per try

A CAN bus not (fully) named on the command line is completed the way
python-can does it (``can.util.load_config``): ``CAN_INTERFACE``,
``CAN_CHANNEL``, ``CAN_BITRATE`` and ``CAN_CONFIG`` in the environment, then
its config files (``~/can.conf``, ``/etc/can.conf``, ``~/.can``, ``~/.canrc``).
Every mistake in these options is a UsageError (exit code 2) raised before
anything is opened.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from typing import Any, Optional

from contour import protocol_gen as pg
from contour.errors import UsageError
from contour.link.transport import CanBus, can_bus_config, open_transport, parse_can_spec

DEFAULT_TIMEOUT_S = 0.5


def link_options(timeout: float = DEFAULT_TIMEOUT_S) -> argparse.ArgumentParser:
    """The argparse parent with the drive-link options."""
    parent = argparse.ArgumentParser(add_help=False)
    add_link_options(parent, timeout)
    return parent


def add_link_options(parser, timeout: float = DEFAULT_TIMEOUT_S) -> None:
    """The drive-link options on an existing parser (what the parent holds)."""
    g = parser.add_argument_group(
        "drive link",
        "a serial port, or a CAN bus as python-can names it (its CAN_* environment and "
        "config file fill in what is not given)",
    )
    g.add_argument("--port", metavar="PATH", help="serial device or pyserial URL")
    g.add_argument(
        "--can",
        metavar="IFACE:CHANNEL",
        help="short form of --interface and --channel, e.g. socketcan:can0, "
        "slcan:/dev/ttyACM0 (slcan:/dev/ttyACM0@115200: python-can's serial baud)",
    )
    g.add_argument("--interface", metavar="NAME", help="python-can interface, e.g. socketcan")
    g.add_argument("--channel", metavar="NAME", help="python-can channel, e.g. can0")
    g.add_argument("--bitrate", type=int, metavar="N", help="CAN bitrate, bit/s")
    g.add_argument(
        "--node", type=int, default=1, metavar="N", help="CAN node id of the drive (default 1)"
    )
    g.add_argument(
        "--timeout",
        type=float,
        metavar="S",
        default=timeout,
        help=f"reply timeout per try, s (default {timeout:g})",
    )


@dataclass(frozen=True)
class LinkTarget:
    """Where the drive is: a serial port, or a python-can bus config and a node."""

    port: Optional[str] = None
    can: Optional[dict] = None
    node: int = 1


def can_bus_from_args(args) -> Optional[CanBus]:
    """The CAN bus named by --can / --interface / --channel / --bitrate, or
    None when none of them is given."""
    bitrate = getattr(args, "bitrate", None)
    if bitrate is not None and bitrate <= 0:
        raise UsageError(f"--bitrate {bitrate}: must be positive")
    interface = getattr(args, "interface", None)
    channel = getattr(args, "channel", None)
    if args.can:
        if interface or channel:
            raise UsageError(
                "--can IFACE:CHANNEL is the short form of --interface and --channel: "
                "give one or the other"
            )
        bus = parse_can_spec(args.can)
        return CanBus(bus.interface, bus.channel, bitrate)
    if interface or channel or bitrate is not None:
        return CanBus(interface, channel, bitrate)
    return None


def check_timeout(args) -> None:
    t = args.timeout
    if not (math.isfinite(t) and 0 < t <= 60):
        raise UsageError(f"--timeout must be in (0, 60] s, got {t:g}")


def target_from_args(args, can_only: bool = False) -> LinkTarget:
    """The drive the options name; every mistake is a UsageError."""
    if hasattr(args, "timeout"):
        check_timeout(args)
    bus = can_bus_from_args(args)
    port = getattr(args, "port", None)
    if can_only and port:
        raise UsageError("this command listens on a CAN bus: --can, --interface/--channel")
    if port and bus is not None:
        raise UsageError("choose the drive with --port PATH or a CAN bus, not both")
    if port:
        return LinkTarget(port=port, node=args.node)
    if not 1 <= args.node <= pg.CAN_NODE_MAX:
        raise UsageError(f"--node {args.node}: must be 1..{pg.CAN_NODE_MAX}")
    return LinkTarget(can=can_bus_config(bus), node=args.node)


def transport_from_args(args, **kw: Any):
    """The transport the options name (opened)."""
    target = target_from_args(args)
    return open_transport(port=target.port, can=target.can, node=target.node, **kw)


def connect_from_args(args, retries: int = 3, **kw: Any):
    """A :class:`contour.link.client.Client` on the drive the options name."""
    from contour.link.client import Client

    return Client(transport_from_args(args, **kw), args.timeout, retries)
