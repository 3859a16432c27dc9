"""End to end on the QEMU board (firmware/ports/mps2_an386, docs/ports.md).

The bootloader image boots under qemu-system-arm with UART0 on a TCP socket;
`contour flash` writes the application over it, reboots the board and waits
for the application; `contour info` must report it; a short G-code job must
end at its programmed end point; `contour calibrate --apply` measures axis X
against the board's reference scale (the plant's pitch error map,
plant_mps2.h), applies the table and re-measures the residual. The axes are
the simulator's axis model, compiled into the image, the control code the
real cross-compiled one. One board (one QEMU, one flash) serves the module's
mps2 tests; each test that needs the application flashes it if no earlier
test did, so each can run alone. The STM32F4 images run on QEMU's
netduinoplus2 as far as QEMU models that MCU (boot, link, calibration
reachable). Skipped when arm-none-eabi-gcc or qemu-system-arm is missing.
"""

from __future__ import annotations

import contextlib
import dataclasses
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
from contour.calibration import run
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


class Board:
    """The module's QEMU mps2-an386 board: its serial URL and whether the
    application has been flashed (by test_flash_reboot_and_info or by the
    first test that needs it)."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.flashed = False


@pytest.fixture(scope="module")
def board(firmware: Path, tmp_path_factory: pytest.TempPathFactory):
    log = tmp_path_factory.mktemp("qemu_mps2") / "qemu.log"
    args = ["-M", "mps2-an386", "-serial", "SERIAL", "-kernel", str(firmware / "boot.elf")]
    with _qemu(args, log) as url:
        yield Board(url)


def _flash(board: Board, firmware: Path) -> float:
    """contour flash the application (seconds taken)."""
    t0 = time.monotonic()
    board.flashed = False
    _contour("flash", str(firmware / "app.img"), "--port", board.url, "--no-progress", timeout=180)
    board.flashed = True
    return time.monotonic() - t0


@pytest.fixture()
def app_board(board: Board, firmware: Path) -> str:
    """The board running the application: flashed once per module."""
    if not board.flashed:
        _flash(board, firmware)
    return board.url


def _info(url: str) -> dict:
    return json.loads(_contour("info", "--port", url, "--json").stdout)


def test_flash_reboot_and_info(board: Board, firmware: Path, tmp_path: Path) -> None:
    if board.flashed:
        pytest.skip("the board was flashed by an earlier test (run this test first)")
    # a bare bootloader: info reports it as such (no application yet)
    r = subprocess.run(
        [*CONTOUR, "info", "--port", board.url, "--json"],
        capture_output=True, text=True, timeout=30, cwd=ROOT,
    )  # fmt: skip
    assert r.returncode == 0, r.stdout + r.stderr
    boot = json.loads(r.stdout)
    assert boot["state"] == "bootloader" and boot["board_id"] == 3, boot

    # an image for another board is refused before anything is erased
    other = tmp_path / "other.img"
    subprocess.run(
        [*CONTOUR, "image", "build", str(firmware / "app.elf"), "--board", "stm32f4",
         "--version", "9.9.9", "-o", str(other)],
        check=True, capture_output=True, cwd=ROOT,
    )  # fmt: skip
    r = subprocess.run(
        [*CONTOUR, "flash", str(other), "--port", board.url, "--no-progress"],
        capture_output=True, text=True, timeout=60, cwd=ROOT,
    )  # fmt: skip
    assert r.returncode != 0 and "refusing to flash" in r.stderr, r.stderr

    flash_s = _flash(board, firmware)

    info = _info(board.url)
    assert info["board_id"] == 3  # BOOT_BOARD_QEMU
    assert info["axes"] == 3
    assert "bootloader" in info["capabilities"] and "calibration" in info["capabilities"]
    image_info = json.loads(_contour("image", "info", str(firmware / "app.img"), "--json").stdout)
    fw = image_info["fw_version"]
    assert info["firmware_version"] == f"{fw >> 16}.{(fw >> 8) & 0xFF}.{fw & 0xFF}"
    assert info["state"] == "disabled" and info["faults"] == []
    print(f"\nQEMU board: flashed in {flash_s:.1f} s")


def test_gcode_job_ends_at_end_point(app_board: str, tmp_path: Path) -> None:
    job = tmp_path / "job.nc"
    job.write_text(JOB)
    res = json.loads(_contour("run", str(job), "--port", app_board, "--json", timeout=120).stdout)
    assert res["blocks"] > 4

    # the axes settle on the end point (1.25 um per encoder count)
    deadline = time.monotonic() + 20
    while True:
        info = _info(app_board)
        err = [abs(p - e) for p, e in zip(info["position_mm"], END_MM)]
        if max(err) <= 0.0025 or time.monotonic() > deadline:
            break
        time.sleep(0.3)
    assert info["faults"] == [], info
    assert max(err) <= 0.0025, f"end position {info['position_mm']} mm, expected {END_MM}"
    print(f"\nQEMU board: job {res['elapsed_s']:.2f} s")


# Axis X's pitch error e (um) at the calibrated points, plant_mps2.h; the
# calibration's error is encoder - reference = -e.
PLANT_X_PITCH_UM = {0.0: 0.0, 10.0: 12.0, 20.0: 8.0}


def test_calibrate_apply_residual_on_qemu_board(app_board: str) -> None:
    """`contour calibrate --apply` of axis X against the board's reference
    scale: the measured error is the plant's pitch error, the table goes to
    the drive's flash, and the re-measured residual (on a grid of half the
    step, so also between the table's points) is a small fraction of it."""
    t0 = time.monotonic()
    rep = json.loads(
        _contour(
            "calibrate", "--port", app_board, "--axis", "X", "--from", "0", "--to", "20",
            "--step", "10", "--samples", "20", "--sample-ticks", "1", "--dwell-ms", "100",
            "--apply", "--json", "--no-progress", timeout=120,
        ).stdout
    )  # fmt: skip
    wall_s = time.monotonic() - t0
    assert rep["axis"] == "X"
    assert [p["position_mm"] for p in rep["points"]] == [0.0, 10.0, 20.0]
    assert rep["measure"]["samples"] == 3 * 2 * 20 and rep["measure"]["samples_lost"] == 0
    # before: the plant's map, both directions (measured within 0.4 um of it)
    for p in rep["points"]:
        want_mm = -PLANT_X_PITCH_UM[p["position_mm"]] * 1e-3
        assert abs(p["mean_err_pos_mm"] - want_mm) < 0.0015, p
        assert abs(p["mean_err_neg_mm"] - want_mm) < 0.0015, p
    before_um = rep["summary"]["max_systematic_um"]
    assert before_um > 10.0, rep["summary"]  # 11.8 measured
    # applied: 3 points stored; re-measured at 0, 5 .. 20 mm with the compensation on
    assert rep["applied"]["n"] == 3
    assert [p["position_mm"] for p in rep["residual_points"]] == [0.0, 5.0, 10.0, 15.0, 20.0]
    assert rep["verify"]["samples"] == 5 * 2 * 20
    residual_um = rep["residual"]["residual_systematic_um"]
    assert residual_um < 1.5, rep["residual"]  # 0.25 measured
    assert residual_um < before_um / 8, (before_um, residual_um)
    info = _info(app_board)
    assert info["faults"] == [] and info["state"] in ("ready", "disabled"), info
    print(
        f"\nQEMU board: calibrate X {before_um:.2f} um -> residual {residual_um:.2f} um "
        f"in {wall_s:.1f} s"
    )


