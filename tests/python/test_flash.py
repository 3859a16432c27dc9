"""contour flash and the image format, against the simulated drive's real
bootloader (firmware/core/boot + the simulated flash, in process through
libcontour.so), with fault injection at every block boundary and at random
flash bytes: the drive always comes back in its bootloader or in a valid
(old or new) application, and a second flash always succeeds."""

from __future__ import annotations

import contextlib
import ctypes
import random
import shutil
import struct
import subprocess

import can
import pytest
from contour import image as img
from contour import native
from contour import protocol_gen as pg
from contour.cli import main as cli_main
from contour.errors import UserError
from contour.link import boot as fl
from contour.link import codec
from contour.sim.bootsim import SimDriveLink

SIM_LOAD = 0x08010000 + img.HDR_AREA
SIM_BOARD = img.BOARDS["sim"]


def make_image(n: int, version: str, seed: int, **kw) -> img.Image:
    rnd = random.Random(seed)
    payload = bytes(rnd.getrandbits(8) for _ in range(n))
    args = dict(board_id=SIM_BOARD, fw_version=img.parse_version(version), load_addr=SIM_LOAD)
    args.update(kw)
    return img.build(payload, **args)


OLD = make_image(9000, "1.0.0", 1)
NEW = make_image(16001, "2.0.1", 2)


class Killed(Exception):
    """The host process dies."""


@pytest.fixture
def drive(tmp_path):
    try:
        assert native.load().boot_sim_init
    except (UserError, AttributeError):
        pytest.skip("build/host/libcontour.so without the simulated bootloader: run make")
    d = SimDriveLink(str(tmp_path / "flash.bin"))
    d.sent = []
    inner = d.exchange

    def recording(msg, timeout):
        d.sent.append(msg[0])
        return inner(msg, timeout)

    d.exchange = recording
    return d


def client(link) -> fl.BootClient:
    return fl.BootClient(link, timeout=0.0, retries=4, sleep=lambda s: None)


def do_flash(link, image, **kw):
    kw.setdefault("confirm_wait", 1.0)
    kw.setdefault("enter_wait", 0.2)
    return fl.flash(client(link), image, log=lambda s: None, **kw)


def state(drive) -> tuple[str, int]:
    """(mode, running version) after a reset of the drive."""
    drive.before = drive.after = None
    drive.reset()
    if drive.mode() == "app":
        return "app", drive.lib.boot_sim_app_version()
    return "bootloader", 0


def assert_recoverable(drive, allowed_versions):
    mode, version = state(drive)
    if mode == "app":
        assert version in allowed_versions
    r = do_flash(drive, NEW)
    assert r["version"] == "2.0.1"
    assert state(drive) == ("app", NEW.header.fw_version)
    return mode


# ---- image format --------------------------------------------------------------


def test_image_roundtrip_and_hex_holds_a_validated_slot():
    data = NEW.to_bytes()
    back = img.parse(data)
    assert back.header.length == 16001
    assert back.header.payload_crc == img.crc32(NEW.payload)
    mem = img.from_hex(img.to_hex(NEW.flash_records()))
    slot = SIM_LOAD - img.HDR_AREA
    assert bytes(mem[slot + i] for i in range(64)) == data[:64]
    marker = bytes(mem[slot + 64 + i] for i in range(8))
    assert marker == struct.pack("<II", img.MARK_VALID, NEW.header.header_crc)
    assert bytes(mem[SIM_LOAD + i] for i in range(16001)) == NEW.payload
    assert slot + 65 + 8 not in mem  # the rest of the header area stays erased


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda b: b[:-1], "truncated image"),
        (lambda b: b[:40], "truncated image"),
        (lambda b: b + b"\0", "after the"),
        (lambda b: b[:100] + bytes([b[100] ^ 1]) + b[101:], "payload CRC mismatch"),
        (lambda b: b[:12] + bytes([b[12] ^ 1]) + b[13:], "header CRC mismatch"),
        (lambda b: b"XTFW" + b[4:], "not a contour firmware image"),
    ],
)
def test_corrupted_image_files_are_refused(mutate, message):
    with pytest.raises(img.ImageError, match=message):
        img.parse(mutate(NEW.to_bytes()))


