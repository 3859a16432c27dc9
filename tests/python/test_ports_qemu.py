"""End to end on the QEMU board (firmware/ports/mps2_an386, docs/ports.md).

The bootloader image boots under qemu-system-arm with UART0 on a TCP socket;
`contour flash` writes the application over it, reboots the board and waits
for the application; `contour info` must report it; a short G-code job must
end at its programmed end point (the axes are the simulator's axis model,
compiled into the image, the control code the real cross-compiled one).
Skipped when arm-none-eabi-gcc or qemu-system-arm is missing.
"""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FW = ROOT / "build" / "fw" / "mps2_an386"
CONTOUR = [sys.executable, "-m", "contour"]

pytestmark = pytest.mark.skipif(
    shutil.which("arm-none-eabi-gcc") is None or shutil.which("qemu-system-arm") is None,
    reason="needs arm-none-eabi-gcc and qemu-system-arm",
)

JOB = """\
(short job on the QEMU board)
G21 G90
G1 X2 Y1 Z0.5 F600
G1 X3 Y-1 F900
G2 X5 Y-1 I1 J0 F600
G0 X1.5 Y0.75 Z0.25
"""
END_MM = (1.5, 0.75, 0.25)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _contour(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    r = subprocess.run([*CONTOUR, *args], capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    assert r.returncode == 0, f"contour {' '.join(args)} failed:\n{r.stdout}\n{r.stderr}"
    return r


@pytest.fixture(scope="module")
def firmware() -> Path:
    r = subprocess.run(
        [str(ROOT / "mk" / "firmware.sh"), "mps2_an386"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    return FW


@pytest.fixture()
def board(firmware: Path, tmp_path: Path):
    port = _free_port()
    with open(tmp_path / "qemu.log", "w") as log:
        proc = subprocess.Popen(
            [
                "qemu-system-arm",
                "-M", "mps2-an386",
                "-nographic",
                "-monitor", "none",
                "-serial", f"tcp:127.0.0.1:{port},server=on,wait=off",
                "-kernel", str(firmware / "boot.elf"),
            ],
            stdout=log,
            stderr=subprocess.STDOUT,
        )  # fmt: skip
        try:
            deadline = time.monotonic() + 10
            while True:
                try:
                    socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
                    break
                except OSError:
                    assert proc.poll() is None, (tmp_path / "qemu.log").read_text()
                    assert time.monotonic() < deadline, "QEMU did not open its serial socket"
                    time.sleep(0.05)
            yield f"socket://127.0.0.1:{port}"
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()


def _info(url: str) -> dict:
    return json.loads(_contour("info", "--port", url, "--json").stdout)


def test_flash_reboot_info_and_job(board: str, firmware: Path, tmp_path: Path) -> None:
    # a bare bootloader: identify answers, but as a bootloader (no application yet)
    r = subprocess.run(
        [*CONTOUR, "info", "--port", board, "--json"],
        capture_output=True, text=True, timeout=30, cwd=ROOT,
    )  # fmt: skip
    assert r.returncode != 0 and "unknown_message" in r.stderr

    # an image for another board is refused before anything is erased
    other = tmp_path / "other.img"
    subprocess.run(
        [*CONTOUR, "image", "build", str(firmware / "app.elf"), "--board", "stm32f4",
         "--version", "9.9.9", "-o", str(other)],
        check=True, capture_output=True, cwd=ROOT,
    )  # fmt: skip
    r = subprocess.run(
        [*CONTOUR, "flash", str(other), "--port", board, "--no-progress"],
        capture_output=True, text=True, timeout=60, cwd=ROOT,
    )  # fmt: skip
    assert r.returncode != 0 and "refusing to flash" in r.stderr, r.stderr

    t0 = time.monotonic()
    _contour("flash", str(firmware / "app.img"), "--port", board, "--no-progress", timeout=180)
    flash_s = time.monotonic() - t0

    info = _info(board)
    assert info["board_id"] == 3  # BOOT_BOARD_QEMU
    assert info["axes"] == 3
    assert "bootloader" in info["capabilities"]
    image_info = json.loads(_contour("image", "info", str(firmware / "app.img"), "--json").stdout)
    fw = image_info["fw_version"]
    assert info["firmware_version"] == f"{fw >> 16}.{(fw >> 8) & 0xFF}.{fw & 0xFF}"
    assert info["state"] == "disabled" and info["faults"] == []

    job = tmp_path / "job.nc"
    job.write_text(JOB)
    res = json.loads(_contour("run", str(job), "--port", board, "--json", timeout=120).stdout)
    assert res["blocks"] > 4

    # the axes settle on the end point (1.25 um per encoder count)
    deadline = time.monotonic() + 20
    while True:
        info = _info(board)
        err = [abs(p - e) for p, e in zip(info["position_mm"], END_MM)]
        if max(err) <= 0.0025 or time.monotonic() > deadline:
            break
        time.sleep(0.3)
    assert info["faults"] == [], info
    assert max(err) <= 0.0025, f"end position {info['position_mm']} mm, expected {END_MM}"
    print(f"\nQEMU board: flashed in {flash_s:.1f} s, job {res['elapsed_s']:.2f} s")
