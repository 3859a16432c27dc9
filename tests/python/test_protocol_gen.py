"""The protocol definition and what is generated from it.

- every generated file matches what protocol/gen.py makes now (stale = fail);
- the generator rejects a broken definition with a clear message;
- the Python codec and framing agree byte for byte with the C ones (through
  libcontour.so, when it is built);
- the DBC decodes the cyclic frames the codec encodes (cantools).
"""

from __future__ import annotations

import ctypes
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
GEN = ROOT / "protocol" / "gen.py"


def _gen_module():
    spec = importlib.util.spec_from_file_location("proto_gen_script", GEN)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_generated_files_are_fresh():
    r = subprocess.run(
        [sys.executable, str(GEN), "--check"], capture_output=True, text=True, timeout=60
    )
    assert r.returncode == 0, r.stderr


def test_check_detects_a_stale_file(tmp_path):
    gen = _gen_module()
    out = gen.generate(gen.load())
    for rel, text in out.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    assert gen.main(["--check", "--out", str(tmp_path)]) == 0
    victim = tmp_path / "firmware/core/proto_msgs.h"
    text = victim.read_text()
    assert "#define PROTO_VERSION " in text
    victim.write_text(text.replace("#define PROTO_VERSION ", "#define PROTO_VERSION 9"))
    assert gen.main(["--check", "--out", str(tmp_path)]) == 1


BAD = [
    ("id = 0x02", "id = 0x01", "already used"),
    (
        'dir = "h2d"\nreply = "ack"\ndoc = "Enable',
        'dir = "x2y"\nreply = "ack"\ndoc = "Enable',
        "dir",
    ),
    (
        '{ name = "param", type = "u16", doc = "parameter id (per-axis: id + axis)" },\n]',
        '{ name = "param", type = "u17" },\n]',
        "unknown type",
    ),
    ("can_func = 4\n", "can_func = 5\n", "CAN function 5 already used"),
    ("max = 60000\ndefault = 1000", "max = 60000\ndefault = 70000", "default outside"),
]


@pytest.mark.parametrize("old,new,message", BAD)
def test_generator_rejects_broken_definitions(tmp_path, old, new, message, capsys):
    gen = _gen_module()
    text = (ROOT / "protocol" / "contour.toml").read_text()
    assert old in text
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace(old, new, 1))
    assert gen.main(["--spec", str(bad), "--check", "--out", str(tmp_path)]) == 1
    assert message in capsys.readouterr().err


def test_id_ranges_of_the_readme_are_respected():
    from contour import protocol_gen as pg

    for m in pg.MESSAGES:
        if m.dir == "h2d":
            assert (
                0x01 <= m.id <= 0x2F
                or 0x80 <= m.id <= 0x8F
                or 0xA0 <= m.id <= 0xAF
                or 0xC8 <= m.id <= 0xCC  # the 2-D map (README: 0xC0-0xCF)
                or 0xD0 <= m.id <= 0xD7
            ), m
        if m.can_func is not None:
            assert 0x30 <= m.id <= 0x3F, m
            assert m.max_len <= 8


def test_codec_round_trip_and_errors():
    from contour.link import codec

    m = codec.encode("queue_block", 7, block_seq=9, kind=0, feed=1000, target=[-1, 2, 3, 4])
    d = codec.decode(m)
    assert d.name == "queue_block" and d.seq == 7
    assert d.fields["target"] == [-1, 2, 3, 4]
    p = codec.encode("pos_1", 0, seq=65535, pos=-(2**47))
    assert codec.decode(p).fields["pos"] == -(2**47)
    with pytest.raises(codec.ProtocolError, match="does not fit"):
        codec.encode("pos_1", 0, pos=2**47)
    with pytest.raises(codec.ProtocolError, match="unknown field"):
        codec.encode("identify", 0, bogus=1)
    with pytest.raises(codec.ProtocolError, match="payload of 3 bytes"):
        codec.decode(bytes([0x42, 0, 1, 2, 3]))


def test_python_framing_survives_garbage_and_counts_errors():
    from contour.link import codec

    msgs = [codec.encode("param_set", i, param=1, value=-i) for i in range(20)]
    stream = b"\x13\x37garbage" + b"".join(codec.frame(m) for m in msgs)
    broken = bytearray(codec.frame(msgs[0]))
    broken[3] ^= 0x40
    dec = codec.FrameDecoder()
    out = dec.feed(bytes(broken) + stream)
    assert out == msgs
    assert dec.errors["crc"] + dec.errors["cobs"] >= 1


def _lib():
    from contour import native

    if not native.library_path().exists():
        pytest.skip("libcontour.so not built")
    return native.load()


def test_python_and_c_frames_are_identical():
    from contour.link import codec

    lib = _lib()
    out = ctypes.create_string_buffer(300)
    for n in (2, 3, 100, 252):
        for fill in (0, 0xFF, 0x5A):
            msg = bytes([fill]) * n
            k = lib.proto_frame_encode(msg, n, out, 300)
            assert out.raw[:k] == codec.frame(msg)


def test_c_message_table_matches_python():
    from contour import protocol_gen as pg

    lib = _lib()

    for m in pg.MESSAGES:
        info = lib.proto_msg_info(m.id).contents
        assert info.name.decode() == m.name
        assert (info.min_len, info.max_len) == (m.fixed_len, m.max_len)
        assert info.can_func == (m.can_func or 0)
    assert not lib.proto_msg_info(0xEE)


def test_dbc_decodes_cyclic_frames():
    cantools = pytest.importorskip("cantools")
    from contour import protocol_gen as pg
    from contour.link import codec

    db = cantools.database.load_file(str(ROOT / "protocol" / "contour.dbc"))
    frame = codec.encode_payload(pg.MSG_BY_NAME["pos_2"], {"seq": 513, "pos": -123456789012})
    msg = db.get_message_by_frame_id(pg.can_id(pg.CAN_FUNC["pos_2"], 1))
    assert msg.decode(frame) == {"seq": 513, "pos": -123456789012}
    frame = codec.encode_payload(
        pg.MSG_BY_NAME["status"],
        {"seq": 7, "state": 2, "enabled": 7, "faults": 1, "free_slots": 60},
    )
    dec = db.get_message_by_frame_id(pg.can_id(pg.CAN_FUNC["status"], 1)).decode(
        frame, decode_choices=False
    )
    assert dec["state"] == 2 and dec["free_slots"] == 60 and dec["seq"] == 7
