"""Comments of a G-code line (RS-274/NGC as LinuxCNC reads them).

``( ... )`` comments may not nest and must close on their line; ``;``
comments the rest of the line; of several comments only the last is
*active*: ``(MSG,text)``, ``(DEBUG,text)`` and ``(PRINT,text)`` give a
message (the last two with ``#n``/``#<name>`` replaced by their values, in
LinuxCNC's ``%d``, ``%f``, ``%.Nf``, ``%lf`` formats), LinuxCNC's log and
probe-file comments are reported (no file is written), ``(ABORT,text)``
refuses the program. ``NAME(...)`` right after a Sinumerik identifier
(``CYCLE832(0.01,1)``) is its argument list, not a comment.
"""

from __future__ import annotations

import re

from contour.gcode.expr import Malformed
from contour.gcode.params import NUMBERED_MAX

_SPECIAL = re.compile(r"[(;]")
_FORMAT = re.compile(r"%(?:d|f|lf|\.(\d)f)")
_PARAM = re.compile(r"#\s*(?:<([^>]*)>|(\d+))", re.ASCII)

# O-word keywords: ``o100 sub(comment)`` has a comment, not arguments.
OKEYS = frozenset(
    (
        "SUB",
        "ENDSUB",
        "CALL",
        "RETURN",
        "IF",
        "ELSEIF",
        "ELSE",
        "ENDIF",
        "WHILE",
        "ENDWHILE",
        "DO",
        "REPEAT",
        "ENDREPEAT",
        "BREAK",
        "CONTINUE",
    )
)


def split(text: str):
    """Code (comments replaced by \\x01) and the comment texts of a line."""
    if "(" not in text and ";" not in text:
        return text, ()
    out = []
    comments = []
    i = 0
    n = len(text)
    while i < n:
        m = _SPECIAL.search(text, i)
        if m is None:
            out.append(text[i:])
            break
        j = m.start()
        out.append(text[i:j])
        if text[j] == ";":
            comments.append(text[j + 1 :])
            break
        ident = _ident_before(text, i, j)
        if ident is not None and ident.upper() not in OKEYS:
            k = balanced(text, j)  # Sinumerik NAME(...): arguments, not a comment
            out.append(text[j:k])
            i = k
            continue
        k = text.find(")", j + 1)
        if k < 0:
            raise Malformed("unclosed comment '(' (no ')' on the line)")
        body = text[j + 1 : k]
        if "(" in body:
            raise Malformed("'(' inside a comment (comments do not nest)")
        comments.append(body)
        out.append("\x01")
        i = k + 1
    return "".join(out), comments


def _ident_before(text: str, i: int, j: int):
    """The identifier (2+ letters, then letters/digits) ending at text[j], if
    any: ``CYCLE832`` in ``N10CYCLE832(``."""
    k = j
    while k > i and (text[k - 1].isalnum() or text[k - 1] in "_$") and text[k - 1].isascii():
        k -= 1
    for p in range(k, j - 1):
        a, b = text[p], text[p + 1]
        if (a.isalpha() or a in "_$") and (b.isalpha() or b in "_$"):
            return text[p:j]
    return None


def balanced(text: str, i: int) -> int:
    depth = 0
    quoted = False
    for k in range(i, len(text)):
        c = text[k]
        if c == '"':
            quoted = not quoted
        elif not quoted:
            if c == "(":
                depth += 1
            elif c == ")":
                depth -= 1
                if depth == 0:
                    return k + 1
    raise Malformed("unbalanced parentheses")


def active(body: str, messages: list, lineno: int, params, rep) -> None:
    """Act on the last comment of a line: messages, LinuxCNC log comments
    (reported, not written), ABORT (refused)."""
    head, comma, rest = body.partition(",")
    key = head.replace(" ", "").replace("\t", "").upper()
    if not comma:
        if key in ("LOGCLOSE", "PROBECLOSE") or key.startswith("PROBEOPEN"):
            rep.skip("(" + key + ")", lineno, "LinuxCNC log/probe file: not written")
        return
    if key == "MSG":
        messages.append(rest.strip())
    elif key in ("DEBUG", "PRINT"):
        messages.append(substitute(rest.strip(), params))
    elif key in ("LOG", "LOGOPEN", "LOGAPPEND"):
        rep.skip("(" + key + ",...)", lineno, "LinuxCNC log file: not written")
    elif key == "ABORT":
        raise Malformed(f"(ABORT) the program aborts here: {rest.strip()}")


def substitute(text: str, params) -> str:
    """``#n`` and ``#<name>`` in DEBUG/PRINT text, with LinuxCNC's
    ``%d``, ``%f``, ``%.Nf`` and ``%lf`` formats."""
    out = []
    fmt = 6
    i = 0
    n = len(text)
    while i < n:
        c = text[i]
        if c == "%":
            m = _FORMAT.match(text, i)
            if m is not None:
                g = m.group(0)
                fmt = 0 if g == "%d" else 4 if g == "%f" else 6 if g == "%lf" else int(m.group(1))
                i = m.end()
                continue
        if c == "#":
            m = _PARAM.match(text, i)
            if m is not None:
                if m.group(1) is not None:
                    key = m.group(1).replace(" ", "").replace("\t", "").lower()
                    ok = bool(key) and params.exists(key)
                    out.append(f"{params.get(key, 0):.{fmt}f}" if ok else "######")
                else:
                    k = int(m.group(2))
                    ok = 1 <= k <= NUMBERED_MAX
                    out.append(f"{params.get(k, 0):.{fmt}f}" if ok else "######")
                i = m.end()
                continue
        out.append(c)
        i += 1
    return "".join(out)
