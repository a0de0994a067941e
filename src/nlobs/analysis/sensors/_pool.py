"""The pool of candidate sensors: the model file's ``[sensors.NAME]`` tables, candidates given to the API, or the
default pool (every state measured directly, and every output of the model)."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ...errors import ModelError
from ...model import TIME, ModelFile, System, parse_expression, symbol
from ...model._expr import ExpressionError

__all__ = ["Candidate", "sensor_pool", "DEFAULT_RELATIVE_NOISE"]

#: The noise of a default candidate that the file gives none (a state, or an output without ``[simulation] noise``):
#: this fraction of the largest magnitude it reads at the samples of the ``[simulation]`` run (of 1 when it reads 0).
DEFAULT_RELATIVE_NOISE = 0.01
#: A candidate whose readings stay within this fraction of the largest state magnitude on the run reads 0 (rounding).
ROUNDING = 1e-12

_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")


@dataclass(frozen=True)
class Candidate:
    """One candidate sensor.

    Attributes
    ----------
    name : str
    expr : sympy.Expr
        What it measures.
    noise : float or None
        Standard deviation of its noise; None until the run fixes a default one (see :data:`DEFAULT_RELATIVE_NOISE`).
    cost : float
    text : str
        The expression as written.
    origin : str
        ``"file"`` ([sensors.NAME]), ``"given"`` (the API), ``"state"`` or ``"output"`` (the default pool).
    noise_source : str
        Where the noise comes from.
    period : float or None
        Its own sample period on the run (``[sensors.NAME] period``, or an output's own ``[simulation] sample_period``);
        None: the run's.
    """

    name: str
    expr: sp.Expr
    noise: float | None
    cost: float = 1.0
    text: str = ""
    origin: str = "given"
    noise_source: str = ""
    period: float | None = None


def _symbols(system: System, definitions: Mapping[str, sp.Expr]) -> dict[str, sp.Expr]:
    out: dict[str, sp.Expr] = {n: symbol(n) for n in (*system.states, *system.inputs, *system.params)}
    out["t"] = TIME
    out.update(definitions)
    return out


def _number(value: Any, what: str, *, positive: bool) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not math.isfinite(value):
        raise ModelError(f"{what} must be a finite number, got {value!r}")
    if (value <= 0) if positive else (value < 0):
        raise ModelError(f"{what} must be {'positive' if positive else 'non-negative'}, got {value!r}")
    return float(value)


def _given(system: System, candidates: Any, definitions: Mapping[str, sp.Expr]) -> tuple[Candidate, ...]:
    """Candidates given to the API: a mapping ``{name: expr or {"expr", "noise", "cost"}}`` or a sequence of
    :class:`Candidate`."""
    if isinstance(candidates, Mapping):
        items = list(candidates.items())
    else:
        items = [(c.name, c) if isinstance(c, Candidate) else (None, c) for c in candidates]
    if not items:
        raise ModelError("candidates: the pool is empty; give at least one candidate sensor (or None for the default pool)")
    symbols = _symbols(system, definitions)
    out, seen = [], set()
    for name, spec in items:
        if isinstance(spec, Candidate):
            cand = spec
        else:
            if not isinstance(name, str) or not _NAME.fullmatch(name):
                raise ModelError(f"candidates: {name!r} is not a sensor name (a letter, then letters, digits or underscores)")
            spec = spec if isinstance(spec, Mapping) else {"expr": spec}
            extra = [k for k in spec if k not in ("expr", "noise", "cost")]
            if extra:
                raise ModelError(f"candidates[{name!r}]: unknown key {extra[0]!r}; a candidate has expr, noise and cost")
            if "expr" not in spec:
                raise ModelError(f"candidates[{name!r}]: `expr` is required (what the sensor measures)")
            expr, text = _expression(spec["expr"], symbols, name)
            noise = None if spec.get("noise") is None else _number(spec["noise"], f"candidates[{name!r}]: noise", positive=True)
            cost = _number(spec.get("cost", 1.0), f"candidates[{name!r}]: cost", positive=False)
            cand = Candidate(name, expr, noise, cost, text, "given", "given" if noise is not None else "")
        if cand.name in seen:
            raise ModelError(f"candidates: the name {cand.name!r} is given twice; give each candidate its own name")
        seen.add(cand.name)
        out.append(cand)
    return tuple(out)


def _expression(value: Any, symbols: Mapping[str, sp.Expr], name: str) -> tuple[sp.Expr, str]:
    if isinstance(value, sp.Basic):
        bad = sorted(s.name for s in value.free_symbols if s.name not in symbols)
        if bad:
            raise ModelError(f"candidates[{name!r}]: the expression uses {bad[0]!r}, not a state, input, parameter or t")
        return value, str(value)
    if isinstance(value, str):
        try:
            return parse_expression(value, symbols), value
        except ExpressionError as e:
            raise ModelError(f"candidates[{name!r}]: {e}") from None
    raise ModelError(f"candidates[{name!r}]: `expr` must be an expression (a string), got {type(value).__name__}")


def _default_pool(system: System, simulation: Any) -> tuple[Candidate, ...]:
    """Every state measured directly and every output; an output that reads a state as it is replaces that state's
    candidate (the same measurement, with the file's noise)."""
    noise = dict(getattr(simulation, "noise", None) or {})
    bound = dict(getattr(simulation, "noise_bound", None) or {})
    direct = {h: o for o, h in zip(system.outputs, system.h) if h in system.x}
    out = []
    for s, x in zip(system.states, system.x):
        if x not in direct:
            out.append(Candidate(s, x, None, 1.0, s, "state"))
    for o, h in zip(system.outputs, system.h):
        if o in noise and noise[o] > 0:
            sigma, src = float(noise[o]), "[simulation] noise"
        elif o in bound and bound[o] > 0:
            sigma, src = float(bound[o]) / math.sqrt(3.0), "[simulation] noise_bound / √3"
        else:
            sigma, src = None, ""
        per = getattr(simulation, "sample_period", None)
        out.append(Candidate(o, h, sigma, 1.0, str(h), "output", src,
                             float(per[o]) if isinstance(per, Mapping) and o in per else None))
    return tuple(out)


def sensor_pool(model: ModelFile | System, candidates: Any = None) -> tuple[Candidate, ...]:
    """The candidate sensors of `model`: `candidates` if given, else the file's ``[sensors.NAME]`` tables, else the
    default pool (every state measured directly, and every output).

    Parameters
    ----------
    model : ModelFile or System
    candidates : mapping or sequence, optional
        ``{name: "expr"}`` or ``{name: {"expr": ..., "noise": ..., "cost": ...}}`` (strings over the states, inputs,
        parameters, t and the file's definitions), or a sequence of :class:`Candidate`.

    Returns
    -------
    tuple of Candidate
        Default candidates without a noise of their own have ``noise=None`` (fixed from the run later).
    """
    mf = model if isinstance(model, ModelFile) else None
    system = mf.system if mf is not None else model
    if not isinstance(system, System):
        raise ModelError(f"select_sensors takes a model file (load_model) or a System, got {type(model).__name__}")
    if candidates is not None:
        return _given(system, candidates, dict(mf.definitions) if mf is not None else {})
    if mf is not None and mf.sensors:
        return tuple(Candidate(c.name, c.expr, c.noise, c.cost, c.text, "file", f"[sensors.{c.name}]",
                               getattr(c, "period", None)) for c in mf.sensors.values())
    return _default_pool(system, mf.simulation if mf is not None else None)


def with_default_noise(pool: Sequence[Candidate], readings: np.ndarray, states: np.ndarray | None = None) -> tuple[Candidate, ...]:
    """The pool with every missing noise set to :data:`DEFAULT_RELATIVE_NOISE` of the largest magnitude the candidate
    reads at the run's samples (`readings`, one column per candidate). A candidate that reads 0 — or only rounding,
    at most :data:`ROUNDING` × the largest magnitude of the run's `states` (a vertical speed of 1e-13 on a level
    run) — gets :data:`DEFAULT_RELATIVE_NOISE` in its own units: 1 % of a rounding error would make it the most precise
    sensor of the pool by twelve orders of magnitude and swamp every other candidate's information."""
    run_scale = float(np.max(np.abs(states))) if states is not None and np.size(states) else 0.0
    run_scale = run_scale if math.isfinite(run_scale) else 0.0
    out = []
    for j, c in enumerate(pool):
        if c.noise is not None:
            out.append(c)
            continue
        peak = float(np.max(np.abs(readings[:, j]))) if readings.size else 0.0
        zero = not (peak > ROUNDING * run_scale and math.isfinite(peak))
        scale = 1.0 if zero else peak
        src = (f"default: {DEFAULT_RELATIVE_NOISE:g} × max |{c.name}| at the samples" if not zero
               else f"default: {DEFAULT_RELATIVE_NOISE:g} (it reads 0 on the run" +
               (f", to rounding: max {peak:.2g}" if peak > 0 else "") + "; give its noise)")
        out.append(Candidate(c.name, c.expr, DEFAULT_RELATIVE_NOISE * scale, c.cost, c.text, c.origin, src, c.period))
    return tuple(out)