@pytest.mark.skipif(shutil.which("arm-none-eabi-gcc") is None, reason="no cross compiler")
def test_elf_input_matches_objcopy_with_data_at_its_load_address(tmp_path):
    (tmp_path / "app.ld").write_text(
        "MEMORY { FLASH (rx) : ORIGIN = 0x08010200, LENGTH = 200K\n"
        "         RAM (rwx) : ORIGIN = 0x20000000, LENGTH = 64K }\n"
        "SECTIONS { .text : { KEEP(*(.vectors)) *(.text*) *(.rodata*) } > FLASH\n"
        "  .data : { *(.data*) } > RAM AT > FLASH  .bss : { *(.bss*) } > RAM }\n"
    )
    (tmp_path / "app.c").write_text(
        "int x = 5; int y;\n"
        'const unsigned v[2] __attribute__((section(".vectors"))) = {0x20001000u, 0x08010301u};\n'
        "int main(void) { return x + y; }\n"
    )
    elf = tmp_path / "app.elf"
    cc = ["arm-none-eabi-gcc", "-mcpu=cortex-m4", "-mthumb", "-nostdlib", "-O1"]
    subprocess.run(
        [*cc, "-T", str(tmp_path / "app.ld"), "-o", str(elf), str(tmp_path / "app.c")], check=True
    )
    ref = tmp_path / "ref.bin"
    subprocess.run(
        ["arm-none-eabi-objcopy", "--gap-fill", "0xff", "-O", "binary", str(elf), str(ref)],
        check=True,
    )
    assert img.main(["build", str(elf), "--board", "sim", "--version", "3.4.5"]) == 0
    out = img.load(tmp_path / "app.img")
    assert out.header.load_addr == SIM_LOAD
    assert out.payload == ref.read_bytes()
    assert out.payload[:8] == struct.pack("<II", 0x20001000, 0x08010301)
    assert (tmp_path / "app.bin").read_bytes() == out.payload
    assert (tmp_path / "app.hex").read_text().endswith(":00000001FF\n")
    assert (
        img.main(["build", str(elf), "--board", "1", "--version", "1.0.0", "--load-addr", "0x0"])
        == 2
    )


def test_raw_binary_needs_load_address(tmp_path, capsys):
    (tmp_path / "a.bin").write_bytes(b"abc")
    assert img.main(["build", str(tmp_path / "a.bin"), "--board", "1", "--version", "1.0.0"]) == 2
    assert "needs --load-addr" in capsys.readouterr().err


# ---- flashing ----------------------------------------------------------------------


def test_flash_reboots_into_new_version_and_verify_only(drive):
    r = do_flash(drive, OLD)
    assert r["version"] == "1.0.0"
    assert state(drive) == ("app", OLD.header.fw_version)
    # the application is running: flash asks it to reset into the bootloader
    r = do_flash(drive, NEW)
    assert pg.MSG_BY_NAME["boot_enter"].id in drive.sent
    assert state(drive) == ("app", NEW.header.fw_version)
    do_flash(drive, NEW, verify_only=True)
    with pytest.raises(UserError, match="does not hold this image"):
        do_flash(drive, OLD, verify_only=True)


def test_flash_file_survives_a_simulator_restart(drive, tmp_path):
    do_flash(drive, NEW)
    again = SimDriveLink(str(tmp_path / "flash.bin"))  # new process, same flash file
    assert again.mode() == "app"
    assert again.lib.boot_sim_app_version() == NEW.header.fw_version


@pytest.mark.parametrize(
    "kw, message",
    [
        ({"board_id": 7}, "image is for board 7, the drive is board 1"),
        ({"load_addr": SIM_LOAD + 0x1000}, "linked for load address 0x08011200"),
    ],
)
def test_wrong_target_refused_before_anything_is_erased(drive, kw, message):
    do_flash(drive, OLD)
    bad = make_image(2000, "9.9.9", 5, **kw)
    drive.sent.clear()
    with pytest.raises(img.ImageError, match=message) as exc_info:
        do_flash(drive, bad)
    assert pg.MSG_BY_NAME["boot_erase"].id not in drive.sent
    assert state(drive) == ("app", OLD.header.fw_version)
    if "board_id" in kw:  # known from the application itself: it is never reset
        assert pg.MSG_BY_NAME["boot_enter"].id not in drive.sent
        assert "keeps running its application" in str(exc_info.value)


def test_oversize_refused_before_anything_is_erased(drive):
    do_flash(drive, OLD)
    big = make_image(256 * 1024 - 32 * 1024 - img.HDR_AREA + 1, "9.9.9", 6)
    drive.sent.clear()
    with pytest.raises(img.ImageError, match="slot holds 228864"):
        do_flash(drive, big)
    assert pg.MSG_BY_NAME["boot_erase"].id not in drive.sent
    assert drive.mode() == "app"  # the refusal rebooted it into its application
    # the drive itself refuses it too, with a specific status and nothing erased
    c = client(drive)
    fl.enter_bootloader(c)
    with pytest.raises(fl.Refused, match="bad length"):
        c.request("boot_erase", {"header": list(big.header.encode())})
    assert state(drive) == ("app", OLD.header.fw_version)


