"""Errors raised by Python code that runs inside a CasADi graph (a ``casadi.Callback``).

CasADi turns an exception raised inside a Callback into a ``RuntimeError`` whose message wraps
the original one in several lines of CasADi context, after printing the Python traceback and
the callback's inputs on stderr. nlobs' callbacks therefore do not raise: they record the error
with :func:`defer_error`, return NaN (which stops any run), and every place that evaluates a
graph (the step runner, :func:`nlobs.engine.evaluate_many`, ``Observer``) calls
:func:`raise_deferred` right after the evaluation, which re-raises the recorded error with its
type and message intact.
"""

from __future__ import annotations

import threading

__all__ = ["defer_error", "raise_deferred", "clear_deferred"]

_LOCAL = threading.local()


def defer_error(exc: BaseException) -> None:
    """Record `exc` to be raised after the current evaluation (the first one recorded wins)."""
    if getattr(_LOCAL, "error", None) is None:
        _LOCAL.error = exc


def raise_deferred() -> None:
    """Raise (and forget) the error recorded by a callback during the last evaluation, if any."""
    exc = getattr(_LOCAL, "error", None)
    if exc is not None:
        _LOCAL.error = None
        raise exc


def clear_deferred() -> None:
    """Forget a recorded error (before an evaluation whose callbacks should start clean)."""
    _LOCAL.error = None
