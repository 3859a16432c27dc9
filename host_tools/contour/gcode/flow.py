"""O-word control flow and the line loop behind :func:`lexer.blocks`.

RS-274/NGC (LinuxCNC) O-words, numbered (``O100``) or named (``O<name>``)::

    O100 sub / endsub [v] / return [v] / call [a1] .. [a30]
    O101 if [c] / elseif [c] / else / endif
    O102 while [c] / endwhile       O103 do / O103 while [c]
    O104 repeat [n] / endrepeat     O102 break / continue

A subroutine must be defined (``sub`` .. ``endsub``, not nested) before it is
called; the call sets #1..#n to the arguments (#n+1..#30 keep the caller's
values), gives the subroutine fresh named locals and restores #1..#30 on
return; ``return``/``endsub [v]`` sets ``#<_value>`` and
``#<_value_returned>``. Calls nest at most :data:`MAX_CALL_DEPTH` deep (as
LinuxCNC) and at most :data:`ITERATION_CAP` loop passes and calls run in one
program, so ``while [1]`` ends with an error instead of hanging.

Memory: lines stream through; only the body of a running loop (from its
first line to the current one) and subroutine bodies are kept.
"""

from __future__ import annotations

import re

from contour.gcode.fastscan import SCAN, SCAN_WORDS
from contour.gcode.lexer import ENDS, LINE_CAP, PLAIN_LINE, Block, Tokenizer, plain_words
from contour.gcode.source import BodySource, FileSource

MAX_CALL_DEPTH = 10
ITERATION_CAP = 1_000_000
LINE_CACHE_SIZE = 4096
# A line with any of these may read or set state (parameters, R parameters,
# block delete and log reports, messages): it is parsed each time it runs.
_VARYING = re.compile(r"[#=/(;]")

_HEAD = re.compile(
    r"(?:/\s*)?(?:N\s*[\d.][\d.\s]*)?O\s*(<[^>]*>|\d[\d\s]*)\s*([A-Z]+)",
    re.IGNORECASE | re.ASCII,
)


def _head(text: str):
    """(label, KEYWORD) of an O-word line, without evaluating anything."""
    if "o" not in text and "O" not in text:
        return None
    m = _HEAD.match(text)
    if m is None:
        return None
    lab = m.group(1)
    if lab[0] == "<":
        lab = "<" + re.sub(r"\s", "", lab[1:-1]).lower() + ">"
    else:
        lab = str(int(re.sub(r"\s", "", lab)))
    return lab, m.group(2).upper()


def _o(label: str) -> str:
    return "O" + label


class _Frame:
    __slots__ = ("src", "label", "saved", "ctl", "line")

    def __init__(self, src, label, saved, line):
        self.src = src
        self.label = label
        self.saved = saved
        self.ctl = []  # [kind, label, line, body_pos, extra]
        self.line = line


