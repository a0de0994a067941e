"""A minimal progress line on stderr for long runs (no dependency needed for one line of text)."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TextIO

__all__ = ["ProgressLine", "as_progress"]


class ProgressLine:
    """``label [#####.....]  42%  1.2 s``, redrawn in place; finished with a newline."""

    def __init__(self, label: str, stream: TextIO | None = None, width: int = 30):
        self.label = label
        self.stream = stream or sys.stderr
        self.width = width
        self.t0 = time.perf_counter()
        self._last = -1

    def __call__(self, fraction: float) -> None:
        pct = int(100 * min(max(fraction, 0.0), 1.0))
        if pct == self._last:
            return
        self._last = pct
        filled = self.width * pct // 100
        bar = "#" * filled + "." * (self.width - filled)
        end = "\n" if pct >= 100 else ""
        self.stream.write(f"\r{self.label} [{bar}] {pct:3d}%  {time.perf_counter() - self.t0:.1f} s{end}")
        self.stream.flush()


def as_progress(progress: bool | Callable[[float], None] | None, label: str) -> Callable[[float], None] | None:
    """None/False: no progress; True: a :class:`ProgressLine`; a callable: used as is."""
    if progress is None or progress is False:
        return None
    if progress is True:
        return ProgressLine(label)
    return progress
