"""Input signals: expressions of t, callables, sampled arrays (zero-order hold or linear), piecewise.

A signal is scalar; a model with several inputs takes one signal per input. Every signal
evaluates on an array of times and returns an array of values.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ..errors import DataError, ModelError, ShapeError
from ._system import TIME, System, exact, symbol, to_expr
from ._translate import NUMPY, translate

__all__ = ["AbstractSignal", "Expression", "Function", "Sampled", "as_signal", "input_signals"]


class AbstractSignal(ABC):
    """A scalar signal of time."""

    @abstractmethod
    def __call__(self, times: np.ndarray) -> np.ndarray:
        """Values at `times` (1-D array), as a 1-D float array of the same length."""

    #: True when the signal is piecewise constant (held), so integrators evaluate it
    #: at the start of each step instead of at the intermediate stages.
    held: bool = False


@dataclass(frozen=True)
class Expression(AbstractSignal):
    """A closed-form signal such as ``0.5*sin(t)`` (a SymPy expression in ``t``)."""

    expr: sp.Expr

    def __call__(self, times: np.ndarray) -> np.ndarray:
        times = np.asarray(times, dtype=float)
        value = translate(self.expr, {TIME: times}, NUMPY)
        return np.broadcast_to(np.asarray(value, dtype=float), times.shape).copy()


@dataclass(frozen=True)
class Function(AbstractSignal):
    """A Python callable ``u(t) -> float``; called on arrays when it accepts them."""

    fn: Callable[[Any], Any]
    name: str = "u"

    def __call__(self, times: np.ndarray) -> np.ndarray:
        times = np.asarray(times, dtype=float)
        try:
            out = np.asarray(self.fn(times), dtype=float)
            if out.shape == times.shape:
                return out
        except Exception:  # noqa: BLE001 - a scalar-only callable; fall back to a loop below
            pass
        try:
            return np.array([float(np.asarray(self.fn(t)).reshape(())) for t in times])
        except Exception as e:
            raise ModelError(f"input `{self.name}`: the callable failed or did not return a number: {e}") from e


@dataclass(frozen=True, init=False)
class Sampled(AbstractSignal):
    """A signal given by samples, held (``hold="zoh"``) or interpolated (``hold="linear"``).

    Outside the sample range the first/last value is held.
    """

    t: np.ndarray
    v: np.ndarray
    hold: str

    def __init__(self, t: Sequence[float], v: Sequence[float], hold: str = "zoh", *, name: str = "u"):
        t_ = np.asarray(t, dtype=float).ravel()
        v_ = np.asarray(v, dtype=float).ravel()
        if t_.shape != v_.shape or t_.size == 0:
            raise ShapeError(f"input `{name}`: {t_.size} sample time(s) for {v_.size} value(s); they must match and be non-empty")
        if hold not in ("zoh", "linear"):
            raise ModelError(f"input `{name}`: `hold` must be 'zoh' or 'linear', got {hold!r}")
        if not np.all(np.isfinite(t_)) or np.any(np.diff(t_) <= 0):
            raise DataError(f"input `{name}`: sample times must be finite and strictly increasing")
        bad = np.flatnonzero(~np.isfinite(v_))
        if bad.size:
            raise DataError(f"input `{name}`: value at row {bad[0]} (t = {t_[bad[0]]:g}) is {v_[bad[0]]}; inputs must be finite")
        object.__setattr__(self, "t", t_)
        object.__setattr__(self, "v", v_)
        object.__setattr__(self, "hold", hold)

    @property
    def held(self) -> bool:  # type: ignore[override]
        return self.hold == "zoh"

    def __call__(self, times: np.ndarray) -> np.ndarray:
        times = np.asarray(times, dtype=float)
        if self.hold == "linear":
            return np.interp(times, self.t, self.v)
        idx = np.searchsorted(self.t, times, side="right") - 1
        return self.v[np.clip(idx, 0, self.v.size - 1)]

    @classmethod
    def piecewise(cls, times: Sequence[float], values: Sequence[float], *, name: str = "u") -> Sampled:
        """A piecewise-constant signal: ``values[i]`` from ``times[i]`` on."""
        return cls(times, values, "zoh", name=name)


def as_signal(value: Any, *, name: str, params: Mapping[str, float] | None = None,
              grid: np.ndarray | None = None) -> AbstractSignal:
    """Turn what a user passes for one input into a signal.

    Parameters
    ----------
    value : signal, number, str, sympy.Expr, callable, array or (t, values) pair
        A signal; a number; an expression in ``t`` (and the model's parameters, substituted
        by their values); a callable ``u(t)``; an array with one value per time of `grid`
        (python-control's ``input_output_response(sys, T, U)`` habit); or a pair ``(t, values)``
        of sample times and values. Arrays and pairs are interpolated linearly between their
        times, as python-control does (``nlobs.Sampled(t, values, "zoh")`` holds them instead).
    name : str
        The input's name, for messages.
    params : mapping of str to float, optional
        Parameter values usable in expressions.
    grid : numpy.ndarray, optional
        The run's time grid (for an array of values).
    """
    if isinstance(value, AbstractSignal):
        return value
    samples = _samples(value, name, grid)
    if samples is not None:
        return samples
    params = dict(params or {})
    if isinstance(value, (str, sp.Basic, int, float, np.integer, np.floating)) and not isinstance(value, bool):
        allowed = {"t": TIME, **{k: symbol(k) for k in params}}
        expr = to_expr(value, allowed, where=f"input `{name}`")
        expr = expr.xreplace({symbol(k): exact(v) for k, v in params.items()})
        return Expression(expr)
    if callable(value):
        return Function(value, name)
    raise ModelError(f"input `{name}`: expected a number, an expression of t, a callable, a signal (nlobs.Sampled(t, values)), "
                     f"an array with one value per time of the run or a (t, values) pair, got {type(value).__name__}")


def _samples(value: Any, name: str, grid: np.ndarray | None) -> Sampled | None:
    """An array on the run's grid or a ``(t, values)`` pair as a linearly interpolated signal; None for anything else."""
    if isinstance(value, tuple) and len(value) == 2 and all(np.ndim(v) == 1 and np.size(v) > 1 for v in value):
        t_, v_ = (np.asarray(v, dtype=float) for v in value)
        if t_.size != v_.size:
            raise ShapeError(f"input `{name}`: a (t, values) pair needs as many values as times, got {t_.size} times and "
                             f"{v_.size} values")
        return Sampled(t_, v_, "linear", name=name)
    if not isinstance(value, (np.ndarray, list)) or isinstance(value, str):
        return None
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"input `{name}`: an array of input values must hold numbers") from None
    if v.ndim != 1:
        raise ShapeError(f"input `{name}`: an array of values must be one-dimensional (one value per time), got shape {v.shape}")
    if grid is None:
        raise ModelError(f"input `{name}`: an array of values needs the run's time grid; pass a (t, values) pair or "
                         "nlobs.Sampled(t, values)")
    if v.size != grid.size:
        raise ShapeError(f"input `{name}`: an array of values needs one value per time of the run ({grid.size} times, "
                         f"t = {grid[0]:g} ... {grid[-1]:g} in steps of the run's dt), got {v.size}; or pass a (t, values) pair")
    return Sampled(grid, v, "linear", name=name)