def test_2d_map_loads_and_applies_on_qemu_board(app_board: str) -> None:
    """The 2-D compensation map (comp2d_link.h) on the cross-compiled image:
    uploaded over the board's serial link, stored in its flash (read back
    byte for byte), and applied in its tick: with the drive disabled the
    axes stand still and the measured position moves by the map's
    correction (+20 um on X, -10 um on Y, everywhere); cleared, it is
    gone."""
    import numpy as np
    from contour.calibration import grid, map2d

    g = np.zeros((2, 3, 3, 3))
    g[0, 0], g[1, 0] = 20.0, -10.0  # mean corrections, um
    rec = map2d.encode_record(map2d.to_c(map2d.Map2D(-100.0, 100.0, -100.0, 100.0, g)))
    with connect(port=app_board, timeout=1.0) as client:
        client.enable(False)
        time.sleep(0.1)
        before = client.status()["pos"]
        info = grid.upload_map(client, rec, time.sleep)
        assert info["active"] == 1 and info["nx"] == 3 and info["length"] == len(rec)
        assert grid.read_map(client) == rec
        time.sleep(0.2)
        after = client.status()["pos"]
        assert abs(after[0] - before[0] - 20000) < 1500, (before, after)
        assert abs(after[1] - before[1] + 10000) < 1500, (before, after)
        assert client.request("comp2d_clear").fields["active"] == 0
        time.sleep(0.2)
        back = client.status()["pos"]
        assert abs(back[0] - before[0]) < 1500 and abs(back[1] - before[1]) < 1500


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


