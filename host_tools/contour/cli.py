"""The `contour` command line: one program, one sub-command per module.

Every module in `contour.commands` that defines ``register(subparsers)`` adds
its sub-command(s); ``register`` must set ``func`` (a callable taking the parsed
arguments and returning an exit code) with ``set_defaults``.

Exit codes (docs/conventions.md), decided here and nowhere else
(:func:`classify`): 0 success, 1 runtime failure (link, drive, fault,
refused program, unreadable or unwritable file), 2 usage error (argparse's
own and :class:`contour.errors.UsageError`), 130 interrupted (Ctrl-C), 128 +
N for signal N (SIGTERM: 143). Errors are one line ``contour: error: ...`` on
stderr, never a traceback; with ``--json`` on the command line they are one
JSON object on stdout instead: ``{"error": {"kind": ..., "message": ...,
"exit_code": ...}}``.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import os
import pkgutil
import signal
import sys
import threading

from contour import __version__, commands
from contour.errors import ContourError, Terminated, UsageError

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


def _exit_table() -> list:
    """(exception class, exit code, kind), most specific first."""
    from contour.image import ImageError
    from contour.link.client import DriveError
    from contour.link.codec import ProtocolError
    from contour.link.transport import LinkError

    return [
        (UsageError, EXIT_USAGE, "usage"),
        (LinkError, EXIT_FAILURE, "link"),
        (DriveError, EXIT_FAILURE, "drive"),
        (ProtocolError, EXIT_FAILURE, "protocol"),
        (ImageError, EXIT_FAILURE, "image"),
        (ContourError, EXIT_FAILURE, None),  # the class's own kind
        (OSError, EXIT_FAILURE, "file"),
    ]


def classify(exc: BaseException) -> tuple[int, str]:
    """(exit code, kind) of an exception that ends a command; the one table."""
    if isinstance(exc, Terminated):
        return 128 + exc.signum, "terminated"
    if isinstance(exc, KeyboardInterrupt):
        return EXIT_INTERRUPTED, "interrupted"
    for cls, code, kind in _exit_table():
        if isinstance(exc, cls):
            return code, kind or getattr(exc, "kind", "error")
    raise exc


def _message(exc: BaseException) -> str:
    if isinstance(exc, OSError) and not isinstance(exc, ContourError):
        where = exc.filename if exc.filename is not None else ""
        text = exc.strerror or str(exc)
        return f"{where}: {text}" if where else text
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted" if not isinstance(exc, Terminated) else f"terminated ({exc})"
    return str(exc)


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are UsageErrors (sub-parsers inherit it)."""

    def error(self, message: str):
        raise UsageError(f"{message} (see `{self.prog} --help`)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="contour",
        description="Deploy, calibrate, feed and simulate the contour CNC axis drive.",
        epilog="Exit codes: 0 success, 1 failure, 2 usage error, 130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"contour {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"contour.commands.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(sub)
    return parser


def wants_json(argv: list[str]) -> bool:
    """``--json`` among the options (before a ``--``)."""
    for a in argv:
        if a == "--":
            return False
        if a == "--json":
            return True
    return False


def report_error(exc: BaseException, as_json: bool) -> int:
    code, kind = classify(exc)
    msg = _message(exc)
    if as_json:
        err = {"kind": kind, "message": msg, "exit_code": code}
        print(json.dumps({"error": err}), flush=True)
    else:
        print(
            f"contour: error: {msg}" if code != EXIT_INTERRUPTED else f"contour: {msg}",
            file=sys.stderr,
            flush=True,
        )
    return code


def _raise_terminated(signum, frame) -> None:
    raise Terminated(signum)


@contextlib.contextmanager
def _terminate_as_interrupt():
    """SIGTERM/SIGHUP raise Terminated (a KeyboardInterrupt) in the main
    thread while a command runs, so its clean-up runs as for Ctrl-C."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    for s in (signal.SIGTERM, signal.SIGHUP):
        old[s] = signal.signal(s, _raise_terminated)
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    as_json = wants_json(argv)
    try:
        with _terminate_as_interrupt():
            parser = build_parser()
            args = parser.parse_args(argv)
            if not getattr(args, "func", None):
                parser.print_help(sys.stderr)
                return EXIT_USAGE
            return int(args.func(args) or 0)
    except BrokenPipeError:
        # the reader of stdout went away (`contour info | head -1`): nothing
        # left to tell it; no error line, no traceback at exit
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_FAILURE
    except (ContourError, OSError, KeyboardInterrupt) as exc:
        return report_error(exc, as_json)


if __name__ == "__main__":
    raise SystemExit(main())
