"""One signal order for every runnable observer: (t, z, u, y), with u and y by keyword in the public online calls.

Calls written for the previous order keep their meaning for one release, with a DeprecationWarning naming the new
form (never silently re-ordered): ``step(z, t, dt, u, y)`` (now ``step(t, z, dt, u, y)``), ``update(t, y, u)`` and
``run(t, y, u)`` (now ``update(t, u=..., y=...)`` and ``run(t, u=..., y=...)``).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

__all__ = ["signals_by_keyword", "time_first"]


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
