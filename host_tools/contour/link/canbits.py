"""Bits a CAN 2.0A data frame takes on the wire, for bus-load figures and
the simulated bus of `sim serve` (protocol/README.md, "Throughput and bus capacity").

A frame is SOF, 11-bit id, RTR, IDE, r0, DLC (4), 8 x n data bits and the
15-bit CRC - 34 + 8n bits that are bit-stuffed (after five equal bits a
complementary one, which counts for the next run) - then the CRC delimiter,
ACK slot and delimiter, 7 bits of EOF and 3 of interframe space: 47 + 8n
bits before stuffing. Worst case one stuff bit per 4 bits after the first:
floor((34 + 8n - 1) / 4), 24 for n = 8 (135 bits).

A CAN 2.0B extended frame (our protocol's 29-bit ids, docs/canopen.md) has
after the 11-bit base id SRR and IDE (both recessive), the 18-bit id
extension, RTR, r1, r0: 54 + 8n stuffed bits, 67 + 8n before stuffing,
at most 160 bits for n = 8 (135 for a standard one).
"""

from __future__ import annotations

FIXED_BITS = 47  # 8n data bits come on top


def crc15(bits: list[int]) -> int:
    crc = 0
    for b in bits:
        nxt = b ^ ((crc >> 14) & 1)
        crc = (crc << 1) & 0x7FFF
        if nxt:
            crc ^= 0x4599
    return crc


EXT_EXTRA_BITS = 20  # SRR, IDE, 18-bit id extension, r1 in an extended frame


def frame_bits(cid: int, data: bytes, extended: bool = False) -> int:
    """Exact bits on the wire of one data frame, standard (11-bit `cid`) or
    extended (29-bit `cid`), interframe space included."""
    n = len(data)
    bits = [0]  # SOF
    if extended:
        bits += [(cid >> (28 - i)) & 1 for i in range(11)]
        bits += [1, 1]  # SRR, IDE
        bits += [(cid >> (17 - i)) & 1 for i in range(18)]
        bits += [0, 0, 0]  # RTR, r1, r0
    else:
        bits += [(cid >> (10 - i)) & 1 for i in range(11)]
        bits += [0, 0, 0]  # RTR, IDE, r0
    bits += [(n >> (3 - i)) & 1 for i in range(4)]
    for byte in data:
        bits += [(byte >> (7 - i)) & 1 for i in range(8)]
    c = crc15(bits)
    bits += [(c >> (14 - i)) & 1 for i in range(15)]
    stuff, run, last = 0, 0, None
    for b in bits:
        if b == last:
            run += 1
        else:
            run, last = 1, b
        if run == 5:
            stuff += 1
            run, last = 1, 1 - b  # the stuff bit starts the next run
    return FIXED_BITS + (EXT_EXTRA_BITS if extended else 0) + 8 * n + stuff


def worst_frame_bits(n: int, extended: bool = False) -> int:
    """Bits of a frame with n data bytes under worst-case stuffing."""
    s = 34 + (EXT_EXTRA_BITS if extended else 0) + 8 * n
    return FIXED_BITS + (EXT_EXTRA_BITS if extended else 0) + 8 * n + (s - 1) // 4
