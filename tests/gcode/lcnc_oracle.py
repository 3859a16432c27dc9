"""Compare contour.gcode.read with LinuxCNC's own interpreter, program by program.

A development tool, not part of the test run. LinuxCNC's stand-alone interpreter
``rs274`` (Debian package ``linuxcnc-uspace``) prints the canonical moves of a
program; this script turns them into machine end point, feed length, rapid
length and dwell, and prints them next to contour's. Unpack the package
without installing it (the way the build fetches Unity)::

    bash mk/debian-fetch.sh bookworm .cache/linuxcnc linuxcnc-uspace libboost-python1.74.0

then ``.venv/bin/python tests/gcode/lcnc_oracle.py [--tool-table T] tests/gcode/programs/*.ngc``
(``LCNC_ROOT`` overrides ``.cache/linuxcnc``). Differences to keep in mind:
rs274 keeps its parameters in inches (so ``#5221 = 7`` is 7 in there and 7 mm
here), and it accepts what contour refuses (G93, NURBS ...).
"""

import contextlib
import math
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from contour import gcode

ROOT = Path(os.environ.get("LCNC_ROOT", Path(__file__).resolve().parents[2] / ".cache/linuxcnc"))
RS = str(ROOT / "usr/bin/rs274")
ENV = dict(os.environ, LD_LIBRARY_PATH=f"{ROOT}/usr/lib:{ROOT}/usr/lib/x86_64-linux-gnu")
CALL = re.compile(r"^\s*\d+ N\S* +([A-Z_0-9]+)\((.*)\)\s*$")


TOOL_TABLE = None  # --tool-table FILE: the same table for both (inch tables: ';units: inch')


def canon(path):
    with tempfile.TemporaryDirectory() as d:
        var = os.path.join(d, "rs274ngc.var")
        Path(var).write_text("5220 1.0\n")
        tbl = os.path.join(d, "tool.tbl")
        table = Path(TOOL_TABLE).read_text() if TOOL_TABLE else "T1 P1 D4 ;\nT2 P2 D10 ;\n"
        Path(tbl).write_text(table)
        r = subprocess.run(
            [RS, "-v", var, "-t", tbl, "-g", os.path.abspath(path)],
            capture_output=True,
            text=True,
            env=ENV,
            stdin=subprocess.DEVNULL,
            timeout=60,
            cwd=d,
        )
    text = r.stdout + r.stderr
    if r.returncode != 0:
        # The message and the offending line follow "executing".
        tail = text.split("executing", 1)[-1].strip().replace("\n", " | ")
        text += f"\nRS274 ERROR: {tail}\n"
    return text


def nums(args):
    out = []
    for a in args.split(","):
        with contextlib.suppress(ValueError):
            out.append(float(a))
    return out


def simulate(text):
    u = 1.0
    g5x = [0.0] * 6
    g92 = [0.0] * 6
    feed = rapid = dwell = 0.0
    plane = "XY"
    err = None

    def mach(p):
        return [p[i] * (u if i < 3 else 1) + g5x[i] + g92[i] for i in range(6)]

    cur = [0.0] * 6
    for line in text.splitlines():
        m = CALL.match(line)
        if not m:
            if (
                "error" in line.lower()
                or "Near line" in line
                or "Unable" in line
                or "not " in line.lower()
            ):
                err = (err or "") + line.strip() + " "
            continue
        name, args = m.groups()
        v = nums(args)
        if name == "USE_LENGTH_UNITS":
            u = 25.4 if "INCHES" in args else 1.0
        elif name == "SET_G5X_OFFSET":
            g5x = [x * (u if i < 3 else 1) for i, x in enumerate(v[1:7])]
        elif name == "SET_G92_OFFSET":
            g92 = [x * (u if i < 3 else 1) for i, x in enumerate(v[:6])]
        elif name == "SELECT_PLANE":
            plane = args.split("_")[-1]
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            tgt = mach(v[:6])
            d = math.dist(cur[:3], tgt[:3])
            if name == "STRAIGHT_FEED":
                feed += d
            else:
                rapid += d
            cur = tgt
        elif name == "ARC_FEED":
            fe, se, fa, sa, rot, ae = v[:6]
            a, b, c = v[6:9]
            ax = {"XY": (0, 1, 2), "XZ": (2, 0, 1), "YZ": (1, 2, 0)}[plane]
            prog = [0.0] * 6
            prog[ax[0]], prog[ax[1]], prog[ax[2]] = fe, se, ae
            prog[3:] = [a, b, c]
            tgt = mach(prog)
            cen = [0.0] * 6
            cen[ax[0]], cen[ax[1]] = fa, sa
            cen = mach(cen)
            i, j, k = ax
            r = math.hypot(cur[i] - cen[i], cur[j] - cen[j])
            a0 = math.atan2(cur[j] - cen[j], cur[i] - cen[i])
            a1 = math.atan2(tgt[j] - cen[j], tgt[i] - cen[i])
            rot = int(rot)
            sweep = (a1 - a0) % (2 * math.pi) if rot > 0 else (a0 - a1) % (2 * math.pi)
            if sweep < 1e-12:
                sweep = 2 * math.pi
            sweep += 2 * math.pi * (abs(rot) - 1)
            feed += math.hypot(r * sweep, tgt[k] - cur[k])
            cur = tgt
        elif name == "DWELL":
            dwell += v[0]
    return cur, feed, rapid, dwell, err


def ours(path):
    try:
        p = gcode.read(path, tool_table=TOOL_TABLE)
    except gcode.GcodeError as e:
        return None, str(e)
    s = gcode.segments(p, 1e-7)
    mv = p.kind[s.block] != gcode.DWELL
    end = p.end[-1] if len(p) else p.start
    return (
        list(end),
        float(s.length[mv & ~s.rapid].sum()),
        float(s.length[mv & s.rapid].sum()),
        float(p.dwell_s.sum()),
    ), None


def main(paths):
    for path in paths:
        text = canon(path)
        lc = simulate(text)
        mine, myerr = ours(path)
        name = os.path.basename(path)
        if lc[4] or myerr:
            theirs = "ERROR " + lc[4][:90] if lc[4] else "ok"
            print(f"{name:32} LinuxCNC: {theirs} | ours: {myerr or 'ok'}")
            continue
        ok = (
            np.allclose(lc[0][:6], mine[0][:6], atol=1e-4)
            and abs(lc[1] - mine[1]) < 1e-3
            and abs(lc[2] - mine[2]) < 1e-3
            and abs(lc[3] - mine[3]) < 1e-6
        )
        verdict = "SAME" if ok else "DIFF"
        print(
            f"{name:32} {verdict} end {np.round(lc[0][:3], 4)} vs {np.round(mine[0][:3], 4)}"
            f" feed {lc[1]:.4f}/{mine[1]:.4f} rapid {lc[2]:.4f}/{mine[2]:.4f}"
            f" dwell {lc[3]:g}/{mine[3]:g}"
        )


if __name__ == "__main__":
    args = sys.argv[1:]
    if args[:1] == ["--tool-table"]:
        TOOL_TABLE = args[1]
        args = args[2:]
    main(args)
