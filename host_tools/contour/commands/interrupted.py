"""How a motion command reports Ctrl-C or SIGTERM: the axes were already
brought to a controlled stop; say where, in text or JSON, and give the exit
code (130, or 128 + the signal)."""

from __future__ import annotations

import json
import sys

from contour.errors import Terminated


def report(op, exc: KeyboardInterrupt, command: str, what: str, as_json: bool) -> int:
    snap = op.snapshot()
    term = isinstance(exc, Terminated)
    by = f"signal {exc.signum}" if term else "Ctrl-C"
    code = 128 + exc.signum if term else 130
    text = f"{what} by {by} at {snap.position_text()} mm (state {snap.state})"
    if as_json:
        err = {"kind": "terminated" if term else "interrupted", "message": text, "exit_code": code}
        print(json.dumps({"error": err, **snap.as_dict()}))
    else:
        print(f"contour {command}: {text}", file=sys.stderr)
    return code
