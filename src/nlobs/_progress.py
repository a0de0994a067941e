"""Progress of long runs on stderr, drawn by tqdm (only when stderr is a terminal)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import TextIO

from tqdm import tqdm

__all__ = ["ProgressBar", "as_progress"]


class ProgressBar:
    """A tqdm bar fed with fractions in [0, 1]; closed (with its newline) when it reaches 1.

    When `stream` is not a terminal (a log file, a pipe, CI) nothing is drawn at all: tqdm's
    ``disable=None``. A bar left unfinished (a run that blew up) is closed by :meth:`close` or
    when the bar is garbage-collected, so the terminal line always ends.
    """

    def __init__(self, label: str, stream: TextIO | None = None):
        self._bar = tqdm(total=1000, desc=label, file=stream or sys.stderr, disable=None, leave=True, unit="‰",
                         bar_format="{desc} {bar} {percentage:3.0f}% {elapsed}<{remaining}", dynamic_ncols=True)
        self._done = 0

    def __call__(self, fraction: float) -> None:
        k = int(1000 * min(max(fraction, 0.0), 1.0))
        if k > self._done:
            self._bar.update(k - self._done)
            self._done = k
        if k >= 1000:
            self.close()

    def close(self) -> None:
        self._bar.close()


def as_progress(progress: bool | Callable[[float], None] | None, label: str) -> Callable[[float], None] | None:
    """None/False: no progress; True: a :class:`ProgressBar` on stderr; a callable: used as is."""
    if progress is None or progress is False:
        return None
    if progress is True:
        return ProgressBar(label)
    return progress
