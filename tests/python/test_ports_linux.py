"""The Linux board port (firmware/ports/linux) through the link-time libgpiod
fake (tests/ports/gpiod_fake.c): scripted encoder edges in, enable lines out,
the protocol on a pseudo-terminal. The port is compiled against the real
libgpiod v2 headers (Debian bookworm-backports, fetched into .cache/gpiod);
build/fw/linux/contour-drive is also linked against the real library.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FW = ROOT / "build" / "fw" / "linux"
LINES = 8  # offsets per axis: A, B, EN, DIR, FAULT
NM_PER_COUNT = 1250


@pytest.fixture(scope="module")
def drive_bin() -> Path:
    r = subprocess.run(
        [str(ROOT / "mk" / "firmware.sh"), "linux"],
        capture_output=True, text=True, timeout=600, cwd=ROOT,
    )  # fmt: skip
    assert r.returncode == 0, r.stdout + r.stderr
    return FW / "contour-drive-fake"


def quadrature(axis: int, counts: int, t0_us: int, dt_us: int = 10) -> list[str]:
    """Edge lines moving `axis` by `counts` (x4) from A = B = 0."""
    a, b = axis * LINES, axis * LINES + 1
    fwd = [(a, 1), (b, 1), (a, 0), (b, 0)]
    rev = [(b, 1), (a, 1), (b, 0), (a, 0)]
    seq = fwd if counts >= 0 else rev
    return [f"edge {t0_us + k * dt_us} {seq[k % 4][0]} {seq[k % 4][1]}" for k in range(abs(counts))]


def write_script(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(sorted(lines, key=lambda s: int(s.split()[1]))) + "\n")
    return path


def outputs(path: Path) -> dict[int, int]:
    """Last value driven on each output line."""
    last: dict[int, int] = {}
    for line in path.read_text().splitlines():
        _, off, val = line.split()
        last[int(off)] = int(val)
    return last


def test_edges_decoded_exactly(drive_bin: Path, tmp_path: Path) -> None:
    edges = quadrature(0, 4001, 50_000) + quadrature(1, -1203, 60_000, 7)
    # a repeated level on axis 2 (glitch without change) must count nothing
    edges += ["edge 70000 16 1", "edge 70010 16 1", "edge 70020 16 0"]
    script = write_script(tmp_path / "s.txt", edges)
    env = dict(os.environ, GPIOD_FAKE_SCRIPT=str(script), GPIOD_FAKE_OUT=str(tmp_path / "o.txt"))
    r = subprocess.run(
        [str(drive_bin), "--serial", "pty", "--gpiochip", "fake", "--tick-hz", "1000",
         "--ticks", "300"],
        capture_output=True, text=True, timeout=60, env=env,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    last = r.stdout.strip().splitlines()[-1].split()
    assert last[last.index("edges") + 1] == str(4001 + 1203 + 3)
    pos = [int(x) for x in last[last.index("pos") + 1 :]]
    assert pos == [4001, -1203, 0], r.stdout


def test_bad_arguments_are_refused(drive_bin: Path) -> None:
    for args, text in (
        (["--serial", "pty", "--axes", "9"], "bad option or value"),
        (["--gpiochip", "fake"], "give --serial and/or --can"),
        (["--serial", "pty", "--tick-hz"], "missing value"),
        (["--serial", "/nonexistent/tty"], "cannot open /nonexistent/tty"),
    ):
        r = subprocess.run([str(drive_bin), *args], capture_output=True, text=True, timeout=10)
        assert r.returncode in (1, 2) and text in r.stderr, (args, r.stderr)


class Drive:
    def __init__(self, binary: Path, tmp: Path, script_lines: list[str]) -> None:
        self.out = tmp / "outputs.txt"
        script = write_script(tmp / "script.txt", script_lines)
        env = dict(os.environ, GPIOD_FAKE_SCRIPT=str(script), GPIOD_FAKE_OUT=str(self.out))
        self.proc = subprocess.Popen(
            [str(binary), "--serial", "pty", "--gpiochip", "fake", "--tick-hz", "1000"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        )  # fmt: skip
        line = self.proc.stdout.readline()
        assert line.startswith("serial: "), line + self.proc.stderr.read()
        self.port = line.split(": ", 1)[1].strip()
        assert self.proc.stdout.readline().strip() == "ready"

    def contour(self, *args: str) -> dict:
        r = subprocess.run(
            [sys.executable, "-m", "contour", *args, "--port", self.port, "--json"],
            capture_output=True, text=True, timeout=30, cwd=ROOT,
        )  # fmt: skip
        assert r.returncode == 0, r.stderr
        return json.loads(r.stdout)

    def stop(self) -> str:
        self.proc.terminate()
        out, _ = self.proc.communicate(timeout=10)
        return out


def wait_for(pred, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.05)
    return pred()


def test_protocol_positions_and_enable_lines(drive_bin: Path, tmp_path: Path) -> None:
    from contour.link.client import connect

    d = Drive(drive_bin, tmp_path, quadrature(0, 400, 100_000) + quadrature(1, -100, 120_000))
    try:
        assert wait_for(lambda: d.contour("info")["position_mm"][:2] == [0.5, -0.125])
        info = d.contour("info")
        assert info["board_id"] == 4 and info["axes"] == 3
        assert info["firmware_version"] != "0.0.0"
        en = [a * LINES + 2 for a in range(3)]
        assert all(outputs(d.out).get(o) == 0 for o in en)
        with connect(port=d.port) as c:
            c.enable(True)
            assert wait_for(lambda: all(outputs(d.out).get(o) == 1 for o in en))
            assert c.status()["faults"] == 0
            c.enable(False)
            assert wait_for(lambda: all(outputs(d.out).get(o) == 0 for o in en))
    finally:
        d.stop()


def test_amplifier_fault_input(drive_bin: Path, tmp_path: Path) -> None:
    from contour.link.client import DriveError

    # axis 1's FAULT input held low (asserted) from the start: the drive
    # latches the amplifier fault, refuses to enable, keeps the outputs off
    d = Drive(drive_bin, tmp_path, [f"level {1 * LINES + 4} 0"])
    try:
        assert wait_for(lambda: d.contour("info")["state"] == "fault")
        assert d.contour("info")["faults"] == ["amp_fault"]
        from contour.link.client import connect

        with connect(port=d.port) as c, pytest.raises(DriveError, match="fault is latched"):
            c.enable(True)
        assert all(outputs(d.out).get(a * LINES + 2) == 0 for a in range(3))
    finally:
        d.stop()
