"""Other controls' languages: what the reader takes and what it refuses
with a hint.

- Sinumerik words the reader has always taken (``TRAORI``, ``FNORM``,
  ``CYCLE832(...)``, ``$A_...``): passed on as identifiers; the interpreter
  decides (report or refuse).
- Sinumerik control flow (``GOTOF``, ``IF .. GOTO``, ``DEF``, ``PROC``,
  ``REPEAT .. P=``, labels ``NAME:``) and frames (``TRANS``, ``ROT`` ...,
  which move the path): refused, naming the construct.
- Heidenhain conversational (Klartext) programs (``BEGIN PGM``, ``L X+10 R0
  FMAX``, ``TOOL CALL``, ``CYCL DEF``): refused as a whole with a hint.
"""

from __future__ import annotations

import re

from contour.gcode.comments import balanced
from contour.gcode.expr import Malformed

_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)"
_SINU_VALUE = re.compile(r"(" + _NUM + r")|R(\d+)|(DC|ACP|ACN|AC|IC)\((" + _NUM + r")\)", re.ASCII)
_GAP = " \t\x01"


def _split(text: str) -> list:
    return text.split()


SINUMERIK_WORDS = frozenset(
    _split(
        """
    TRAORI TRAFOOF TRACYL TRANSMIT TRAANG TRACON TRAF00F FNORM FLIN FCUB FPRAON FPRAOF
    FFWON FFWOF SOFT BRISK DRIVE SOFTA BRISKA DRIVEA CFC CFTCP CFIN ORIWKS ORIMKS ORIAXES
    ORIVECT ORIEULER ORIRPY ORIPLANE ORICONCW ORICONCCW ORICONIO ORICONTO ORICURVE ORIPATH
    ORIPATHS ORIROTA ORIROTR ORIROTT ORIROTC OSOF OST OSC OSS OSSE UPATH SPATH COMPON
    COMPOF COMPCURV COMPCAD COMPSURF STOPRE CUT2D CUT2DF CUT3DC CUT3DFS CUT3DF
    CUT3DFF DIAMOF WAITM WAITS SBLOF SBLON DISPLOF DISPLON PTP CP PTPG0
    FGREF FGROUP G642 CPRECON CPRECOF FIFOCTRL
        """
    )
)

_CONTROL_FLOW = frozenset(
    _split(
        """
    IF ELSE ENDIF WHILE ENDWHILE FOR ENDFOR LOOP ENDLOOP REPEAT REPEATB UNTIL CASE DEF
    PROC RET EXTERN CALL PCALL MCALL SAVE DEFINE GOTO GOTOF GOTOB GOTOC GOTOS
        """
    )
)

_FRAMES = frozenset(
    _split(
        """
    TRANS ATRANS CTRANS ROT AROT ROTS AROTS CROT SCALE ASCALE CSCALE MIRROR AMIRROR
    CMIRROR TOFRAME TOROT TOFRAMEX TOFRAMEY TOFRAMEZ TOROTX TOROTY TOROTZ
        """
    )
)

# Words that change where the axes go in ways this reader does not model.
_PATH_WORDS = {
    "SUPA": "SUPA (machine coordinates, all offsets suppressed)",
    "DIAMON": "DIAMON (diameter programming)",
    "DIAM90": "DIAM90 (diameter programming)",
    "DIAMCYCOF": "DIAMCYCOF (diameter programming)",
}

_HEIDENHAIN = re.compile(
    r"^\s*(?:\d+\s+)?(?:BEGIN\s+PGM|END\s+PGM|BLK\s+FORM|TOOL\s+(?:CALL|DEF)|"
    r"CYCL\s+(?:DEF|CALL)|CALL\s+(?:LBL|PGM)|LBL\s+\S|FN\s*\d+\s*:|"
    r"(?:L|LN|LP|C|CC|CR|CT|CP|RND|CHF|APPR\s*\w*|DEP\s*\w*)\s+"
    r"(?:I?[XYZABC]\s*[+-]|PR\s*[+-]|PA\s*[+-]|R[LR0]\b|R\s*[+-]?\d|F\s*MAX\b)|"
    r"Q\d+\s*=)|\bFMAX\b",
    re.IGNORECASE,
)

