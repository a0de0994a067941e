"""The regimes of a piecewise model (abs, sign, min, max, sat) that a trajectory visits.

A model with piecewise functions is smooth on each *regime*, the set of points where every
piecewise function keeps one branch; the structural analysis (:func:`nlobs.analyze`) works on one
regime at a time (``regime=point``). :func:`visited_regimes` groups the samples of a trajectory
(simulated or reconstructed) by regime, so each visited one can be analysed, with the share of
time spent in it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ...errors import ModelError, ShapeError
from ...model import TIME, System, symbol
from ...model._system import exact
from ...model._translate import NUMPY, translate
from ...algebra._series import pretty

__all__ = ["Regime", "piecewise_nodes", "visited_regimes"]

_PIECEWISE = (sp.Abs, sp.sign, sp.Min, sp.Max)


def piecewise_nodes(system: System) -> list[sp.Expr]:
    """The distinct piecewise sub-expressions (abs, sign, min, max) of f and h, parameters substituted."""
    f, h = system.substituted()
    seen: dict[sp.Expr, None] = {}
    for e in (*f, *h):
        for node in sp.preorder_traversal(e):
            if isinstance(node, _PIECEWISE):
                seen.setdefault(node, None)
    return list(seen)


@dataclass(frozen=True)
class Regime:
    """One regime a trajectory visits.

    Attributes
    ----------
    point : dict of str to float
        The middle sample of the trajectory in this regime (states, inputs, t): pass it to
        ``nlobs.analyze(system, regime=point)``.
    fraction : float
        Share of the samples in this regime.
    branches : tuple of str
        Each piecewise function and the branch it takes here (``"min(10, x2) = x2"``).
    """

    point: dict[str, float]
    fraction: float
    branches: tuple[str, ...]

    def __str__(self) -> str:
        return f"{100 * self.fraction:.0f} % of the samples: " + "; ".join(self.branches)


def visited_regimes(system: System, samples: Mapping[str, Any]) -> list[Regime]:
    """Group trajectory samples by regime; most visited first.

    Parameters
    ----------
    system : System
    samples : mapping of name to 1-D array
        Every state, and the inputs and ``t`` if the piecewise functions use them (missing
        inputs are 0), all of the same length.

    Returns
    -------
    list of Regime
        Empty when the model has no piecewise function.

    Raises
    ------
    ModelError, ShapeError
        For a missing state, an unknown name, or arrays of different lengths.
    """
    nodes = piecewise_nodes(system)
    missing = [k for k in system.states if k not in samples]
    if missing:
        raise ModelError(f"visited_regimes: `samples` needs every state; missing: {', '.join(missing)}")
    unknown = [k for k in samples if k not in (*system.states, *system.inputs, "t")]
    if unknown:
        raise ModelError(f"visited_regimes: {unknown[0]!r} is not a state, input or t of {system.name!r}")
    arrays = {k: np.asarray(v, dtype=float).reshape(-1) for k, v in samples.items()}
    N = arrays[system.states[0]].size
    if any(a.size != N for a in arrays.values()) or N == 0:
        raise ShapeError("visited_regimes: every sample array must have the same, non-zero length")
    if not nodes:
        return []
    leaves: dict[sp.Symbol, Any] = {symbol(k): np.zeros(N) for k in system.inputs}
    leaves[TIME] = np.zeros(N)
    leaves.update({TIME if k == "t" else symbol(k): v for k, v in arrays.items()})
    leaves.update({symbol(k): np.full(N, float(exact(v))) for k, v in system.params.items()})

    def value(e: sp.Expr) -> np.ndarray:
        with np.errstate(all="ignore"):
            return np.broadcast_to(np.asarray(translate(e, leaves, NUMPY), dtype=float), (N,))

    codes, labels = [], []
    for node in nodes:
        if isinstance(node, (sp.Abs, sp.sign)):
            g = node.args[0]
            codes.append((value(g) < 0).astype(int))
            labels.append([f"{pretty(node)} = {pretty(s * g if isinstance(node, sp.Abs) else sp.Integer(s))}"
                           for s in (1, -1)])
        else:
            vals = np.vstack([value(a) for a in node.args])
            best = vals.min(axis=0) if isinstance(node, sp.Min) else vals.max(axis=0)
            # on a tie (a boundary), the branch that is not a constant, as analyze() chooses it
            prefer = sorted(range(len(node.args)), key=lambda i: node.args[i].is_number)
            hit = vals[prefer] == best
            codes.append(np.asarray(prefer)[np.argmax(hit, axis=0)])
            labels.append([f"{pretty(node)} = {pretty(a)}" for a in node.args])
    sig = np.column_stack(codes)
    keys, inverse, counts = np.unique(sig, axis=0, return_inverse=True, return_counts=True)
    inverse = np.asarray(inverse).reshape(-1)
    order = np.argsort(-counts, kind="stable")
    out = []
    for i in order:
        members = np.flatnonzero(inverse == i)
        k = int(members[members.size // 2])  # the middle sample: inside the regime rather than on its boundary
        point = {name: float(arrays[name][k]) for name in arrays}
        out.append(Regime(point, float(counts[i] / N), tuple(labels[j][int(c)] for j, c in enumerate(keys[i]))))
    return out
