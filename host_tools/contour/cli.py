"""The `contour` command line: one program, one sub-command per module.

Every module in `contour.commands` that defines ``register(subparsers)`` adds
its sub-command(s); ``register`` must set ``func`` (a callable taking the parsed
arguments and returning an exit code) with ``set_defaults``. Errors a user can
cause raise :class:`contour.errors.UserError`; they are printed as one line
``contour: error: ...`` with exit code 2, never as a traceback; so are
command-line mistakes (unknown option, missing argument, a value that is not
a number), which argparse would otherwise print as a usage block.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from contour import __version__, commands
from contour.errors import UserError


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are UserErrors (sub-parsers inherit it)."""

    def error(self, message: str):
        raise UserError(f"{message} (see `{self.prog} --help`)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="contour",
        description="Deploy, calibrate, feed and simulate the contour CNC axis drive.",
    )
    parser.add_argument("--version", action="version", version=f"contour {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"contour.commands.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"contour: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("contour: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
