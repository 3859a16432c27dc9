"""`contour config backup|restore|save`: the drive's parameters as a file and in flash.

backup FILE.toml
    Every writable parameter (per axis for the drive's axes) in user units
    (``"25 mm/s"``, ``"curvature"``; contour/params.py), under a ``[drive]``
    header naming board, firmware version, build id, protocol version and axes.
restore FILE.toml
    Checks the whole file first: a ``[drive]`` table with the drive's axis
    count, only known writable parameters, every per-axis parameter with one
    value per axis of the drive, every value in its range, the drive not
    moving, a disabled-only parameter (encoder_mean) changed only on a
    disabled drive. Nothing is written unless all of that holds. Then sends
    the whole file as one parameter transaction (param_begin, param_stage,
    param_commit): the drive checks the values together (max_acceleration
    against the file's max_jerk) and its state, and applies all of them or
    none; then every value is read back. A second session that starts
    motion, enables the drive or opens a session before the commit gets the
    restore refused with nothing written and the reason (the first refused
    parameter, or the lost transaction). A commit whose reply is lost on
    every try is asked again (same transaction) until the drive answers
    applied or not; a link that stays dead ends in an error saying that the
    outcome is unknown and how to check. A drive without transactions is
    refused, nothing written. Another board id only warns.
save
    Stores the drive parameters in the drive's flash (message param_save); the
    drive loads them at start-up and reports what it did in the read-only
    parameter param_store_status. Only while the drive is disabled.
"""

from __future__ import annotations

import contextlib
import datetime
import json
import sys
import time

import tomllib

from contour import params as up
from contour import protocol_gen as pg
from contour.commands.param import param_names
from contour.errors import UserError
from contour.image import build_id_prefix
from contour.link.client import DriveError, parse_param
from contour.link.options import connect_from_args, link_options
from contour.link.transport import LinkError

AXES = "xyza"
HEADER = """\
# contour drive configuration (contour config backup). Values in user units:
# a number with its unit ("25 mm/s"; another unit of the same kind is taken,
# "1500 mm/min"), enums by name. Write it back with: contour config restore FILE
"""


def _version(v: int) -> str:
    return f"{v >> 16}.{(v >> 8) & 0xFF}.{v & 0xFF}"


def _q(s: str) -> str:
    return json.dumps(s, ensure_ascii=False)  # a TOML basic string


def _toml_value(p: pg.Param, raw: int) -> str:
    return _q(up.format_value(p, raw))


