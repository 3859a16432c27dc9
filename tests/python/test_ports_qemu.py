"""End to end on the QEMU board (firmware/ports/mps2_an386, docs/ports.md).

The bootloader image boots under qemu-system-arm with UART0 on a TCP socket;
`contour flash` writes the application over it, reboots the board and waits
for the application; `contour info` must report it; a short G-code job must
end at its programmed end point (the axes are the simulator's axis model,
compiled into the image, the control code the real cross-compiled one).
Skipped when arm-none-eabi-gcc or qemu-system-arm is missing.
"""

from __future__ import annotations

import contextlib
import json
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from contour import image as img
from contour import protocol_gen as pg
from contour.link import boot as flashcmd
from contour.link.client import DriveError, connect
from contour.link.transport import open_transport

ROOT = Path(__file__).resolve().parents[2]
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


def _build(board: str) -> Path:
    r = subprocess.run(
        [str(ROOT / "mk" / "firmware.sh"), board],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    return ROOT / "build" / "fw" / board


@pytest.fixture(scope="module")
def firmware() -> Path:
    return _build("mps2_an386")


@contextlib.contextmanager
def _qemu(args: list[str], log_path: Path):
    """qemu-system-arm with one UART on a TCP socket; yields its URL."""
    port = _free_port()
    serial = f"tcp:127.0.0.1:{port},server=on,wait=off"
    with open(log_path, "w") as log:
        proc = subprocess.Popen(
            ["qemu-system-arm", "-nographic", "-monitor", "none",
             *[serial if a == "SERIAL" else a for a in args]],
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
                    assert proc.poll() is None, log_path.read_text()
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


@pytest.fixture()
def board(firmware: Path, tmp_path: Path):
    args = ["-M", "mps2-an386", "-serial", "SERIAL", "-kernel", str(firmware / "boot.elf")]
    with _qemu(args, tmp_path / "qemu.log") as url:
        yield url


def _info(url: str) -> dict:
    return json.loads(_contour("info", "--port", url, "--json").stdout)


def test_flash_reboot_info_and_job(board: str, firmware: Path, tmp_path: Path) -> None:
    # a bare bootloader: identify answers, but as a bootloader (no application yet)
    r = subprocess.run(
        [*CONTOUR, "info", "--port", board, "--json"],
        capture_output=True, text=True, timeout=30, cwd=ROOT,
    )  # fmt: skip
    err = json.loads(r.stdout)["error"]  # --json: the error is JSON on stdout
    assert r.returncode == 1 and err["kind"] == "drive" and "unknown_message" in err["message"]

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


# ---- the STM32F4 images on QEMU's netduinoplus2 (STM32F405) ------------------------------------

F4_FLASH = 0x08000000


def _f4_factory_flash(fw: Path, out: Path) -> Path:
    """1 MiB of erased flash with the bootloader at its start and the
    validated application slot (app.hex) on top: what a factory programmer
    writes. QEMU's flash is ROM that reads 0 where nothing was loaded."""
    flash = bytearray(b"\xff" * (1 << 20))
    boot = (fw / "boot.bin").read_bytes()
    flash[: len(boot)] = boot
    for addr, b in img.from_hex((fw / "app.hex").read_text()).items():
        flash[addr - F4_FLASH] = b
    out.write_bytes(flash)
    return out


def test_stm32f4_images_boot_on_qemu_netduinoplus2(tmp_path: Path) -> None:
    """The STM32F4 bootloader and application, unchanged, on QEMU's STM32F405
    model: start-up code, vector tables, linker scripts, the bootloader's
    slot check and jump, SysTick, USART2 and the protocol. QEMU models no
    RCC, GPIO, encoder mode or bxCAN: the crystal never reports ready, so
    the board takes its HSI fallback and must refuse to drive the axes."""
    fw = _build("stm32f4")
    flash = _f4_factory_flash(fw, tmp_path / "flash.bin")
    args = ["-M", "netduinoplus2", "-device", f"loader,file={flash},addr={F4_FLASH},force-raw=on",
            "-serial", "null", "-serial", "SERIAL"]  # fmt: skip
    with _qemu(args, tmp_path / "qemu.log") as url:
        deadline = time.monotonic() + 20
        while True:  # the bootloader's connect window, then the application
            r = subprocess.run([*CONTOUR, "info", "--port", url, "--json"],
                               capture_output=True, text=True, timeout=30, cwd=ROOT)  # fmt: skip
            if r.returncode == 0 or time.monotonic() > deadline:
                break
            time.sleep(0.5)
        assert r.returncode == 0, r.stderr
        info = json.loads(r.stdout)
        image = img.load(str(fw / "app.img"))
        fw_version = image.header.fw_version
        assert info["board_id"] == 2  # BOOT_BOARD_STM32F4
        assert info["axes"] == 3 and info["tick_hz"] == 10000
        assert info["firmware_version"] == (
            f"{fw_version >> 16}.{(fw_version >> 8) & 0xFF}.{fw_version & 0xFF}"
        )
        assert "bootloader" in info["capabilities"]
        # HSI fallback: every axis reports an amplifier fault, enable refused
        assert info["state"] == "fault" and info["faults"] == ["amp_fault"], info
        with connect(port=url) as client, pytest.raises(DriveError, match="fault"):
            client.enable(True)

        # boot_enter: the application resets into its bootloader, which holds
        # (the host connected) and reports the application CRC-checked
        link = flashcmd.TransportLink(open_transport(port=url))
        try:
            boot = flashcmd.enter_bootloader(flashcmd.BootClient(link, timeout=1.0), wait=20.0)
        finally:
            link.close()
        assert boot["board_id"] == 2
        assert boot["app_state"] == pg.BootReason.APP_OK
        assert boot["slot_base"] == 0x08020000 and boot["page_size"] == 128 * 1024
        assert boot["app_version"] == fw_version and boot["app_length"] == image.header.length