def input_signals(system: System, inputs: Any, params: Mapping[str, float] | None = None,
                  grid: np.ndarray | None = None) -> tuple[AbstractSignal, ...]:
    """One signal per input of `system` from `inputs`, a mapping ``{name: signal-like}`` (see :func:`as_signal`).

    Inputs not given are zero. With a single input, a bare signal-like value is accepted; a 2-D array with one
    row (or column) per input and one value per time of `grid` gives every input (python-control's ``U``).
    `params` (default: the system's) are the values usable in expressions.
    """
    params = system.params if params is None else params
    if inputs is None:
        inputs = {}
    if isinstance(inputs, np.ndarray) and inputs.ndim == 2 and system.n_inputs > 1:
        rows = inputs if inputs.shape[0] == system.n_inputs else inputs.T
        if rows.shape[0] != system.n_inputs:
            raise ShapeError(f"`inputs`: a 2-D array needs one row per input of {system.name!r} ({system.n_inputs}: "
                             f"{', '.join(system.inputs)}), got shape {inputs.shape}")
        inputs = dict(zip(system.inputs, rows))
    if not isinstance(inputs, Mapping):
        if system.n_inputs != 1:
            raise ModelError(f"{system.name!r} has {system.n_inputs} inputs; pass `inputs` as a mapping {{name: signal}}")
        inputs = {system.inputs[0]: inputs}
    unknown = [k for k in inputs if k not in system.inputs]
    if unknown:
        raise ModelError(f"`inputs` names {', '.join(map(repr, unknown))}, which {'is' if len(unknown) == 1 else 'are'} not an input of "
                         f"{system.name!r}; its inputs are: {', '.join(system.inputs) or '(none)'}")
    return tuple(as_signal(inputs.get(n, 0.0), name=n, params=params, grid=grid) for n in system.inputs)
