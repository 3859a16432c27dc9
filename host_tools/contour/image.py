"""Firmware images: build (header + payload, Intel HEX) and parse/validate.

The format is specified in ``firmware/core/boot/image.h`` and
``docs/bootloader.md``: a 64-byte little-endian header (magic "CTFW", format
version 1, board id, firmware version, load address, payload length, CRC-32 of
the payload, 16-byte build id, header CRC-32) followed by the payload. In flash
the header sits ``HDR_AREA`` (512) bytes before ``load_addr``; the Intel HEX
file holds exactly what a validated slot contains (header, VALID marker,
payload), so a factory programmer can write it directly.

Command line (also ``contour image ...``)::

    python -m contour.image build app.elf --board 1 --version 1.2.3 -o app.img [--hex app.hex]
    python -m contour.image info app.img [--board 1 --load-addr 0x08010200]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import struct
import zlib
from dataclasses import asdict, dataclass
from pathlib import Path

from contour.errors import UsageError, UserError

MAGIC = 0x57465443  # b"CTFW" little-endian
FORMAT_VERSION = 1
HDR_SIZE = 64
HDR_AREA = 512
BUILD_ID_LEN = 16
MARK_VALID_OFF = 64
MARK_VALID = 0x444C4156  # b"VALD"
_HDR = struct.Struct("<IHHIIIII16s16sI")

BOARDS = {"sim": 1, "stm32f4": 2, "qemu": 3, "linux": 4}


class ImageError(UserError):
    """An image file that must not be flashed; the message says why."""


def crc32(data: bytes, crc: int = 0) -> int:
    """CRC-32 of firmware/core/crc.h (IEEE 802.3, same as zlib)."""
    return zlib.crc32(data, crc) & 0xFFFFFFFF


def version_str(v: int) -> str:
    return f"{(v >> 16) & 0xFFFF}.{(v >> 8) & 0xFF}.{v & 0xFF}"


def build_id_prefix(ident_build_id: int) -> str:
    """The `identify` reply's build_id as hex in the image's byte order.

    The drive reports the first 4 bytes of its image's build id as a
    little-endian u32 (firmware/ports/common/port_app.c); printed as that
    integer it would read byte-reversed. This gives the bytes in header order,
    the prefix of what `contour image info` prints and of the git commit
    `make firmware` puts there."""
    return (ident_build_id & 0xFFFFFFFF).to_bytes(4, "little").hex()


def parse_version(text: str) -> int:
    parts = text.split(".")
    try:
        nums = [int(p, 10) for p in parts]
    except ValueError:
        nums = []
    if len(nums) != 3 or not (0 <= nums[0] < 65536 and 0 <= nums[1] < 256 and 0 <= nums[2] < 256):
        raise UsageError(f"version {text!r}: expected MAJOR.MINOR.PATCH (0..65535.0..255.0..255)")
    return (nums[0] << 16) | (nums[1] << 8) | nums[2]


def parse_int(text: str, what: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise UsageError(f"{what} {text!r} is not a number") from None


def parse_board(text: str) -> int:
    if text.lower() in BOARDS:
        return BOARDS[text.lower()]
    return parse_int(text, "board id")


@dataclass
class Header:
    board_id: int
    fw_version: int
    load_addr: int
    length: int
    payload_crc: int
    build_id: bytes
    magic: int = MAGIC
    format_version: int = FORMAT_VERSION
    header_size: int = HDR_SIZE
    header_crc: int = 0

    def encode(self) -> bytes:
        body = _HDR.pack(
            self.magic,
            self.format_version,
            self.header_size,
            self.board_id,
            self.fw_version,
            self.load_addr,
            self.length,
            self.payload_crc,
            self.build_id.ljust(BUILD_ID_LEN, b"\0")[:BUILD_ID_LEN],
            bytes(16),
            0,
        )[:60]
        self.header_crc = crc32(body)
        return body + struct.pack("<I", self.header_crc)

    @property
    def slot_base(self) -> int:
        return self.load_addr - HDR_AREA

    def describe(self) -> dict:
        d = asdict(self)
        d["build_id"] = self.build_id.hex()
        d["version"] = version_str(self.fw_version)
        return d


@dataclass
class Image:
    header: Header
    payload: bytes

    def to_bytes(self) -> bytes:
        return self.header.encode() + self.payload

    def valid_marker(self) -> bytes:
        return struct.pack("<II", MARK_VALID, self.header.header_crc)

    def flash_records(self) -> list[tuple[int, bytes]]:
        """(address, bytes) of everything a validated slot holds."""
        hdr = self.header.encode()
        return [
            (self.header.slot_base, hdr),
            (self.header.slot_base + MARK_VALID_OFF, self.valid_marker()),
            (self.header.load_addr, self.payload),
        ]


def build(
    payload: bytes,
    *,
    board_id: int,
    fw_version: int,
    load_addr: int,
    build_id: bytes | None = None,
) -> Image:
    """Wrap a payload in a header (build id default: SHA-256 of the payload)."""
    if not payload:
        raise ImageError("payload is empty")
    if not 0 <= board_id <= 0xFFFF:
        raise ImageError(f"board id {board_id} out of range 0..65535")
    if load_addr < HDR_AREA or load_addr + len(payload) > 1 << 32:
        raise ImageError(f"load address 0x{load_addr:08X} leaves no room for the header")
    if build_id is None:
        build_id = hashlib.sha256(payload).digest()[:BUILD_ID_LEN]
    if len(build_id) > BUILD_ID_LEN:
        raise ImageError(f"build id longer than {BUILD_ID_LEN} bytes")
    hdr = Header(board_id, fw_version, load_addr, len(payload), crc32(payload), build_id)
    hdr.encode()
    return Image(hdr, bytes(payload))


def parse_header(raw: bytes) -> Header:
    """Decode and check 64 header bytes (magic, version, header CRC, reserved)."""
    if len(raw) < HDR_SIZE:
        raise ImageError(f"truncated image: {len(raw)} bytes, a header alone is {HDR_SIZE}")
    f = _HDR.unpack(raw[:HDR_SIZE])
    magic, fmt, hsize, board, ver, load, length, pcrc, bid, reserved, hcrc = f
    if magic != MAGIC:
        raise ImageError(f"not a contour firmware image (magic 0x{magic:08X})")
    if fmt != FORMAT_VERSION or hsize != HDR_SIZE:
        raise ImageError(f"unknown image format version {fmt} (header size {hsize})")
    if crc32(raw[:60]) != hcrc:
        raise ImageError("image header CRC mismatch: the header is corrupted")
    if any(reserved):
        raise ImageError("image header reserved bytes are not zero")
    return Header(board, ver, load, length, pcrc, bid, magic, fmt, hsize, hcrc)


def parse(data: bytes) -> Image:
    """Parse and validate a whole image file (header + payload)."""
    hdr = parse_header(data)
    payload = data[HDR_SIZE:]
    if len(payload) < hdr.length:
        raise ImageError(
            f"truncated image: header announces {hdr.length} payload bytes, file has {len(payload)}"
        )
    if len(payload) > hdr.length:
        raise ImageError(
            f"image has {len(payload) - hdr.length} bytes after the {hdr.length}-byte payload"
        )
    if hdr.length == 0:
        raise ImageError("image payload is empty")
    crc = crc32(payload)
    if crc != hdr.payload_crc:
        raise ImageError(
            f"image payload CRC mismatch: header says 0x{hdr.payload_crc:08X}, "
            f"payload has 0x{crc:08X} (corrupted file)"
        )
    return Image(hdr, payload)


def load(path: str | Path) -> Image:
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise UserError(f"{p}: {exc.strerror}") from None
    try:
        return parse(data)
    except ImageError as exc:
        raise ImageError(f"{p}: {exc}") from None


def check_target(hdr: Header, *, board_id: int, load_addr: int, max_length: int) -> None:
    """Refuse an image that does not fit the connected drive (specific message)."""
    if hdr.board_id != board_id:
        raise ImageError(
            f"image is for board {hdr.board_id}, the drive is board {board_id}: refusing to flash"
        )
    if hdr.load_addr != load_addr:
        raise ImageError(
            f"image is linked for load address 0x{hdr.load_addr:08X}, the drive's application "
            f"starts at 0x{load_addr:08X}: refusing to flash"
        )
    if hdr.length > max_length:
        raise ImageError(
            f"image payload is {hdr.length} bytes, the drive's application slot holds "
            f"{max_length}: refusing to flash"
        )


# ---- inputs: ELF or raw binary ----------------------------------------------


def elf_payload(data: bytes) -> tuple[int, bytes]:
    """(load address, bytes) of an ELF32 little-endian executable, as
    `objcopy -O binary` makes it: every allocated section with contents, at
    its load address (LMA, from the PT_LOAD segment holding it); gaps are
    filled with 0xFF (erased flash)."""
    if data[:4] != b"\x7fELF":
        raise UserError("not an ELF file")
    if data[4] != 1 or data[5] != 1:
        raise UserError("only 32-bit little-endian ELF files are supported")
    try:
        (e_phoff, e_shoff) = struct.unpack_from("<II", data, 28)
        e_phentsize, e_phnum, e_shentsize, e_shnum = struct.unpack_from("<HHHH", data, 42)
        segs = []
        for i in range(e_phnum):
            p_type, p_offset, _va, p_paddr, p_filesz = struct.unpack_from(
                "<5I", data, e_phoff + i * e_phentsize
            )
            if p_type == 1:
                segs.append((p_offset, p_filesz, p_paddr))
        parts = []
        for i in range(e_shnum):
            _name, sh_type, sh_flags, sh_addr, sh_offset, sh_size = struct.unpack_from(
                "<6I", data, e_shoff + i * e_shentsize
            )
            if not sh_flags & 0x2 or sh_type == 8 or sh_size == 0:  # SHF_ALLOC, not NOBITS
                continue
            lma = sh_addr
            for off, size, paddr in segs:
                if off <= sh_offset < off + size:
                    lma = paddr + sh_offset - off
            if sh_offset + sh_size > len(data):
                raise UserError("truncated ELF section")
            parts.append((lma, data[sh_offset : sh_offset + sh_size]))
    except struct.error:
        raise UserError("truncated ELF headers") from None
    if not parts:
        raise UserError("ELF file has no loadable bytes")
    parts.sort()
    base = parts[0][0]
    end = max(a + len(b) for a, b in parts)
    if end - base > 16 << 20:
        raise UserError(f"ELF sections span {end - base} bytes: not one flash image")
    out = bytearray(b"\xff" * (end - base))
    for a, b in parts:
        out[a - base : a - base + len(b)] = b
    return base, bytes(out)


# ---- Intel HEX ----------------------------------------------------------------


def _hex_record(rtype: int, addr: int, data: bytes) -> str:
    body = bytes([len(data), (addr >> 8) & 0xFF, addr & 0xFF, rtype]) + data
    return ":" + body.hex().upper() + f"{(-sum(body)) & 0xFF:02X}"


def to_hex(records: list[tuple[int, bytes]]) -> str:
    """Intel HEX (16-byte data records, extended linear addresses, EOF)."""
    lines = []
    upper = None
    for base, blob in records:
        pos = 0
        while pos < len(blob):
            addr = base + pos
            n = min(16, len(blob) - pos, 0x10000 - (addr & 0xFFFF))
            if addr >> 16 != upper:
                upper = addr >> 16
                lines.append(_hex_record(4, 0, struct.pack(">H", upper)))
            lines.append(_hex_record(0, addr & 0xFFFF, blob[pos : pos + n]))
            pos += n
    lines.append(_hex_record(1, 0, b""))
    return "\n".join(lines) + "\n"


def from_hex(text: str) -> dict[int, int]:
    """Address -> byte of an Intel HEX file (checksums verified)."""
    mem: dict[int, int] = {}
    upper = 0
    for n, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line:
            continue
        if not line.startswith(":"):
            raise UserError(f"HEX line {n}: no ':'")
        raw = bytes.fromhex(line[1:])
        if len(raw) < 5 or len(raw) != raw[0] + 5 or sum(raw) & 0xFF:
            raise UserError(f"HEX line {n}: bad length or checksum")
        addr, rtype, data = (raw[1] << 8) | raw[2], raw[3], raw[4 : 4 + raw[0]]
        if rtype == 0:
            for i, b in enumerate(data):
                mem[(upper << 16) + addr + i] = b
        elif rtype == 4:
            upper = (data[0] << 8) | data[1]
        elif rtype == 1:
            break
    return mem


# ---- command line -------------------------------------------------------------


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and a.samefile(b))
    except OSError:
        return False


def build_outputs(
    src: Path, output: str | None, hex_name: str | None, elf: bool
) -> tuple[Path, Path | None, Path]:
    """The files `image build` writes: the image (.img), from an ELF the raw
    payload (.bin) and the Intel HEX file (.hex). Refused (UsageError, before
    anything is written): a name whose extension is not what is written
    there, and any output that is the input or another output."""
    out = Path(output) if output else src.with_suffix(".img")
    if out.suffix.lower() != ".img":
        raise UsageError(
            f"-o {out}: the image is written with extension .img "
            "(the raw payload goes to .bin, Intel HEX to .hex beside it)"
        )
    hex_out = Path(hex_name) if hex_name else out.with_suffix(".hex")
    if hex_out.suffix.lower() != ".hex":
        raise UsageError(f"--hex {hex_out}: Intel HEX is written with extension .hex")
    bin_out = out.with_suffix(".bin") if elf else None
    named = [("image", out), ("Intel HEX", hex_out)]
    if bin_out is not None:
        named.append(("raw payload", bin_out))
    for what, path in named:
        if _same_file(path, src):
            raise UsageError(f"{path}: is the input file; the {what} would overwrite it (use -o)")
    for i, (what, path) in enumerate(named):
        for what2, path2 in named[i + 1 :]:
            if _same_file(path, path2):
                raise UsageError(f"{path}: both the {what} and the {what2} would be written there")
    return out, bin_out, hex_out


def cmd_build(args: argparse.Namespace) -> int:
    src = Path(args.input)
    try:
        data = src.read_bytes()
    except OSError as exc:
        raise UserError(f"{src}: {exc.strerror}") from None
    if data[:4] == b"\x7fELF":
        load_addr, payload = elf_payload(data)
        if args.load_addr is not None and parse_int(args.load_addr, "load address") != load_addr:
            raise UsageError(
                f"{src}: linked at 0x{load_addr:08X}, not at the requested {args.load_addr}"
            )
    else:
        if args.load_addr is None:
            raise UsageError(f"{src}: a raw binary needs --load-addr")
        load_addr, payload = parse_int(args.load_addr, "load address"), data
    build_id = None
    if args.build_id:
        try:
            build_id = bytes.fromhex(args.build_id)[:BUILD_ID_LEN]
        except ValueError:
            raise UsageError(f"build id {args.build_id!r} is not hexadecimal") from None
    img = build(
        payload,
        board_id=parse_board(args.board),
        fw_version=parse_version(args.version),
        load_addr=load_addr,
        build_id=build_id,
    )
    out, bin_out, hex_out = build_outputs(src, args.output, args.hex, data[:4] == b"\x7fELF")
    out.write_bytes(img.to_bytes())
    if bin_out is not None:
        bin_out.write_bytes(img.payload)  # the raw payload, as objcopy -O binary
    hex_out.write_text(to_hex(img.flash_records()))
    if getattr(args, "json", False):
        files = {"image": str(out), "hex": str(hex_out), "bin": str(bin_out) if bin_out else None}
        print(json.dumps({**files, "header": img.header.describe()}, indent=2))
        return 0
    print(
        f"{out}: {img.header.length} bytes at 0x{img.header.load_addr:08X}, board "
        f"{img.header.board_id}, version {version_str(img.header.fw_version)}, "
        f"crc 0x{img.header.payload_crc:08X}; {hex_out}"
    )
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    img = load(args.image)
    if args.board is not None or args.load_addr is not None:
        check_target(
            img.header,
            board_id=parse_board(args.board) if args.board is not None else img.header.board_id,
            load_addr=parse_int(args.load_addr, "load address")
            if args.load_addr is not None
            else img.header.load_addr,
            max_length=args.max_length if args.max_length is not None else img.header.length,
        )
    d = img.header.describe()
    if args.json:
        print(json.dumps(d, indent=2))
    else:
        for k in ("version", "board_id", "load_addr", "length", "payload_crc", "build_id"):
            v = d[k]
            print(f"{k}: {hex(v) if isinstance(v, int) and k != 'length' else v}")
    return 0


def add_parsers(sub) -> None:
    b = sub.add_parser("build", help="build an image (.img and .hex) from an ELF or raw binary")
    b.add_argument("input", help="ELF (load address from its segments) or raw .bin")
    b.add_argument("--board", required=True, help="board id (number, or sim/stm32f4/qemu/linux)")
    b.add_argument("--version", required=True, help="firmware version MAJOR.MINOR.PATCH")
    b.add_argument("--load-addr", help="payload flash address (required for a raw binary)")
    b.add_argument("--build-id", help="build id as hex (default: SHA-256 of the payload)")
    b.add_argument(
        "-o",
        "--output",
        help="image file, .img (default: INPUT with .img; from an ELF also the payload as .bin)",
    )
    b.add_argument("--hex", help="Intel HEX file, .hex (default: OUTPUT with .hex)")
    b.add_argument("--json", action="store_true", help="print the files and the header as JSON")
    b.set_defaults(func=cmd_build)
    i = sub.add_parser("info", help="validate an image and print its header")
    i.add_argument("image")
    i.add_argument("--board", help="also check against this board id")
    i.add_argument("--load-addr", help="also check against this load address")
    i.add_argument("--max-length", type=int, help="also check against this slot capacity")
    i.add_argument("--json", action="store_true")
    i.set_defaults(func=cmd_info)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m contour.image", description=__doc__.splitlines()[0]
    )
    add_parsers(ap.add_subparsers(dest="cmd", required=True))
    args = ap.parse_args(argv)
    try:
        return args.func(args)
    except (UserError, OSError) as exc:
        from contour.cli import report_error  # the exit codes of `contour image`

        return report_error(exc, as_json=False)


if __name__ == "__main__":
    raise SystemExit(main())
