"""What the interpreter does with every G and M code: modal groups (for the
one-per-group rule of RS-274/NGC), the codes reported once per kind because
they change nothing for a drive, and the codes refused because they would
change the path, its timing or the machine state and are not implemented.

Codes are keyed as ``round(value * 10)`` (``G92.1`` -> 921, ``G700`` ->
7000) so that dotted codes compare exactly. docs/gcode.md is the prose
version of these tables; keep the two in step.
"""

from __future__ import annotations

# ---- G codes -----------------------------------------------------------------

# Modal groups as LinuxCNC numbers them (0 = non-modal). Sinumerik codes the
# reader keeps are put in the group of their LinuxCNC equivalent; their own
# groups (601-603 exact-stop window, 641-645 blending) get private numbers.
G_GROUP = {}
for _g, _grp in (
    ((40, 100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923), 0),
    ((0, 10, 20, 30, 50, 51, 52, 53, 330, 331, 382, 383, 384, 385, 730, 740, 760), 1),
    ((800, 810, 820, 830, 840, 850, 860, 870, 880, 890), 1),
    ((170, 180, 190, 171, 181, 191), 2),
    ((900, 910), 3),
    ((901, 911), 4),
    ((930, 940, 950), 5),
    ((200, 210, 700, 710, 7000, 7100), 6),
    ((400, 410, 420, 411, 421), 7),
    ((430, 431, 432, 490), 8),
    ((980, 990), 10),
    ((540, 550, 560, 570, 580, 590, 591, 592, 593), 12),
    ((600, 610, 611, 640, 6410, 6420, 6430, 6440, 6450), 13),
    ((960, 970), 14),
    ((70, 80), 15),
    ((90,), 100),  # G9 exact stop in this block (Fanuc/Sinumerik)
    ((6010, 6020, 6030), 101),  # Sinumerik exact-stop windows
    ((150, 160), 102),  # polar coordinates (Fanuc)
):
    for _c in _g:
        G_GROUP[_c] = _grp

# Group 0 codes that take axis words (only one axis user per line).
G_AXIS_USERS = {100, 280, 300, 520, 920}

# Reported once per kind: no effect on the path of a drive.
G_REPORTED = {
    940: "",  # feed per minute: the default, nothing to do
    970: "spindle RPM mode",
    960: "constant surface speed: spindle only",
    80: "",  # radius mode (lathe), the default
    6010: "",
    6020: "",
    6030: "",
}

# Refused: 'file:line: <feature> is not supported'.
G_REFUSED = {
    50: "G5 cubic spline",
    51: "G5.1 quadratic B-spline",
    52: "G5.2 NURBS",
    53: "G5.3 NURBS end",
    70: "G7 lathe diameter mode",
    150: "G15 polar coordinates",
    160: "G16 polar coordinates",
    171: "G17.1 UV plane",
    181: "G18.1 WU plane",
    191: "G19.1 VW plane",
    330: "G33 spindle-synchronized motion",
    331: "G33.1 rigid tapping",
    382: "G38.2 probing",
    383: "G38.3 probing",
    384: "G38.4 probing",
    385: "G38.5 probing",
    430: "G43 tool length offset",
    431: "G43.1 dynamic tool length offset",
    432: "G43.2 additional tool length offset",
    520: "G52 local coordinate offset",
    740: "G74 left-hand tapping cycle",
    760: "G76 threading cycle",
    840: "G84 tapping cycle",
    860: "G86 boring cycle",
    870: "G87 back boring cycle",
    880: "G88 boring cycle",
    930: "G93 inverse time feed",
    950: "G95 feed per revolution",
}

# ---- M codes -----------------------------------------------------------------

M_GROUP = {}
for _m, _grp in (
    ((0, 1, 2, 30, 60), 4),
    ((6, 61), 6),
    ((3, 4, 5), 7),
    ((7, 8, 9), 8),  # LinuxCNC 2.9's rs274 refuses M7 M8 on one line too
    ((48, 49, 50, 51, 52, 53), 9),
):
    for _c in _m:
        M_GROUP[_c] = _grp

M_NOTE = "machine function, not timed"
M_REPORTED = {
    0: "program stop: the wait is not timed",
    1: "optional stop: the wait is not timed",
    60: "pallet change stop: the wait is not timed",
    3: "spindle on (clockwise)",
    4: "spindle on (counter-clockwise)",
    5: "spindle stop",
    6: "tool change not timed",
    61: "set current tool number",
    7: "mist coolant",
    8: "flood coolant",
    9: "coolant off",
    19: "spindle orientation not timed",
    48: "overrides enabled",
    49: "overrides disabled",
    50: "feed override control",
    51: "spindle override control",
    52: "adaptive feed control",
    53: "feed stop control",
    62: "digital output",
    63: "digital output",
    64: "digital output",
    65: "digital output",
    67: "analog output",
    68: "analog output",
}
M_REFUSED = {
    66: "M66 wait on input",
    70: "M70 save modal state",
    71: "M71 invalidate saved modal state",
    72: "M72 restore modal state",
    73: "M73 save and auto-restore modal state",
}
# M100-M199: user programs that may do anything.
M_USER = range(100, 200)

# ---- other words ---------------------------------------------------------------

WORD_NOTES = {
    "S": "spindle speed",
    "T": "tool select",
    "D": "tool offset number",
    "H": "tool length offset number (G43 is refused)",
    "T=": "tool select by name",
}

# Sinumerik identifiers: what each one is; all are reported.
IDENT_NOTES = {
    "TRAORI": "5-axis transformation not modelled: X Y Z A B C read as machine axes",
    "TRAFOOF": "transformation off",
    "TRAF00F": "unknown word (TRAFOOF, transform off, written with zeros?)",
    "FNORM": "feed normal (the default)",
    "CYCLE800": "swivel cycle (orientation), not timed",
    "CYCLE832": "high-speed settings: read as continuous path (G64) until CYCLE832(); "
    "its tolerance and compressor are the profile's business",
}
IDENT_NOTE = "Sinumerik word not interpreted"


def code_key(value: float) -> int:
    """``G92.1`` -> 921; a code with more than one decimal gets -1 (unknown)."""
    k = round(value * 10)
    return k if abs(k - value * 10) < 1e-6 else -1


def code_name(letter: str, value: float) -> str:
    return letter + (str(int(value)) if value == int(value) else f"{value:g}")
