"""Time budgets: a deadline per observer's run, kept by every place that runs one (compiler, compiled loops, VM).

``with time_budget(seconds, ...)`` sets a deadline for the code inside it (in this thread and context; nested budgets
keep the earlier deadline). The compiled C drivers poll a flag that a timer raises at the deadline
(:class:`Watchdog`), the virtual-machine paths call :func:`check_time` between their calls, and the compiler is given
the time that is left; each raises :class:`nlobs.TimeBudgetError`, which the callers keep with that observer (the
others keep their results). Used by ``nlobs design --run`` (``--budget``) for every candidate.
"""

from __future__ import annotations

import ctypes
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any

from ..errors import TimeBudgetError

__all__ = ["time_budget", "check_time", "expired", "remaining", "Watchdog", "observer_budget", "per_observer"]

#: (deadline on time.monotonic(), the budget in seconds) of the running code, or None.
_DEADLINE: ContextVar[tuple[float, float] | None] = ContextVar("nlobs_deadline", default=None)
#: Seconds each observer of a multi-observer run gets (``observer_budget``), or None.
_PER_OBSERVER: ContextVar[float | None] = ContextVar("nlobs_observer_budget", default=None)


@contextmanager
def time_budget(seconds: float | None) -> Iterator[None]:
    """A deadline `seconds` from now for the code inside (None: no new deadline)."""
    if seconds is None:
        yield
        return
    now = time.monotonic()
    outer = _DEADLINE.get()
    mine = (now + float(seconds), float(seconds))
    token = _DEADLINE.set(mine if outer is None or mine[0] < outer[0] else outer)
    try:
        yield
    finally:
        _DEADLINE.reset(token)


@contextmanager
def observer_budget(seconds: float | None) -> Iterator[None]:
    """Each observer run inside gets its own budget of `seconds` (see ``nlobs.simulate._isolate.each_observer``)."""
    token = _PER_OBSERVER.set(seconds)
    try:
        yield
    finally:
        _PER_OBSERVER.reset(token)


def per_observer() -> float | None:
    """The budget each observer gets here, or None."""
    return _PER_OBSERVER.get()


def remaining() -> float | None:
    """Seconds left before the deadline (None: no deadline)."""
    d = _DEADLINE.get()
    return None if d is None else d[0] - time.monotonic()


def expired(what: str) -> TimeBudgetError:
    """The budget error of the current deadline (for a caller that saw it run out, e.g. a compiler timeout)."""
    d = _DEADLINE.get()
    return TimeBudgetError(d[1] if d is not None else 0.0, what)


def check_time(what: str) -> None:
    """Raise :class:`nlobs.TimeBudgetError` when the deadline has passed."""
    d = _DEADLINE.get()
    if d is not None and time.monotonic() >= d[0]:
        raise TimeBudgetError(d[1], what)


class Watchdog:
    """A flag a compiled driver polls (``const volatile int*``), raised by a timer at the deadline.

    ``with Watchdog() as w: lib.driver(..., w.ref)``; then ``w.tripped`` tells whether it stopped the driver, and
    :meth:`raise_if_tripped` raises the budget error. Without a deadline ``ref`` is None (the driver never stops).
    """

    def __init__(self) -> None:
        self._flag = ctypes.c_int(0)
        self._timer: threading.Timer | None = None
        self._deadline = _DEADLINE.get()

    @property
    def ref(self) -> Any:
        return ctypes.byref(self._flag) if self._deadline is not None else None

    @property
    def tripped(self) -> bool:
        return bool(self._flag.value)

    def __enter__(self) -> Watchdog:
        if self._deadline is not None:
            left = self._deadline[0] - time.monotonic()
            if left <= 0:
                self._flag.value = 1
            else:
                self._timer = threading.Timer(left, self._trip)
                self._timer.daemon = True
                self._timer.start()
        return self

    def _trip(self) -> None:
        self._flag.value = 1

    def __exit__(self, *exc: Any) -> None:
        if self._timer is not None:
            self._timer.cancel()

    def raise_if_tripped(self, what: str) -> None:
        if self.tripped and self._deadline is not None:
            raise TimeBudgetError(self._deadline[1], what)
