"""One signal order for every runnable observer: (t, z, u, y), with u and y by keyword in the public online calls.

Calls written for the previous order keep their meaning for one release, with a DeprecationWarning naming the new
form (never silently re-ordered): ``step(z, t, dt, u, y)`` (now ``step(t, z, dt, u, y)``), ``update(t, y, u)`` and
``run(t, y, u)`` (now ``update(t, u=..., y=...)`` and ``run(t, u=..., y=...)``).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..errors import ShapeError

__all__ = ["signals_by_keyword", "time_first", "delays_of"]


def signals_by_keyword(where: str, args: tuple[Any, ...], u: Any, y: Any) -> tuple[Any, Any]:
    """(u, y) of a call that takes them by keyword; positional `args` are the old order (y, u), with a warning."""
    if not args:
        return u, y
    if len(args) > 2 or (len(args) >= 1 and y is not None) or (len(args) == 2 and u is not None):
        raise TypeError(f"{where}: give the signals by keyword, {where.split('.')[-1]}(t, u=..., y=...)")
    warnings.warn(f"{where}(t, y, u) with positional signals is the old order; write {where.split('.')[-1]}(t, u=..., y=...) "
                  "(positional signals are refused from the next release)", DeprecationWarning, stacklevel=3)
    return (args[1] if len(args) == 2 else u), args[0]


def time_first(where: str, t: Any, z: Any) -> tuple[Any, Any]:
    """(t, z) of ``step(t, z, ...)``; an old call ``step(z, t, ...)`` (a state vector first, a number second) keeps its
    meaning with a warning. A number in both places is read in the new order only when z is an array."""
    if np.ndim(t) >= 1 and np.ndim(z) == 0:
        warnings.warn(f"{where}(z, t, dt, u, y) is the old order; write {where.split('.')[-1]}(t, z, dt, u, y)",
                      DeprecationWarning, stacklevel=3)
        return z, t
    return t, z


def delays_of(delay: Any, outputs: Sequence[str], caller: str, param: str = "delay") -> np.ndarray:
    """The known measurement delay of each of `outputs` in seconds (0 for those not named), checked: a mapping
    {output: seconds} of outputs of the model, each a finite number >= 0."""
    d = np.zeros(len(outputs))
    if delay is None:
        return d
    if not isinstance(delay, Mapping):
        raise ShapeError(f"{caller}: `{param}` must be a mapping {{output: seconds}}, got {type(delay).__name__}")
    outputs = list(outputs)
    for k, v in delay.items():
        if k not in outputs:
            raise ShapeError(f"{caller}: `{param}` names {k!r}, which is not an output; the outputs are {', '.join(outputs)}")
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not (np.isfinite(v) and v >= 0):
            raise ShapeError(f"{caller}: the delay of {k!r} must be a finite number of seconds >= 0, got {v!r}")
        d[outputs.index(k)] = float(v)
    return d
