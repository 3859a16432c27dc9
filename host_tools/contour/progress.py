"""The one progress bar of the command line (flash, calibrate, run).

Drawn with tqdm on stderr, and only when stderr is a terminal: into a pipe
or a log file a bar is hundreds of redraws of noise, so there it draws
nothing at all (the command's summary line says what happened).

    with Bar(total=n, unit="B", desc="flash") as bar:
        bar.update(k)          # k more done
        bar.to(done, total)    # absolute position (total may change)
        bar.note("feed 1200")  # text after the bar
"""

from __future__ import annotations

import sys
import time
from typing import Optional, TextIO

MIN_REDRAW_S = 0.1  # `to` redraws at most this often


def is_terminal(stream: Optional[TextIO]) -> bool:
    try:
        return stream is not None and stream.isatty()
    except (AttributeError, ValueError):  # no isatty, or closed
        return False


class Bar:
    """A tqdm bar on a terminal, nothing otherwise (``active`` says which)."""

    def __init__(
        self,
        total: float = 0,
        unit: str = "it",
        desc: str = "",
        enabled: bool = True,
        file: Optional[TextIO] = None,
        **tqdm_kw,
    ) -> None:
        stream = sys.stderr if file is None else file
        self._bar = None
        self._drawn = 0.0
        if enabled and is_terminal(stream):
            from tqdm import tqdm

            self._bar = tqdm(total=total, unit=unit, desc=desc, file=stream, **tqdm_kw)

    @property
    def active(self) -> bool:
        return self._bar is not None

    def reset(self, total: float) -> None:
        if self._bar is not None:
            self._bar.reset(total=total)

    def update(self, n: float = 1) -> None:
        if self._bar is not None:
            self._bar.update(n)

    def to(self, n: float, total: Optional[float] = None) -> None:
        """Move to the absolute position `n` (and change the total)."""
        if self._bar is None:
            return
        if total is not None and self._bar.total != total:
            self._bar.total = total
        self._bar.n = n
        now = time.monotonic()
        if now - self._drawn >= MIN_REDRAW_S or n >= (self._bar.total or 0):
            self._drawn = now
            self._bar.refresh()

    def note(self, text: str) -> None:
        if self._bar is not None:
            self._bar.set_postfix_str(text, refresh=False)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Bar:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