def backup_text(ident: dict, values: dict[str, int]) -> str:
    """The backup file for `values` (name or name.axis -> raw)."""
    axes = ident["axes"]
    lines = [
        HEADER,
        "[drive]",
        f"board_id = {ident['board_id']}",
        f"firmware_version = {_q(_version(ident['fw_version']))}",
        f"build_id = {_q(build_id_prefix(ident['build_id']))}",
        f"protocol_version = {ident['protocol_version']}",
        f"axes = {axes}",
        "saved = "
        + _q(datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")),
        "",
        "[params]",
    ]
    for p in pg.PARAMS:
        if p.access != "rw":
            continue
        if p.per_axis:
            cells = ", ".join(
                f"{AXES[i]} = {_toml_value(p, values[f'{p.name}.{AXES[i]}'])}" for i in range(axes)
            )
            lines.append(f"{p.name} = {{ {cells} }}")
        else:
            lines.append(f"{p.name} = {_toml_value(p, values[p.name])}")
    return "\n".join(lines) + "\n"


def read_all(client, axes: int) -> dict[str, int]:
    return {n: client.get_param(n) for n in param_names(axes, writable_only=True)}


def parse_backup(text: str, axes: int, source: str = "file") -> tuple[dict, dict[str, int]]:
    """Check a whole backup against a drive with `axes` axes: ([drive] table,
    name -> raw value). Every problem is collected; UserError lists them."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise UserError(f"{source}: not TOML: {exc}") from None
    problems = []
    drive = doc.get("drive")
    if not isinstance(drive, dict):
        problems.append("no [drive] table")
        drive = {}
    elif drive.get("axes") != axes:
        problems.append(f"written for {drive.get('axes')} axes, the drive has {axes}")
    table = doc.get("params")
    if not isinstance(table, dict):
        problems.append("no [params] table")
        table = {}
    unknown = sorted(set(doc) - {"drive", "params"})
    if unknown:
        problems.append(f"unknown tables: {', '.join(unknown)}")
    out: dict[str, int] = {}
    for name, v in table.items():
        p = pg.PARAM_BY_NAME.get(name)
        if p is None:
            problems.append(f"{name}: unknown parameter")
            continue
        if p.access != "rw":
            problems.append(f"{name}: read-only")
            continue
        if p.per_axis:
            want = set(AXES[:axes])
            if not isinstance(v, dict) or set(v) != want:
                got = ", ".join(sorted(v)) if isinstance(v, dict) else repr(v)
                problems.append(
                    f"{name}: needs one value per axis ({', '.join(AXES[:axes])}), got {got}"
                )
                continue
            items = [(f"{name}.{a}", v[a]) for a in AXES[:axes]]
        else:
            items = [(name, v)]
        for full, val in items:
            if isinstance(val, bool) or not isinstance(val, (str, int, float)):
                problems.append(f"{full}: {val!r} is not a value")
                continue
            try:
                out[full] = up.parse_value(p, str(val))
            except UserError as exc:
                problems.append(str(exc))
    if problems:
        raise UserError(
            f"{source}: nothing written, {len(problems)} problem(s):\n  " + "\n  ".join(problems)
        )
    return drive, out


# Parameters the drive refuses to change unless it is disabled (drive.h).
DISABLED_ONLY = ("encoder_mean",)
# (u16 id, i64 value) pairs per param_stage frame (its data field: 240 bytes)
STAGE_PAIRS = pg.MSG_BY_NAME["param_stage"].fields[-1].max // 10


def write_all(client, values: dict[str, int]) -> None:
    """Write `values` as one parameter transaction (param_begin, param_stage,
    param_commit): the drive checks them together with its state at the
    commit and applies all of them or none; then read every value back.

    A second session that starts motion or enables the drive before the
    commit gets the commit refused (naming the first parameter it refuses);
    one that opens a session or begins a transaction of its own loses this
    one. Either way nothing is written, and the error says why. A commit
    not answered on any try is settled by asking again (_commit). A drive
    without transactions (param_begin unknown) is refused before anything
    is written: one value at a time could leave it half restored."""
    try:
        txn = client.request("param_begin").fields["txn"]
    except DriveError as exc:
        if exc.code == pg.ErrorCode.UNKNOWN_MESSAGE:
            raise UserError(
                "restore refused, nothing written: the drive's firmware has no parameter "
                "transactions (param_begin unknown), and writing one value at a time could "
                "leave it half restored; update its firmware (contour flash), or set values "
                "one by one with contour set"
            ) from None
        raise
    pairs = [(parse_param(n)[1], raw) for n, raw in values.items()]
    try:
        for i in range(0, len(pairs), STAGE_PAIRS):
            data = b"".join(
                pid.to_bytes(2, "little") + int(raw).to_bytes(8, "little", signed=True)
                for pid, raw in pairs[i : i + STAGE_PAIRS]
            )
            client.request("param_stage", txn=txn, data=data)
        done = _commit(client, txn, values)
    except DriveError as exc:
        _abort(client, txn)
        why = ""
        if exc.code == pg.ErrorCode.BUSY:
            why = " (another session enabled or moved the drive since the restore's check?)"
        raise UserError(f"restore refused, nothing written: {exc}{why}") from None
    if not done["committed"] or done["staged"] != len(values):
        raise UserError(
            f"restore: the drive committed {done['staged']} of {len(values)} values "
            f"(committed = {done['committed']})"
        )
    wrong = []
    for name, raw in values.items():
        back = client.get_param(name)
        if back != raw:
            p = parse_param(name)[0]
            wrong.append(
                f"{name} reads {up.format_value(p, back)}, wrote {up.format_value(p, raw)}"
            )
    if wrong:
        raise UserError("restore verify failed: " + "; ".join(wrong))


# A commit none of whose tries was answered is asked again, as a new request
# of the same transaction, this many times (each with the client's own tries),
# a pause before each: a link that comes back within about
# ROUNDS * (PAUSE + (1 + retries) * timeout) settles the outcome.
COMMIT_ASK_ROUNDS = 4
COMMIT_ASK_PAUSE_S = 0.5


def _commit(client, txn: int, values: dict[str, int]) -> dict:
    """param_commit of `txn`; when no try of it was answered, ask again until
    the drive answers: committed (now, or before: a commit of the drive's
    last committed id answers committed and applies nothing twice) or an
    error (the transaction lost or refused: nothing applied, DriveError). An
    id the drive no longer knows (not_open: another session's transaction
    came since) is settled by reading the values back. A link that stays
    dead raises a UserError saying that the outcome is unknown."""
    try:
        return client.request("param_commit", txn=txn).fields
    except LinkError as exc:
        lost: LinkError = exc
    for _ in range(COMMIT_ASK_ROUNDS):
        time.sleep(COMMIT_ASK_PAUSE_S)
        try:
            return client.request("param_commit", txn=txn).fields
        except LinkError as exc:
            lost = exc
        except DriveError as exc:
            if exc.code != pg.ErrorCode.TXN or exc.fields["arg"] != pg.TxnStatus.NOT_OPEN:
                raise
            return _settle_by_reading(client, txn, values)
    raise UserError(
        f"restore outcome unknown: the drive did not answer the commit of transaction {txn} "
        f"({lost}), so it may or may not have applied the file (all of it or none). "
        "Check when the link is back: contour config backup OTHER.toml and compare it with "
        "the file, or run the restore again (restoring the same file twice is harmless)"
    ) from None


def _settle_by_reading(client, txn: int, values: dict[str, int]) -> dict:
    """The drive no longer knows `txn` (committed or lost, and another
    session's transaction since): the drive holds the file or it does not."""
    differ = [name for name, raw in values.items() if client.get_param(name) != raw]
    if differ:
        raise UserError(
            f"restore not completed: the commit of transaction {txn} was not answered and "
            "the drive no longer knows it (another session's transaction came since); "
            f"{len(differ)} value(s) differ from the file ({', '.join(differ[:4])}"
            f"{', ...' if len(differ) > 4 else ''}): run the restore again"
        )
    return {"txn": txn, "staged": len(values), "committed": 1}


def _abort(client, txn: int) -> None:
    """Drop a refused transaction (a lost one is gone already)."""
    with contextlib.suppress(DriveError):
        client.request("param_abort", txn=txn)


def run_backup(args) -> int:
    with connect_from_args(args) as client:
        ident = client.identify()
        values = read_all(client, ident["axes"])
    text = backup_text(ident, values)
    if args.file == "-":
        sys.stdout.write(text)
        return 0
    try:
        with open(args.file, "w", encoding="utf-8") as f:
            f.write(text)
    except OSError as exc:
        raise UserError(f"{args.file}: {exc.strerror}") from None
    if args.json:
        print(json.dumps({"file": args.file, "values": len(values), "axes": ident["axes"]}))
    else:
        print(f"{len(values)} values of {ident['axes']} axes written to {args.file}")
    return 0


def run_restore(args) -> int:
    try:
        with open(args.file, encoding="utf-8") as f:
            text = f.read()
    except OSError as exc:
        raise UserError(f"{args.file}: {exc.strerror}") from None
    with connect_from_args(args) as client:
        ident = client.identify()
        drive, values = parse_backup(text, ident["axes"], args.file)
        if drive.get("board_id") not in (None, ident["board_id"]):
            print(
                f"warning: {args.file} is from board {drive['board_id']}, "
                f"the drive is board {ident['board_id']}",
                file=sys.stderr,
            )
        st = client.status()
        if st["state"] in (pg.State.RUNNING, pg.State.STOPPING, pg.State.HOMING):
            raise UserError(
                f"the drive is moving ({pg.State(st['state']).name.lower()}): nothing written "
                "(wait or stop it first)"
            )
        # The drive changes these only while disabled (busy otherwise): check
        # before the first write, so that a restore is never half-applied.
        for name in DISABLED_ONLY:
            if (
                name in values
                and st["state"] != pg.State.DISABLED
                and client.get_param(name) != values[name]
            ):
                raise UserError(
                    f"{name} changes only while the drive is disabled: nothing written "
                    "(contour disable first)"
                )
        if not args.dry_run:
            write_all(client, values)
    if args.json:
        print(json.dumps({"file": args.file, "values": len(values), "written": not args.dry_run}))
    elif args.dry_run:
        print(f"{args.file}: {len(values)} values check out; nothing written (--dry-run)")
    else:
        print(f"{len(values)} values restored from {args.file} and read back")
    return 0


def run_save(args) -> int:
    with connect_from_args(args) as client:
        try:
            client.request("param_save")
        except DriveError as exc:
            if exc.code == pg.ErrorCode.BAD_STATE:
                raise UserError(
                    "the drive saves its parameters only while disabled: contour disable first"
                ) from None
            raise
    if args.json:
        print(json.dumps({"saved": True}))
    else:
        print("drive parameters saved to the drive's flash (loaded at its next start)")
    return 0


def register(sub) -> None:
    c = sub.add_parser(
        "config",
        help="drive parameters: backup to / restore from a TOML file, save to flash",
        description=__doc__.split("\n\n", 1)[1] if __doc__ else None,
    )
    cs = c.add_subparsers(dest="config_cmd", metavar="{backup,restore,save}", required=True)
    b = cs.add_parser(
        "backup",
        help="write every writable parameter to FILE.toml (- : stdout)",
        parents=[link_options()],
    )
    b.add_argument("file", metavar="FILE.toml")
    b.add_argument("--json", action="store_true", help="print the result as JSON")
    b.set_defaults(func=run_backup)
    r = cs.add_parser(
        "restore",
        help="check FILE.toml completely, then write it and read it back",
        parents=[link_options()],
    )
    r.add_argument("file", metavar="FILE.toml")
    r.add_argument("--dry-run", action="store_true", help="check only, write nothing")
    r.add_argument("--json", action="store_true", help="print the result as JSON")
    r.set_defaults(func=run_restore)
    s = cs.add_parser(
        "save",
        help="store the drive parameters in its flash (drive disabled)",
        parents=[link_options()],
    )
    s.add_argument("--json", action="store_true", help="print JSON")
    s.set_defaults(func=run_save)
