"""LinuxCNC's own interpreter as an oracle for the test programs.

``rs274``, the stand-alone RS-274/NGC interpreter of LinuxCNC, prints the
canonical moves of a program. It comes in Debian's ``linuxcnc-uspace``
package, which is unpacked (never installed) into ``.cache/linuxcnc`` by
``mk/debian-fetch.sh``, as the build does for Unity::

    .venv/bin/python tests/gcode/linuxcnc_oracle.py --fetch tests/gcode/programs/*.ngc

prints, for every program, LinuxCNC's end point, feed and rapid lengths
(arcs measured exactly), dwell, or its error, next to the ``; expect``
lines. ``tests/python/test_gcode_linuxcnc_oracle.py`` runs the cycle and
cutter-compensation programs through it when the package has been fetched
(and is skipped otherwise). Tool tables: ``-t`` gets a table with T1 (6 mm)
and T2 (20 mm) unless the program's directory has ``tool.tbl``.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

TOP = Path(__file__).resolve().parents[2]
ROOT = Path(os.environ.get("CONTOUR_CACHE", TOP / ".cache")) / "linuxcnc"
RS274 = ROOT / "usr" / "bin" / "rs274"
PACKAGES = ("linuxcnc-uspace", "libboost-python1.74.0")
SUITE = "bookworm"

_CALL = re.compile(r"N\.\.\.\.\. (\w+)\((.*)\)")
_EXPECT = re.compile(r";\s*expect\s+(\w+):\s*(.*)")


@dataclass
class Result:
    moves: list = field(default_factory=list)  # (name, end xyz, centre or None)
    end: tuple = (0.0, 0.0, 0.0)
    feed_mm: float = 0.0
    rapid_mm: float = 0.0
    dwell_s: float = 0.0
    error: str = ""


def available() -> bool:
    return RS274.exists()


def fetch() -> None:
    subprocess.run(
        [str(TOP / "mk" / "debian-fetch.sh"), SUITE, str(ROOT), *PACKAGES],
        check=True,
        stdout=subprocess.DEVNULL,
    )


def run(path, tool_table=None) -> Result:
    """Run one program through rs274 and sum its canonical moves."""
    with tempfile.TemporaryDirectory() as home:
        table = tool_table
        if table is None:
            local = Path(path).parent / "tool.tbl"
            table = local if local.exists() else Path(home) / "tool.tbl"
            if not local.exists():
                table.write_text("T1 P1 D6 Z0 ;6 mm\nT2 P2 D20 Z0 ;20 mm\n")
        libs = [ROOT / "usr" / "lib", ROOT / "usr" / "lib" / "x86_64-linux-gnu"]
        env = dict(os.environ, HOME=home, LD_LIBRARY_PATH=":".join(str(p) for p in libs))
        p = subprocess.run(
            [str(RS274), "-g", "-t", str(table), str(path)],
            capture_output=True,
            text=True,
            env=env,
            stdin=subprocess.DEVNULL,
            timeout=60,
        )
    return parse(p.stdout + p.stderr)


def parse(text: str) -> Result:
    res = Result()
    pos = [0.0] * 6
    axes = (0, 1, 2)  # the plane's first, second and normal axis
    errors = []
    for line in text.splitlines():
        m = _CALL.search(line)
        if not m:
            if line.strip() and line.strip() != "executing":
                errors.append(line.strip())
            continue
        name, args = m.groups()
        if name == "SELECT_PLANE":
            axes = {"XY": (0, 1, 2), "XZ": (2, 0, 1), "YZ": (1, 2, 0)}[args.split("_")[-1]]
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            v = [float(x) for x in args.split(",")][:6]
            d = math.dist(pos[:3], v[:3])
            if name == "STRAIGHT_TRAVERSE":
                res.rapid_mm += d
            else:
                res.feed_mm += d
            res.moves.append((name[9:], tuple(v[:3]), None))
            pos = v
        elif name == "ARC_FEED":
            v = [float(x) for x in args.split(",")]
            e1, e2, c1, c2, rot, e3 = v[:6]
            u, w, n = axes
            a0 = math.atan2(pos[w] - c2, pos[u] - c1)
            a1 = math.atan2(e2 - c2, e1 - c1)
            sweep = ((a1 - a0) if rot > 0 else (a0 - a1)) % (2 * math.pi)
            if sweep < 1e-12:
                sweep = 2 * math.pi
            sweep += 2 * math.pi * (abs(int(rot)) - 1)
            r = math.hypot(pos[u] - c1, pos[w] - c2)
            res.feed_mm += math.hypot(sweep * r, e3 - pos[n])
            new = list(pos)
            new[u], new[w], new[n] = e1, e2, e3
            new[3:6] = v[6:9]
            res.moves.append(("ARC_CCW" if rot > 0 else "ARC_CW", tuple(new[:3]), (c1, c2)))
            pos = new
        elif name == "DWELL":
            res.dwell_s += float(args)
    res.end = tuple(pos[:3])
    res.error = errors[0] if errors else ""
    return res


def expectations(path) -> dict:
    exp = {}
    for line in Path(path).read_text().splitlines():
        m = _EXPECT.match(line)
        if m:
            exp[m.group(1)] = m.group(2).strip()
    return exp


def agrees(path, res: Result, tol=1e-3) -> bool:
    """The program's expectations hold for LinuxCNC's result (a refusal
    must be refused, whatever LinuxCNC's wording)."""
    exp = expectations(path)
    if "refused" in exp:
        return bool(res.error)
    if res.error:
        return False
    ok = True
    for axis, value in re.findall(r"([XYZ])(-?[\d.]+)", exp.get("end", "")):
        ok &= abs(res.end["XYZ".index(axis)] - float(value)) <= tol
    for key, got in (
        ("feed_mm", res.feed_mm),
        ("rapid_mm", res.rapid_mm),
        ("dwell_s", res.dwell_s),
    ):
        if key in exp:
            ok &= abs(got - float(exp[key])) <= tol
    return ok


def main(argv) -> int:
    if argv and argv[0] == "--fetch":
        argv = argv[1:]
        if not available():
            fetch()
    if not available():
        print("rs274 not fetched: run with --fetch first", file=sys.stderr)
        return 2
    bad = 0
    for path in argv:
        res = run(path)
        ok = agrees(path, res)
        bad += not ok
        x, y, z = res.end
        what = (
            f"refused: {res.error}"
            if res.error
            else f"end X{x:.4f} Y{y:.4f} Z{z:.4f} feed {res.feed_mm:.6f} "
            f"rapid {res.rapid_mm:.6f} dwell {res.dwell_s:g}"
        )
        print(f"{'ok ' if ok else 'BAD'} {Path(path).name}: {what}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
