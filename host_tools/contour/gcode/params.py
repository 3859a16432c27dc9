"""G-code parameters as RS-274/NGC (LinuxCNC) defines them.

- Numbered ``#1`` .. ``#5602``: read 0 until set. ``#1``-``#30`` are local to
  a subroutine call (saved on call, restored on return); the others are
  global. The interpreter stores its persistent state in some of them
  (offsets 5221-5390, G28/G30 positions 5161-5169/5181-5189 ...).
- Named ``#<name>``: case and spaces are folded (keys are lower-case,
  without spaces). A name starting with ``_`` is global; others are local to
  the subroutine (or main program) that set them. Reading a named parameter
  that was never set is an error.
- Predefined read-only names (``#<_x>``, ``#<_metric>`` ...) come from the
  interpreter through :attr:`Params.system`, a callable ``system(name) ->
  float | None`` (None: not a predefined name).
- Sinumerik ``R`` parameters (``R1=5``) live in :attr:`Params.r`, apart from
  RS-274/NGC parameters.

Errors are raised through the reporter installed in :attr:`Params.rep`
(``rep.error(line, message)``), so they name ``file:line``.
"""

from __future__ import annotations

import math
from typing import Callable, Optional

NUMBERED_MAX = 5602
LOCAL_MAX = 30


class Params:
    """Parameter store of one read (one program)."""

    def __init__(self, system: Optional[Callable[[str], Optional[float]]] = None):
        self.numbered: dict[int, float] = {}
        # Return value of the last O-word call (LinuxCNC: 0 at program start).
        self.globals: dict[str, float] = {"_value": 0.0, "_value_returned": 0.0}
        # Named locals of the main program and of each active call.
        self.locals: list[dict[str, float]] = [{}]
        self.system = system
        self.rep = None  # installed by lexer.blocks()
        self.r: dict[int, float] = {}

    # ---- errors -------------------------------------------------------------
    def _error(self, line: int, message: str):
        if self.rep is not None:
            return self.rep.error(line, message)
        from contour.gcode import GcodeError  # late: the package imports us

        return GcodeError("<gcode>", line, message)

    # ---- keys ---------------------------------------------------------------
    def index(self, value: float, line: int) -> int:
        """Numbered parameter index from an evaluated value (LinuxCNC takes a
        value within 1e-4 of an integer)."""
        if not math.isfinite(value):
            raise self._error(line, "parameter number is not a finite number")
        k = int(round(value))
        if abs(value - k) > 1e-4:
            raise self._error(line, f"parameter number #{value:g} is not an integer")
        if k < 1 or k > NUMBERED_MAX:
            raise self._error(line, f"parameter number #{k} out of range 1..{NUMBERED_MAX}")
        return k

    # ---- access -------------------------------------------------------------
    def get(self, key, line: int) -> float:
        """Value of ``key`` (int: numbered, str: lower-case name)."""
        if type(key) is int:
            if key < 1 or key > NUMBERED_MAX:
                raise self._error(line, f"parameter number #{key} out of range 1..{NUMBERED_MAX}")
            return self.numbered.get(key, 0.0)
        if key[:1] == "_":
            if self.system is not None:
                v = self.system(key)
                if v is not None:
                    return float(v)
            v = self.globals.get(key)
        else:
            v = self.locals[-1].get(key)
        if v is None:
            raise self._error(line, f"named parameter #<{key}> read before it is set")
        return v

    def exists(self, key: str) -> bool:
        if key[:1] == "_":
            if self.system is not None and self.system(key) is not None:
                return True
            return key in self.globals
        return key in self.locals[-1]

    def set(self, key, value: float, line: int = 0) -> None:
        """Set ``key`` (int: numbered, str: lower-case name) to ``value``."""
        value = float(value)
        if not math.isfinite(value):
            raise self._error(line, f"parameter {_show(key)} set to a non-finite value")
        if type(key) is int:
            if key < 1 or key > NUMBERED_MAX:
                raise self._error(line, f"parameter number #{key} out of range 1..{NUMBERED_MAX}")
            self.numbered[key] = value
        elif key[:1] == "_":
            if self.system is not None and self.system(key) is not None:
                raise self._error(line, f"#<{key}> is a read-only predefined parameter")
            self.globals[key] = value
        else:
            self.locals[-1][key] = value

    # ---- calls ----------------------------------------------------------------
    def enter(self, args: list) -> tuple:
        """Start a subroutine call with ``args`` in #1..; returns what
        :meth:`leave` needs. Locals beyond the arguments keep the caller's
        values (LinuxCNC)."""
        saved = tuple(self.numbered.get(i, 0.0) for i in range(1, LOCAL_MAX + 1))
        for i, v in enumerate(args, 1):
            self.numbered[i] = v
        self.locals.append({})
        return saved

    def leave(self, saved: tuple) -> None:
        for i, v in enumerate(saved, 1):
            self.numbered[i] = v
        self.locals.pop()


def _show(key) -> str:
    return f"#{key}" if type(key) is int else f"#<{key}>"
