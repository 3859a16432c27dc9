"""Coordinate systems as LinuxCNC keeps them, in its numbered parameters.

Machine coordinates are what the drive moves in. A program position is
``machine - (work offset of the selected system + G92 offset)``, axis by
axis (no rotation: ``G10 L2 R`` other than 0 is refused).

Parameters (values in mm for X Y Z, degrees for A B C, the machine's units
whatever G20/G21 says, as LinuxCNC stores them in its machine units):

- 5161-5166 G28 stored position, 5181-5186 G30 stored position (machine
  coordinates; zero unless G28.1/G30.1 or an assignment sets them),
- 5210 1 while a G92 offset is applied, 5211-5216 the G92 offsets,
- 5220 the selected system (1.0 = G54 ... 9.0 = G59.3),
- 5201 + 20 n + axis: the work offsets of system n (5221-5226 G54, 5241 G55,
  ... 5381-5386 G59.3), 5230 + 20 (n - 1) its rotation,
- 5420-5428 the current position in program coordinates and program units
  (served by the interpreter's read hook, not stored).

U V W (the seventh to ninth parameter of each group) are not axes here and
stay zero.

The parameter store is any object with ``get(key, line)`` and ``set(key,
value)`` (the front end's :class:`~contour.gcode.params.Params`). Selecting
another system reads its parameters, as LinuxCNC does (``#5221 = 5`` takes
effect at the next ``G54`` after another system); selecting the active one
again does not (the interpreter does not call :meth:`Offsets.select` then).
"""

from __future__ import annotations

G28_BASE = 5161
G30_BASE = 5181
G92_FLAG = 5210
G92_BASE = 5211
SYSTEM = 5220
POSITION_BASE = 5420
SYSTEM_NAMES = ("G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")
SYSTEM_KEYS = (540, 550, 560, 570, 580, 590, 591, 592, 593)


def system_base(n: int) -> int:
    """First parameter (X) of coordinate system n (1 = G54 ... 9 = G59.3)."""
    return 5201 + 20 * n


class Offsets:
    """The active offsets (``origin``: work + G92, per axis, mm/deg) and the
    parameters behind them."""

    def __init__(self, params):
        self.params = params
        self.system = 1
        self.work = [0.0] * 6
        self.g92_offset = [0.0] * 6
        self.origin = [0.0] * 6
        self.set_in_program = set()  # systems given values by G10 in this program
        self.home_set = {28: False, 30: False}
        params.set(SYSTEM, 1.0)

    def _get(self, key: int, line: int) -> float:
        v = self.params.get(key, line)
        return 0.0 if v is None else float(v)

    def _update(self) -> None:
        self.origin = [w + g for w, g in zip(self.work, self.g92_offset)]

    def load(self, line: int) -> None:
        """Take the active offsets from the parameters (at the start)."""
        self.select(int(self._get(SYSTEM, line)) or 1, line)
        if self._get(G92_FLAG, line):
            self.g92_restore(line)

    # ---- G54 - G59.3 ----------------------------------------------------
    def select(self, n: int, line: int) -> None:
        base = system_base(n)
        self.system = n
        self.work = [self._get(base + i, line) for i in range(6)]
        self.params.set(SYSTEM, float(n))
        self._update()

    # ---- G10 L2 / L20 -----------------------------------------------------
    def set_system(self, n: int, values: dict, line: int) -> None:
        """G10 L2 P<n>: the origin of system n is at ``values`` (machine
        coordinates, mm/deg, by axis index)."""
        n = n or self.system
        base = system_base(n)
        for i, v in values.items():
            self.params.set(base + i, v)
        self.set_in_program.add(n)
        if n == self.system:
            self.select(n, line)

    def set_system_here(self, n: int, values: dict, machine_pos, line: int) -> None:
        """G10 L20 P<n>: system n such that the current point has the
        program coordinates ``values`` (mm/deg) once it is selected."""
        self.set_system(
            n, {i: machine_pos[i] - self.g92_offset[i] - v for i, v in values.items()}, line
        )

    # ---- G92 family --------------------------------------------------------
    def g92(self, values: dict, machine_pos, line: int) -> None:
        """G92: the current point gets the program coordinates ``values``."""
        for i, v in values.items():
            self.g92_offset[i] = machine_pos[i] - self.work[i] - v
        for i in range(6):
            self.params.set(G92_BASE + i, self.g92_offset[i])
        self.params.set(G92_FLAG, 1.0)
        self._update()

    def g92_1(self) -> None:
        """G92.1: offsets off and the parameters zeroed."""
        self.g92_offset = [0.0] * 6
        for i in range(6):
            self.params.set(G92_BASE + i, 0.0)
        self.params.set(G92_FLAG, 0.0)
        self._update()

    def g92_2(self) -> None:
        """G92.2: offsets off, the parameters kept."""
        self.g92_offset = [0.0] * 6
        self.params.set(G92_FLAG, 0.0)
        self._update()

    def g92_restore(self, line: int) -> None:
        """G92.3: offsets from the parameters."""
        self.g92_offset = [self._get(G92_BASE + i, line) for i in range(6)]
        self.params.set(G92_FLAG, 1.0)
        self._update()

    # ---- G28 / G30 ----------------------------------------------------------
    def store_home(self, which: int, machine_pos) -> None:
        base = G28_BASE if which == 28 else G30_BASE
        for i in range(6):
            self.params.set(base + i, float(machine_pos[i]))
        self.home_set[which] = True

    def home(self, which: int, line: int) -> list:
        base = G28_BASE if which == 28 else G30_BASE
        return [self._get(base + i, line) for i in range(6)]
