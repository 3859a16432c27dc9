"""Errors that a user or a wire can cause: printed as one clear line.

Every error the command line reports on purpose is a :class:`ContourError`;
its class says which exit code it gets (the one table is
``contour.cli.classify``; docs/conventions.md lists the codes):

- :class:`UsageError` (2): the command line itself is wrong: an unknown
  option, a missing argument, a value out of its range, options that
  exclude each other. Nothing was opened or moved.
- :class:`UserError` (1): an input the command was given cannot be used (a
  file that does not parse, a profile that does not fit, a program the drive
  refuses); like every runtime failure.
- link, drive and image errors (``contour.link.LinkError``,
  ``contour.link.DriveError``, ``contour.image.ImageError``) are UserErrors
  too, with their own ``kind`` for ``--json``.
"""


class ContourError(Exception):
    """A failure reported as one line (exit code 1 unless a subclass says)."""

    kind = "error"


class UserError(ContourError):
    """Bad input (a file, a value, a program) or a runtime failure: exit code 1."""

    kind = "input"


class FileLineError(UserError):
    """Bad input at ``file:line`` (a G-code program, a tool table, ...)."""

    def __init__(self, path: str, line: int, message: str):
        super().__init__(f"{path}:{line}: {message}")
        self.path = path
        self.line = line
        self.message = message


class UsageError(UserError):
    """The command line is wrong (option, argument, value range): exit code 2."""

    kind = "usage"


class Terminated(KeyboardInterrupt):
    """SIGTERM (or SIGHUP) while a command runs: raised from the signal
    handler so that the command's own clean-up (the same as for Ctrl-C)
    runs; exit code 128 + the signal number."""

    def __init__(self, signum: int) -> None:
        super().__init__(f"signal {signum}")
        self.signum = signum


class usage_errors:  # noqa: N801 - used as a context manager, like contextlib's
    """``with usage_errors(): ...``: a plain UserError raised inside (e.g. by a
    library parser given an option's text) is the command line's fault:
    re-raised as a UsageError. Subclasses with a kind of their own (link,
    drive, image errors) pass unchanged."""

    def __enter__(self) -> None:
        return None

    def __exit__(self, typ, exc, tb) -> bool:
        if typ is UserError:
            raise UsageError(str(exc)) from None
        return False
