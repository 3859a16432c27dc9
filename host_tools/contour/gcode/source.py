"""Where the lines of a G-code program come from.

:class:`FileSource` streams the file: each raw line (``str`` or UTF-8
``bytes``) is checked (length cap, decoding, a byte order mark only at the
start) and stripped; blank lines and ``%`` tape marks are consumed here (the
program lies between the first two ``%`` lines when the first non-blank
line is ``%``). Lines are kept only while a loop that may run them again is
open (:meth:`FileSource.mark` / :meth:`FileSource.release`).
:class:`BodySource` serves a subroutine body. Both give ``(lineno, text)``.
"""

from __future__ import annotations

from contour.gcode.fastscan import SCAN
from contour.gcode.lexer import LINE_CAP


class FileSource:
    """The program file: streamed, with the lines of running loops kept."""

    def __init__(self, lines, rep):
        self.it = iter(lines)
        self.rep = rep
        self.lineno = 0
        self.buf = []
        self.base = 0  # stream index of buf[0]
        self.pos = 0  # stream index of the next line
        self.hold = 0  # running loops that need their lines again
        self.percent = 0  # 1: opened by a % line, 2: closed
        self.started = False

    def next(self):
        k = self.pos - self.base
        if k < len(self.buf):
            self.pos += 1
            return self.buf[k]
        if self.percent == 2:
            return None
        clean = self.clean
        for raw in self.it:
            if raw is SCAN:
                continue  # offered to the plain-line loop only (fastscan)
            self.lineno += 1
            text = clean(raw, self.lineno)
            if text is None:
                if self.percent == 2:
                    return None
                continue
            item = (self.lineno, text)
            self.pos += 1
            if self.hold:
                self.buf.append(item)
            else:
                if self.buf:
                    self.buf.clear()
                self.base = self.pos
            return item
        return None

    def clean(self, raw, lineno: int):
        """Stripped text of a raw line, or None for a line with nothing
        (blank, or a % tape mark)."""
        if (
            len(raw) > LINE_CAP
            and len(raw.rstrip(b"\r\n" if type(raw) is bytes else "\r\n")) > LINE_CAP
        ):
            raise self.rep.error(lineno, f"line longer than {LINE_CAP} characters")
        if type(raw) is not str:
            try:
                raw = raw.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise self.rep.error(
                    lineno,
                    f"not UTF-8 text (byte 0x{raw[exc.start]:02x} at column {exc.start + 1}); "
                    "a binary file?",
                ) from None
        text = raw.strip()
        if lineno == 1 and text.startswith("\ufeff"):
            text = text[1:].strip()
        if not text:
            return None
        f = self
        if text[0] == "%" and text[1:4].upper() == "_N_":
            # Sinumerik file header (%_N_PART_MPF): names the file.
            self.rep.skip("%_N_ (file header)", lineno, "Sinumerik file name line")
            self.started = True
            return None
        if text == "%":
            if not f.started:
                f.started = True
                f.percent = 1
            elif f.percent == 1:
                f.percent = 2
            else:
                self.rep.skip("%", lineno, "% line inside the program: ignored")
            return None
        f.started = True
        if not text.isascii():
            for k, c in enumerate(text):
                if c == "\ufffd" or "\ud800" <= c <= "\udfff":
                    raise self.rep.error(
                        lineno, f"undecodable byte at column {k + 1}; a binary file?"
                    )
                if c == "\ufeff":
                    raise self.rep.error(lineno, "byte order mark (U+FEFF) inside the file")
        return text

    def mark(self) -> int:
        if not self.hold and self.pos - self.base >= len(self.buf):
            self.buf.clear()
            self.base = self.pos
        self.hold += 1
        return self.pos

    def release(self) -> None:
        self.hold -= 1
        if not self.hold:
            del self.buf[: self.pos - self.base]
            self.base = self.pos

    def seek(self, pos: int) -> None:
        self.pos = pos


class BodySource:
    """A subroutine body (its lines, ``endsub`` last)."""

    def __init__(self, items):
        self.items = items
        self.pos = 0

    def next(self):
        if self.pos < len(self.items):
            self.pos += 1
            return self.items[self.pos - 1]
        return None

    def mark(self) -> int:
        return self.pos

    def release(self) -> None:
        pass

    def seek(self, pos: int) -> None:
        self.pos = pos