@pytest.fixture(scope="module")
def f4_firmware() -> Path:
    return _build("stm32f4")


@contextlib.contextmanager
def _f4_board(fw: Path, tmp_path: Path):
    """The factory-programmed STM32F4 on netduinoplus2, running its
    application; yields the URL and the application's `contour info`."""
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
        yield url, json.loads(r.stdout)


def test_stm32f4_images_boot_on_qemu_netduinoplus2(f4_firmware: Path, tmp_path: Path) -> None:
    """The STM32F4 bootloader and application, unchanged, on QEMU's STM32F405
    model: start-up code, vector tables, linker scripts, the bootloader's
    slot check and jump, SysTick, USART2 and the protocol. QEMU models no
    RCC, GPIO, encoder mode or bxCAN: the crystal never reports ready, so
    the board takes its HSI fallback and must refuse to drive the axes."""
    fw = f4_firmware
    with _f4_board(fw, tmp_path) as (url, info):
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


def test_stm32f4_calibration_reachable_on_qemu_netduinoplus2(
    f4_firmware: Path, tmp_path: Path
) -> None:
    """Calibration is wired on the STM32F4 build: the application answers the
    calibration ids with calib_state and checks a setup against its board
    description (X has the reference scale on TIM5, Y none). QEMU models no
    encoder timers and the HSI fallback faults the axes, so no run can move:
    calib_start is refused because the drive is not ready."""
    with _f4_board(f4_firmware, tmp_path) as (url, info), connect(port=url) as client:
        assert "calibration" in info["capabilities"], info
        st = client.request("calib_status")
        assert st.name == "calib_state", st
        assert st.fields["state"] == pg.CalibRunState.IDLE, st.fields

        cal = run.Calibrator(client, time.sleep)
        cfg = run.RunConfig(
            axis=0, targets_nm=[0, 1_000_000], cycles=1, samples=4, sample_ticks=1,
            dwell_ms=10, overrun_nm=100_000, feed_nm_s=10_000_000, host_reference=False,
        )  # fmt: skip
        cal.setup(cfg)  # accepted: X has a reference scale
        st = client.request("calib_status")
        assert st.fields["state"] == pg.CalibRunState.SETUP, st.fields
        with pytest.raises(DriveError) as refused:
            client.request("calib_start")
        f = refused.value.fields
        assert f["code"] == pg.ErrorCode.CALIB and f["arg"] == pg.CalibStatus.DRIVE_DISABLED, f

        with pytest.raises(DriveError) as refused:
            cal.setup(dataclasses.replace(cfg, axis=1))  # Y: no reference scale on this board
        f = refused.value.fields
        assert f["code"] == pg.ErrorCode.CALIB and f["arg"] == pg.CalibStatus.NO_REFERENCE, f
