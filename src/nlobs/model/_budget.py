"""Budgets for symbolic work on user expressions: size (before the work starts) and time.

SymPy does unbounded work on some inputs: expanding ``(x1 + x2 + u + mu + t)**64`` makes ~10⁶
terms, and a chain of definitions that reuse each other makes a tree exponentially larger than
its text. Three limits keep every symbolic step of nlobs finite, each with its own error,
:class:`~nlobs.errors.SymbolicBudgetError`, that names the step and the expression:

- :func:`check_tree`: the size of an expression *as a tree* (shared sub-expressions counted
  every time they occur; SymPy's substitution and printing walk that tree), checked when a
  :class:`~nlobs.System` is built;
- :func:`expand`: ``sympy.expand`` after an upper bound of the number of terms it would make;
- :func:`symbolic_budget`: a time budget for a whole step (an analysis, a design). Only the time
  spent inside SymPy counts (sampled every 50 ms): numeric work in the same step is free. It
  needs ``SIGALRM``, so it applies in the main thread of a POSIX process; elsewhere only the
  size limits apply.
"""

from __future__ import annotations

import math
import os
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass
from typing import Any

import sympy as sp

from ..errors import SymbolicBudgetError
from .._text import shorten

__all__ = ["MAX_TREE", "MAX_TERMS", "symbolic_seconds", "tree_size", "expanded_terms", "check_tree", "expand",
           "symbolic_budget", "symbolic_time_limit", "SymbolicTimeLimit", "short_str"]

MAX_TREE = 200_000  #: largest expression, in tree nodes (shared sub-expressions counted each time)
MAX_TERMS = 20_000  #: largest number of terms an expansion may make
_TICK = 0.05  #: sampling period of the time budget, in seconds


def symbolic_seconds() -> float:
    """The time budget of one symbolic step: ``NLOBS_SYMBOLIC_SECONDS`` (default 30 s)."""
    try:
        value = float(os.environ.get("NLOBS_SYMBOLIC_SECONDS", "30"))
    except ValueError:
        return 30.0
    return value if math.isfinite(value) and value > 0 else 30.0


def tree_size(expr: sp.Basic, cap: int = MAX_TREE) -> int:
    """Number of nodes of `expr` as a tree (a shared sub-expression counts each time), up to `cap` + 1.

    Computed on the DAG (each distinct node once), so it is fast even when the tree is huge.
    """
    memo: dict[sp.Basic, int] = {}
    stack: list[tuple[sp.Basic, bool]] = [(expr, False)]
    while stack:
        node, ready = stack.pop()
        if node in memo:
            continue
        if not node.args:
            memo[node] = 1
            continue
        if ready:
            memo[node] = min(cap + 1, 1 + sum(memo[a] for a in node.args))
            continue
        stack.append((node, True))
        stack.extend((a, False) for a in node.args if a not in memo)
    return memo[expr]


def expanded_terms(expr: sp.Basic, cap: int = MAX_TERMS) -> int:
    """An upper bound of the number of terms ``sympy.expand(expr)`` makes, or of any expansion it
    does inside (in function arguments, denominators), whichever is larger; capped at `cap` + 1.

    A power of a sum of k terms to the n makes at most C(n + k − 1, k − 1) terms (the monomials of
    degree n in k variables); a product multiplies the counts; a sum adds them.
    """
    memo: dict[sp.Basic, int] = {}
    worst = 1

    def terms(e: sp.Basic) -> int:
        nonlocal worst
        if e in memo:
            return memo[e]
        if not e.args:
            out = 1
        elif e.is_Add:
            out = sum(terms(a) for a in e.args)
        elif e.is_Mul:
            out = 1
            for a in e.args:
                out = min(cap + 1, out * terms(a))
        elif e.is_Pow and e.args[1].is_Integer:
            k, n = terms(e.args[0]), abs(int(e.args[1]))
            full = math.comb(n + k - 1, k - 1) if k > 1 else 1
            if e.args[1] > 0:
                out = full
            else:  # expand() expands the denominator too; the power itself stays one term
                worst = max(worst, min(cap + 1, full))
                out = 1
        else:  # a function or a symbolic power: one term, its arguments expanded separately
            for a in e.args:
                worst = max(worst, terms(a))
            out = 1
        out = min(cap + 1, out)
        memo[e] = out
        worst = max(worst, out)
        return out

    terms(expr)
    return min(cap + 1, worst)


def short_str(expr: Any, limit: int = 60) -> str:
    """A short text of an expression for a message, without printing a huge tree in full."""
    if isinstance(expr, sp.Basic):
        size = tree_size(expr, 2000)
        if size > 2000:
            return f"<a {type(expr).__name__} of more than 2000 nodes>"
    return shorten(str(expr), limit)


