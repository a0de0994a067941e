"""Old keyword names kept for one release (the vocabulary of ``docs/developers.rst``).

``@renamed(K="L")`` makes a function accept its old keyword ``K=`` with a DeprecationWarning that
names the new one; giving both is a TypeError. Used by the design functions (``design/_kind.py``
re-exports it) and by the analysis functions whose ``box`` became ``region``.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable
from typing import Any

__all__ = ["renamed", "warn_renamed"]


def warn_renamed(fn_name: str, old: str, new: str, where: str = "") -> None:
    """The DeprecationWarning of an old keyword `old` of `fn_name`, now `new` (shown at the user's call)."""
    warnings.warn(f"{where}{fn_name}: `{old}` is renamed `{new}`; the old name is accepted until the next release",
                  DeprecationWarning, stacklevel=4)


def renamed(**old_to_new: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Keep old keyword names of a function working for one release: ``@renamed(K="L")`` accepts ``K=``
    with a DeprecationWarning naming ``L`` (giving both is a TypeError). The old names are listed in the
    wrapper's ``_nlobs_renamed`` (old -> new)."""

    def wrap(fn: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(fn)
        def inner(*args: Any, **kwargs: Any) -> Any:
            for old, new in old_to_new.items():
                if old in kwargs:
                    if new in kwargs:
                        raise TypeError(f"{fn.__name__}: give `{new}` only (`{old}` is its old name)")
                    warn_renamed(fn.__name__, old, new)
                    kwargs[new] = kwargs.pop(old)
            return fn(*args, **kwargs)

        inner._nlobs_renamed = {**getattr(fn, "_nlobs_renamed", {}), **old_to_new}  # type: ignore[attr-defined]
        return inner

    return wrap