class Runner:
    def __init__(self, lines, params, rep):
        self.params = params
        self.rep = rep
        self.tok = Tokenizer(params, rep)
        self.file = FileSource(lines, rep)
        self.frames = [_Frame(self.file, None, None, 0)]
        self.subs = {}
        self.iterations = 0
        self.plain_ended = False  # an M2 or M30 in a plain line
        self.lines = {}  # text -> Line, for lines that evaluate the same each time

    def error(self, line: int, message: str):
        return self.rep.error(line, message)

    def handle(self, lineno: int, text: str):
        """Evaluate one line; a Block to yield, or None."""
        words = plain_words(text)
        if words is not None:
            if ("M", 2.0) in words or ("M", 30.0) in words:
                self.plain_ended = True
            return Block(lineno, words)
        if len(self.frames) > 1 or self.file.hold:
            line = self.parse_again(text, lineno)
            if line.words and not line.assigns and not line.messages:
                return Block(lineno, list(line.words), (), line.call_args)
        else:
            line = self.tok.parse(text, lineno)
        if line.oword is not None:
            self.control(line.oword, lineno, text)
            return None
        if line.assigns:
            pset = self.params.set
            for key, v in line.assigns:
                pset(key, v, lineno)
        if line.words or line.messages:
            return Block(lineno, line.words, line.messages, line.call_args)
        return None

    def parse_again(self, text: str, lineno: int):
        """Parse a line that runs again (loop, subroutine); one that reads
        no parameter and sets nothing evaluates the same every time."""
        line = self.lines.get(text)
        if line is None:
            line = self.tok.parse(text, lineno)
            if not _VARYING.search(text):
                if len(self.lines) >= LINE_CACHE_SIZE:
                    self.lines.clear()
                self.lines[text] = line
        return line

    # ---- the loop ---------------------------------------------------------
    def run(self):
        f = self.file
        frames = self.frames
        plain = PLAIN_LINE.fullmatch
        clean = f.clean
        handle = self.handle
        while True:
            if f.started and len(frames) == 1 and not f.hold and f.pos - f.base >= len(f.buf):
                # Plain streaming: the hot path for CAM output (after the
                # first line, which may be a % tape mark).
                lineno = f.lineno
                for raw in f.it:
                    lineno += 1
                    if type(raw) is not str and raw.isascii():
                        raw = raw.decode("ascii")  # others: clean() decodes
                    if len(raw) <= LINE_CAP and type(raw) is str:
                        m = plain(raw)
                        if m is not None:
                            body = m[1]
                            words = [(t[0], float(t[1:])) for t in body.split()]
                            if "M" in body and (ENDS[0] in words or ENDS[1] in words):
                                self.plain_ended = True
                            yield Block(lineno, words)
                            continue
                    if raw is SCAN:
                        # C takes the plain lines that follow (fastscan).
                        blk = Block(lineno - 1, SCAN_WORDS)
                        yield blk
                        lineno = blk.line
                        continue
                    f.lineno = lineno
                    text = clean(raw, lineno)
                    if text is None:
                        if f.percent == 2:
                            break
                        continue
                    b = handle(lineno, text)
                    lineno = f.lineno  # control flow may have read ahead
                    if b is not None:
                        yield b
                    if len(frames) > 1 or f.hold or f.pos - f.base < len(f.buf):
                        break
                else:
                    f.lineno = lineno
                    self.finish()
                    return
                if f.percent == 2:
                    self.finish()
                    return
                continue
            fr = frames[-1]
            item = fr.src.next()
            if item is None:
                self.finish()
                return
            b = handle(item[0], item[1])
            if b is not None:
                yield b

    def finish(self):
        fr = self.frames[0]
        if fr.ctl:
            kind, label, line = fr.ctl[-1][:3]
            close = {"if": "endif", "while": "endwhile", "do": "while", "repeat": "endrepeat"}
            raise self.error(line, f"{_o(label)} {kind} without {close[kind]}")
        if self.file.percent == 1 and not (self.tok.ended or self.plain_ended):
            # LinuxCNC: a program that opens with % and has no M2/M30 must
            # close with %; without either, the file may have been cut short.
            raise self.error(
                self.file.lineno,
                "the program opens with a % line but has neither a closing % line nor M2/M30 "
                "(file cut short?)",
            )

    # ---- control flow -----------------------------------------------------
    def _count(self, line: int, what: str):
        self.iterations += 1
        if self.iterations > ITERATION_CAP:
            raise self.error(
                line,
                f"{what}: more than {ITERATION_CAP} loop passes and calls in this program "
                "(endless loop?)",
            )

    def _skip_to(self, fr, label: str, keys, line: int, what: str):
        """Read past lines until ``O<label> <key>``; returns (lineno, text, KEY)."""
        src = fr.src
        while True:
            item = src.next()
            if item is None:
                want = " or ".join(k.lower() for k in keys)
                raise self.error(line, f"{_o(label)} {what} without {want}")
            h = _head(item[1])
            if h is not None and h[0] == label and h[1] in keys:
                return item[0], item[1], h[1]

    def _top(self, fr, label: str, kinds, line: int, key: str):
        if not fr.ctl or fr.ctl[-1][1] != label or fr.ctl[-1][0] not in kinds:
            if fr.ctl and fr.ctl[-1][1] != label:
                k, lab, ln = fr.ctl[-1][:3]
                raise self.error(line, f"{_o(label)} {key} inside {_o(lab)} {k} (line {ln})")
            raise self.error(line, f"{_o(label)} {key} without {' or '.join(kinds)}")
        return fr.ctl[-1]

    def _end_loop(self, fr):
        fr.ctl.pop()
        fr.src.release()

    def control(self, oword, line: int, text: str):  # noqa: C901 - one dispatch
        label, key, values = oword
        fr = self.frames[-1]
        p = self.params
        if key == "SUB":
            self._define(fr, label, line)
        elif key == "CALL":
            body = self.subs.get(label)
            if body is None:
                raise self.error(
                    line,
                    f"{_o(label)} call: subroutine not defined before this line "
                    "(subroutines in other files are not searched)",
                )
            if len(self.frames) > MAX_CALL_DEPTH:
                raise self.error(
                    line,
                    f"{_o(label)} call: calls nested deeper than "
                    f"{MAX_CALL_DEPTH} (endless recursion?)",
                )
            self._count(line, f"{_o(label)} call")
            p.globals["_value"] = 0.0
            p.globals["_value_returned"] = 0.0
            saved = p.enter(values)
            self.frames.append(_Frame(BodySource(body), label, saved, line))
        elif key == "RETURN" or key == "ENDSUB":
            if fr.label is None:
                raise self.error(line, f"{_o(label)} {key.lower()} outside a subroutine")
            if label != fr.label:
                raise self.error(line, f"{_o(label)} {key.lower()} inside {_o(fr.label)}")
            p.globals["_value"] = values[0] if values else 0.0
            p.globals["_value_returned"] = 1.0 if values else 0.0
            p.leave(fr.saved)
            self.frames.pop()
        elif key == "IF":
            self._branch(fr, label, line, values[0] != 0.0)
        elif key == "ELSEIF" or key == "ELSE":
            self._top(fr, label, ("if",), line, key.lower())
            fr.ctl.pop()
            self._skip_to(fr, label, ("ENDIF",), line, key.lower())
        elif key == "ENDIF":
            self._top(fr, label, ("if",), line, "endif")
            fr.ctl.pop()
        elif key == "WHILE":
            top = fr.ctl[-1] if fr.ctl else None
            if top is not None and top[0] == "do" and top[1] == label:
                if values[0] != 0.0:
                    self._count(line, f"{_o(label)} do/while")
                    fr.src.seek(top[3])
                else:
                    self._end_loop(fr)
            elif values[0] != 0.0:
                # The condition is read again from this line at endwhile.
                fr.ctl.append(["while", label, line, fr.src.mark(), text])
            else:
                self._skip_to(fr, label, ("ENDWHILE",), line, "while")
        elif key == "ENDWHILE":
            top = self._top(fr, label, ("while",), line, "endwhile")
            if self._condition(top) != 0.0:
                self._count(top[2], f"{_o(label)} while")
                fr.src.seek(top[3])
            else:
                self._end_loop(fr)
        elif key == "DO":
            fr.ctl.append(["do", label, line, fr.src.mark(), None])
        elif key == "REPEAT":
            n = values[0]
            k = int(round(n))
            if abs(n - k) > 1e-4:
                raise self.error(line, f"{_o(label)} repeat count {n:g} is not an integer")
            if k > 0:
                fr.ctl.append(["repeat", label, line, fr.src.mark(), k - 1])
            else:
                self._skip_to(fr, label, ("ENDREPEAT",), line, "repeat")
        elif key == "ENDREPEAT":
            top = self._top(fr, label, ("repeat",), line, "endrepeat")
            if top[4] > 0:
                top[4] -= 1
                self._count(top[2], f"{_o(label)} repeat")
                fr.src.seek(top[3])
            else:
                self._end_loop(fr)
        else:  # BREAK, CONTINUE
            self._break(fr, label, key, line)

    def _define(self, fr, label: str, line: int):
        if fr.label is not None:
            raise self.error(
                line, f"{_o(label)} sub inside {_o(fr.label)}: subroutines do not nest"
            )
        body = []
        src = fr.src
        while True:
            item = src.next()
            if item is None:
                raise self.error(line, f"{_o(label)} sub without endsub")
            body.append(item)
            h = _head(item[1])
            if h is None:
                continue
            if h[1] == "SUB":
                raise self.error(
                    item[0], f"{_o(h[0])} sub inside {_o(label)}: subroutines do not nest"
                )
            if h[0] == label and h[1] == "ENDSUB":
                break
        self.subs[label] = body

    def _branch(self, fr, label: str, line: int, taken: bool):
        while not taken:
            ln, text, key = self._skip_to(fr, label, ("ELSEIF", "ELSE", "ENDIF"), line, "if")
            if key == "ENDIF":
                return
            if key == "ELSE":
                break
            oword = self.tok.parse(text, ln).oword
            taken = oword[2][0] != 0.0
        fr.ctl.append(["if", label, line, None, None])

    def _break(self, fr, label: str, key: str, line: int):
        for k in range(len(fr.ctl) - 1, -1, -1):
            rec = fr.ctl[k]
            if rec[1] == label and rec[0] in ("while", "do", "repeat"):
                break
        else:
            raise self.error(line, f"{_o(label)} {key.lower()} outside an O{label} loop")
        del fr.ctl[k + 1 :]
        close = {"while": "ENDWHILE", "do": "WHILE", "repeat": "ENDREPEAT"}[rec[0]]
        ln, text, _ = self._skip_to(fr, label, (close,), rec[2], rec[0])
        if key == "BREAK":
            self._end_loop(fr)
        else:
            self.control(self.tok.parse(text, ln).oword, ln, text)

    def _condition(self, rec) -> float:
        return self.parse_again(rec[4], rec[2]).oword[2][0]