# Heidenhain ISO: blocks end with '*', the program opens with %NAME G71 *.
_HEIDENHAIN_ISO = re.compile(r"^%\w+\s+G7[01]\b|\*\s*(?:;.*)?$", re.IGNORECASE)

HEIDENHAIN_ISO_HINT = (
    "Heidenhain ISO program (blocks end with '*'): this reader takes RS-274/NGC G-code "
    "(LinuxCNC dialect); output it from the CAM post-processor instead"
)

HEIDENHAIN_HINT = (
    "Heidenhain conversational (Klartext) program: this reader takes RS-274/NGC G-code "
    "(LinuxCNC dialect); output ISO/DIN G-code from the CAM post-processor instead"
)


def identifier(name: str, after: str):
    """Why the identifier ``name`` (followed by the character ``after``) is
    refused, or None."""
    if after == ":":
        return f"Sinumerik jump label '{name}:' is not supported (no GOTO in RS-274/NGC)"
    if name in _CONTROL_FLOW or name.startswith("GOTO"):
        shown = "GOTO" if name.startswith("GOTO") and name not in _CONTROL_FLOW else name
        return (
            f"Sinumerik/Fanuc control flow '{shown}' is not supported; the reader executes "
            "RS-274/NGC O-word control flow (O100 if/while/repeat/call)"
        )
    if name in _PATH_WORDS:
        return f"Sinumerik {_PATH_WORDS[name]} is not supported"
    if name in _FRAMES:
        return f"Sinumerik frame '{name}' (it shifts, rotates or scales the path) is not supported"
    return None


def hint(text: str):
    """A dialect hint for a line the reader could not read, or None."""
    if _HEIDENHAIN.search(text):
        return HEIDENHAIN_HINT
    if _HEIDENHAIN_ISO.search(text):
        return HEIDENHAIN_ISO_HINT
    return None


# ---- Sinumerik assignments ----------------------------------------------


def sinumerik_assign(s: str, c: str, j: int, words: list, params) -> int:
    """``X=value`` (Sinumerik): number, known R parameter or FUNC(number)."""
    end = value_end(s, j)
    text = s[j:end].strip(_GAP)
    if c == "R":
        raise Malformed(f"malformed R parameter assignment 'R={text}'")
    m = _SINU_VALUE.fullmatch(text)
    if m is None:
        words.append(("=" + c, (None, text)))
    elif m.group(1) is not None:
        words.append(("=" + c, (float(m.group(1)), None)))
    elif m.group(2) is not None:
        v = params.r.get(int(m.group(2)))
        words.append(("=" + c, (v, None) if v is not None else (None, text)))
    else:
        words.append(("=" + c, (float(m.group(4)), m.group(3))))
    return end


def r_assign(index: float, s: str, j: int, params, rep, lineno: int) -> int:
    """``R<n>=value``: a constant (or a known R) is remembered, anything
    else forgotten (and reported)."""
    end = value_end(s, j)
    text = s[j:end].strip(_GAP)
    if index != int(index) or index < 0:
        raise Malformed(f"malformed R parameter number 'R{index:g}'")
    m = _SINU_VALUE.fullmatch(text)
    v = None
    if m is not None and m.group(1) is not None:
        v = float(m.group(1))
    elif m is not None and m.group(2) is not None:
        v = params.r.get(int(m.group(2)))
    if v is None:
        params.r.pop(int(index), None)
        rep.skip("R= expression", lineno, "R parameter set from an expression: left unknown")
    else:
        params.r[int(index)] = v
    return end


def value_end(s: str, j: int) -> int:
    """End of a Sinumerik ``=`` value: the next blank outside ( ) and quotes."""
    n = len(s)
    j = _skip(s, j)
    while j < n and s[j] not in _GAP and s[j] != ";":
        if s[j] == "(":
            j = balanced(s, j)
            continue
        if s[j] == '"':
            k = s.find('"', j + 1)
            if k < 0:
                raise Malformed("unclosed string")
            j = k + 1
            continue
        j += 1
    return j


def _skip(s: str, i: int) -> int:
    n = len(s)
    while i < n and s[i] in _GAP:
        i += 1
    return i