def test_cli_refuses_corrupt_file_with_one_line(tmp_path, capsys):
    p = tmp_path / "x.img"
    data = bytearray(NEW.to_bytes())
    data[200] ^= 0x40
    p.write_bytes(bytes(data))
    assert cli_main(["flash", str(p), "--port", "/nonexistent"]) == 1  # a file error
    err = capsys.readouterr().err
    assert "payload CRC mismatch" in err and "Traceback" not in err


@pytest.mark.parametrize(
    "opts, message",
    [
        (["--attempts", "0"], "--attempts must be 1..100"),  # would flash nothing
        (["--timeout", "-1"], "--timeout must be in (0, 60] s"),
    ],
)
def test_cli_refuses_bad_numbers_before_opening_the_link(tmp_path, capsys, opts, message):
    p = tmp_path / "new.img"
    p.write_bytes(NEW.to_bytes())
    # the port does not exist: the options must be refused before it is opened
    assert cli_main(["flash", str(p), "--port", "/nonexistent", *opts]) == 2
    err = capsys.readouterr().err
    assert err.startswith("contour: error: ") and err.count("\n") == 1
    assert message in err


# ---- fault injection -------------------------------------------------------------


def session_length(drive) -> int:
    """Messages of one flash of NEW into a drive in its bootloader."""
    drive.reset()
    n0 = drive.count
    do_flash(drive, NEW)
    return drive.count - n0


def test_host_killed_at_every_message_of_the_session(drive):
    do_flash(drive, OLD)
    total = session_length(drive)
    outcomes = {"bootloader": 0, "app": 0}
    for k in range(1, total + 1):
        do_flash(drive, OLD)
        base = drive.count

        def before(n, msg, k=k, base=base):
            if n - base == k:
                raise Killed()

        drive.before = before
        with pytest.raises(Killed):
            do_flash(drive, NEW)
        outcomes[assert_recoverable(drive, {OLD.header.fw_version, NEW.header.fw_version})] += 1
    print(f"host killed at {total} points: {outcomes}, {total} second flashes ok")
    assert sum(outcomes.values()) == total
    assert outcomes["bootloader"] > 60  # every block boundary after the erase


def test_link_drops_are_retried_and_long_outage_recovers(drive):
    do_flash(drive, OLD)
    total = session_length(drive)
    recovered_in_place = 0
    for k in range(2, total, 7):
        drive.reset()
        base = drive.count
        # lose request k and the reply to k+1: the client retries with back-off
        drive.before = lambda n, m, k=k, b=base: "drop" if n - b == k else None
        drive.after = lambda n, r, k=k, b=base: "drop" if n - b == k + 2 else None
        do_flash(drive, NEW)
        recovered_in_place += 1
    for k in range(2, total, 11):
        do_flash(drive, OLD)
        base = drive.count
        drive.before = lambda n, m, k=k, b=base: "drop" if n - b >= k else None
        with pytest.raises(fl.LinkLost):
            do_flash(drive, NEW)
        assert_recoverable(drive, {OLD.header.fw_version, NEW.header.fw_version})
    outages = len(range(2, total, 11))
    print(
        f"link drops: {recovered_in_place} flashes recovered by retries, {outages} outages "
        "recovered by a second flash"
    )
    assert recovered_in_place > 5


def test_drive_reset_mid_transfer_restarts_the_session(drive):
    do_flash(drive, OLD)
    total = session_length(drive)
    resets = restarted = 0
    for k in range(3, total - 3, 5):
        drive.reset()
        base = drive.count
        drive.before = lambda n, m, k=k, b=base: "reset" if n - b == k else None
        c = client(drive)
        fl.flash(c, NEW, log=lambda s: None, confirm_wait=1.0)
        assert state(drive) == ("app", NEW.header.fw_version)
        assert c.stats.sessions >= 1
        resets += 1
        restarted += c.stats.sessions > 1
    print(f"drive reset at {resets} messages: {restarted} sessions restarted, all flashed")


def test_power_cut_at_random_flash_bytes(drive):
    rnd = random.Random(9)
    total_bytes = 16001 + 512 + 16 * 1024 + 2048  # erase + program, roughly
    points = 0
    modes = {"bootloader": 0, "app": 0}
    erase_id = pg.MSG_BY_NAME["boot_erase"].id
    for _ in range(60):
        do_flash(drive, OLD)
        cut = rnd.randrange(total_bytes)

        def arm(n, msg, cut=cut):
            if msg[0] == erase_id:  # in the bootloader now; the next reset restores power
                drive.power_cut_after(cut)

        drive.before = arm
        with contextlib.suppress(UserError):
            do_flash(drive, NEW)
        modes[assert_recoverable(drive, {OLD.header.fw_version, NEW.header.fw_version})] += 1
        points += 1
    print(f"power cut at {points} random flash bytes: {modes}, {points} second flashes ok")
    assert modes["bootloader"] > 0