def check_tree(expr: sp.Basic, where: str) -> sp.Basic:
    """`expr` if its tree has at most :data:`MAX_TREE` nodes, else a SymbolicBudgetError naming `where`."""
    if isinstance(expr, sp.Basic) and tree_size(expr) > MAX_TREE:
        raise SymbolicBudgetError(
            f"{where}: the expression has more than {MAX_TREE} nodes once its definitions are substituted "
            f"({short_str(expr)}); nlobs's symbolic steps walk that tree. Reuse fewer nested definitions "
            "or simplify the model")
    return expr


def expand(expr: sp.Basic, *, what: str, **hints: Any) -> sp.Basic:
    """``sympy.expand(expr, **hints)`` within the size and time budgets.

    Raises
    ------
    SymbolicBudgetError
        If the expansion would make more than :data:`MAX_TERMS` terms, or takes too long.
    """
    n = expanded_terms(expr)
    if n > MAX_TERMS:
        raise SymbolicBudgetError(
            f"{what}: expanding {short_str(expr)} would make more than {MAX_TERMS} terms (bound {n:,}); "
            "this step needs the expanded form. Rewrite the expression with a lower power of a sum, or use an "
            "observer kind that does not need the symbolic form (ekf, ukf, mhe)")
    with symbolic_budget(what):
        return sp.expand(expr, **hints)


_ACTIVE = threading.local()


def _inside_sympy(frame: Any) -> bool:
    for _ in range(400):
        if frame is None:
            return False
        name = frame.f_globals.get("__name__", "")
        if name.startswith(("sympy.", "mpmath.")):
            return True
        frame = frame.f_back
    return False


class SymbolicTimeLimit(Exception):
    """An optional piece of symbolic work (see :func:`symbolic_time_limit`) ran out of its time."""


@dataclass
class _Limit:
    limit: float
    error: Callable[[], Exception]
    spent: float = 0.0


@contextmanager
def _limited(entry: _Limit) -> Iterator[None]:
    """Run the block with `entry`'s limit on the time spent inside SymPy (sampled every 50 ms).

    Limits nest: an inner one shares the outer's timer, every open limit is charged, and the
    outermost exceeded limit raises (so an inner, optional step never swallows the outer budget).
    An exceeded limit raises again at every tick spent inside SymPy until its block is left, and once
    more when the block ends normally: code that swallows the error cannot finish the step as if the
    budget had held.
    """
    stack = getattr(_ACTIVE, "stack", None)
    if stack is not None:
        stack.append(entry)
        try:
            yield
        finally:
            stack.remove(entry)
        if entry.spent > entry.limit:   # exceeded, and the error was swallowed inside: raise it on leaving
            raise entry.error()
        return
    usable = (hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
              and signal.getsignal(signal.SIGALRM) in (signal.SIG_DFL, signal.SIG_IGN, None)
              and signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0))
    if not usable:
        yield
        return
    stack = [entry]

    def handler(signum: int, frame: Any) -> None:
        if not _inside_sympy(frame):
            return
        if frame is not None and frame.f_code.co_filename.endswith(("weakref.py", "_weakrefset.py")):
            return   # inside a weakref callback the garbage collector runs: an error there is only printed; next tick
        for e in stack:
            e.spent += _TICK
        for e in stack:
            if e.spent > e.limit:   # raised again at every tick: a broad `except` cannot swallow the budget
                raise e.error()

    previous = signal.signal(signal.SIGALRM, handler)
    _ACTIVE.stack = stack
    signal.setitimer(signal.ITIMER_REAL, _TICK, _TICK)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        _ACTIVE.stack = None
    if entry.spent > entry.limit:
        raise entry.error()


def symbolic_budget(what: str, seconds: float | None = None) -> AbstractContextManager[None]:
    """Stop the step `what` with a SymbolicBudgetError once it has spent `seconds` inside SymPy.

    Nested budgets are charged together with the outer ones; the outermost exceeded one raises.
    Without ``SIGALRM`` (Windows), outside the main thread, or when the process already uses the
    real-time timer, the step runs unbudgeted.
    """
    limit = symbolic_seconds() if seconds is None else float(seconds)

    def error() -> Exception:
        return SymbolicBudgetError(
            f"{what}: the symbolic work (SymPy) took more than {limit:g} s, the budget of one step; the model's "
            "expressions are too large for it. Simplify them, use an observer kind that works numerically "
            "(ekf, ukf, mhe), or raise the budget with the environment variable NLOBS_SYMBOLIC_SECONDS")

    return _limited(_Limit(limit, error))


def symbolic_time_limit(seconds: float) -> AbstractContextManager[None]:
    """Raise :class:`SymbolicTimeLimit` once the block has spent `seconds` inside SymPy: for optional
    work (an attempt to simplify) whose caller has an answer without it. Inside a
    :func:`symbolic_budget` the step's own budget still applies (and wins when it runs out first);
    where no timer is available (see :func:`symbolic_budget`) the block runs unlimited."""
    return _limited(_Limit(float(seconds), SymbolicTimeLimit))