def test_bit_flips_in_transit_are_caught_by_frame_crc(drive):
    """Every request goes through the drive's own serial frame decoder
    (proto_frame.c); a flipped bit fails the frame CRC, the frame is dropped,
    and the host's retry delivers it."""
    lib = drive.lib
    rx = ctypes.create_string_buffer(1024)
    lib.proto_frame_rx_init(rx)
    rnd = random.Random(3)
    flips = {"sent": 0, "dropped": 0}
    inner = SimDriveLink.exchange

    def framed(msg, timeout):
        wire = bytearray(codec.frame(msg))
        if rnd.random() < 0.1:
            bit = rnd.randrange(8 * (len(wire) - 1))
            wire[bit // 8] ^= 1 << (bit % 8)
            flips["sent"] += 1
        out = ctypes.POINTER(ctypes.c_uint8)()
        ln = ctypes.c_size_t()
        got = None
        for b in bytes(wire):
            if lib.proto_frame_rx_byte(rx, b, ctypes.byref(out), ctypes.byref(ln)):
                got = ctypes.string_at(out, ln.value)
        if got is None:
            flips["dropped"] += 1
            return None
        assert got == msg  # a frame that passed the CRC is the message sent
        return inner(drive, got, timeout)

    drive.exchange = framed
    do_flash(drive, NEW)
    assert state(drive) == ("app", NEW.header.fw_version)
    assert flips["sent"] > 5
    assert flips["dropped"] >= flips["sent"] - 1  # a flip in a delimiter may split, not pass


def test_corruption_past_the_frame_layer_is_caught_by_the_image_crc(drive):
    do_flash(drive, OLD)
    w = pg.MSG_BY_NAME["boot_write"].id
    hits = []

    def corrupt(n, msg):
        if msg[0] == w and not hits:
            hits.append(n)
            return "corrupt"
        return None

    inner = drive.exchange

    def exchange(msg, timeout):
        if corrupt(drive.count + 1, msg) == "corrupt":
            msg = msg[:-1] + bytes([msg[-1] ^ 0x10])
        return inner(msg, timeout)

    drive.exchange = exchange
    c = client(drive)
    fl.flash(c, NEW, log=lambda s: None, confirm_wait=1.0)
    assert c.stats.sessions == 2  # read-back CRC mismatch: erased and written again
    assert state(drive) == ("app", NEW.header.fw_version)


def test_transmit_buffer_full_is_waited_out(drive):
    inner = drive.exchange
    calls = {"n": 0}

    def flaky(msg, timeout):
        calls["n"] += 1
        if calls["n"] % 5 == 0:
            raise can.CanOperationError("Transmit buffer full")
        return inner(msg, timeout)

    drive.exchange = flaky
    c = client(drive)
    fl.flash(c, NEW, log=lambda s: None, confirm_wait=1.0)
    assert c.stats.tx_full_waits > 10
    assert c.stats.retries == 0
    assert fl.tx_buffer_full(OSError(105, "No buffer space available"))
    assert not fl.tx_buffer_full(can.CanOperationError("bus off"))


# ---- progress only on a terminal ------------------------------------------------------


def test_flash_draws_no_progress_bar_into_a_pipe(drive, tmp_path, capsys):
    """stderr is not a terminal here: the summary line only, no bar redraws."""
    p = tmp_path / "new.img"
    p.write_bytes(NEW.to_bytes())
    assert cli_main(["flash", str(p), "--sim-flash", str(tmp_path / "f.bin")]) == 0
    err = capsys.readouterr().err
    assert err == "flashed 16001 bytes; drive runs version 2.0.1\n", err


def test_progress_bar_draws_on_a_terminal_only():
    import os

    from contour.progress import Bar

    master, slave = os.openpty()
    with os.fdopen(slave, "w") as tty:
        with Bar(total=10, unit="B", desc="flash", file=tty) as bar:
            assert bar.active
            bar.update(10)
        tty.flush()
        assert b"flash" in os.read(master, 4096)
    os.close(master)
    r, w = os.pipe()
    with os.fdopen(w, "w") as pipe, Bar(total=10, file=pipe) as bar:
        assert not bar.active
        bar.update(5)
        bar.to(10, 10)
        bar.note("x")
    with os.fdopen(r) as f:
        assert f.read() == ""


def test_info_prints_the_build_id_in_the_image_byte_order():
    """`contour info` shows the first bytes of the build id exactly as
    `contour image info` (and the git commit of `make firmware`) does."""
    from contour.commands import info

    image = make_image(100, "1.0.0", 3, build_id=bytes.fromhex("0123456789abcdef"))

    class Fake:
        def identify(self):
            return {
                "fw_version": image.header.fw_version,
                # what the drive sends: the first 4 build-id bytes as a little-endian u32
                "build_id": int.from_bytes(image.header.build_id[:4], "little"),
                "protocol_version": pg.PROTOCOL_VERSION,
                "board_id": SIM_BOARD,
                "node_id": 1,
                "axes": 1,
                "capabilities": 0,
                "tick_hz": 10000,
                "planner_slots": 8,
                "max_payload": 224,
            }

        def status(self):
            return {
                "state": 0,
                "faults": 0,
                "free_slots": 8,
                "queued_us": 0,
                "blocks_done": 0,
                "pos": [0, 0, 0, 0],
                "rx_errors": 0,
                "replayed": 0,
            }

    shown = info.gather(Fake())["build_id"]
    assert shown == "01234567"
    assert image.header.describe()["build_id"].startswith(shown)


# ---- image build never overwrites its input, and names what it writes ---------------


def _build(argv):
    return cli_main(["image", "build", *argv, "--board", "1", "--version", "1.0.0"])


@pytest.mark.parametrize(
    "inp, opts, message",
    [
        ("app.img", [], "is the input file"),  # default output INPUT.img is the input
        ("app.bin", ["-o", "app.bin"], "extension .img"),  # would hold an image, not raw
        ("app.bin", ["-o", "app"], "extension .img"),
        ("app.bin", ["-o", "out.img", "--hex", "out.img"], "extension .hex"),
        ("app.hex", ["-o", "out.img", "--hex", "app.hex"], "is the input file"),
        ("app.bin", ["-o", "sub/../app.bin.img", "--hex", "app.bin"], "extension .hex"),
    ],
)
def test_image_build_refuses_outputs_that_overwrite_or_mislabel(
    tmp_path, capsys, monkeypatch, inp, opts, message
):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sub").mkdir()
    (tmp_path / inp).write_bytes(b"payload bytes")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    assert _build([inp, "--load-addr", hex(SIM_LOAD), *opts]) == 2
    assert message in capsys.readouterr().err
    after = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    assert after == before  # nothing written


def test_image_build_refuses_an_output_linked_to_its_input(tmp_path, capsys):
    (tmp_path / "app.raw").write_bytes(b"payload bytes")
    (tmp_path / "link.img").symlink_to(tmp_path / "app.raw")
    argv = [
        str(tmp_path / "app.raw"),
        "--load-addr",
        hex(SIM_LOAD),
        "-o",
        str(tmp_path / "link.img"),
    ]
    assert _build(argv) == 2
    assert "is the input file" in capsys.readouterr().err
    assert (tmp_path / "app.raw").read_bytes() == b"payload bytes"
    # a good name builds
    argv[-1] = str(tmp_path / "good.img")
    assert _build(argv) == 0
    assert img.load(tmp_path / "good.img").payload == b"payload bytes"
    assert (tmp_path / "good.hex").exists() and not (tmp_path / "good.bin").exists()


def test_flash_and_image_build_json(drive, tmp_path, capsys):
    import json

    p = tmp_path / "new.img"
    p.write_bytes(NEW.to_bytes())
    argv = ["flash", str(p), "--sim-flash", str(tmp_path / "f.bin"), "--json"]
    assert cli_main(argv) == 0
    out = capsys.readouterr()
    r = json.loads(out.out)
    assert r["version"] == "2.0.1" and r["link"]["requests"] > 0 and out.err == ""
    # a corrupt file under --json: one error object, exit 1
    data = bytearray(NEW.to_bytes())
    data[200] ^= 0x40
    p.write_bytes(bytes(data))
    assert cli_main(argv) == 1
    err = json.loads(capsys.readouterr().out)["error"]
    assert err["kind"] == "image" and "payload CRC mismatch" in err["message"]
    (tmp_path / "a.raw").write_bytes(b"abc")
    argv = [str(tmp_path / "a.raw"), "--load-addr", hex(SIM_LOAD), "-o", str(tmp_path / "a.img")]
    assert _build([*argv, "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["image"] == str(tmp_path / "a.img") and r["header"]["length"] == 3
