"""Result objects shared by the analyses: a verdict, the evidence, a readable ``__str__``, ``to_dict()``."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from ..references import cite
from .._display import html_block

__all__ = ["clean_direction", "fmt_vec", "fmt_directions", "fmt_point", "ObservabilityReport", "FunctionCheck", "Symmetry"]


def clean_direction(v: np.ndarray) -> np.ndarray:
    """A unit vector with its largest entry positive and round-off zeros removed (for messages)."""
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v)
    if n == 0:
        return v
    v = v / n
    v = v * np.sign(v[np.argmax(np.abs(v))])
    v[np.abs(v) < 1e-10] = 0.0
    return v + 0.0


def fmt_vec(v: Any, precision: int = 4) -> str:
    return np.array2string(np.asarray(v, dtype=float), precision=precision, separator=", ", suppress_small=True)


def fmt_directions(rows: Any) -> str:
    """Kernel directions for a message: each cleaned (unit, largest entry positive), separated by '; '."""
    return "; ".join(fmt_vec(clean_direction(v)) for v in rows)


def fmt_point(names: Any, point: Any) -> str:
    """``x1=0.5, x2=-1`` for a worst point."""
    return ", ".join(f"{n}={v:.4g}" for n, v in zip(names, point))


@dataclass(frozen=True)
class FunctionCheck:
    """Is a function φ(x, θ) observable? Yes iff its gradient lies in the row space of the jet Jacobian."""

    expr: str
    observable: bool

    def __str__(self) -> str:
        return f"{self.expr}: {'observable' if self.observable else 'NOT observable'}"


@dataclass(frozen=True)
class Symmetry:
    """A sign change σ of some unknowns with f(σx) = σ f(x) and h(σx) = h(x), proved symbolically.

    Then x and σx give the same output for every input: the model is not globally observable
    (although the rank condition, a local property, may hold).
    """

    flipped: tuple[str, ...]

    def __str__(self) -> str:
        return "(" + ", ".join(self.flipped) + ") -> -(" + ", ".join(self.flipped) + ")"


@dataclass(frozen=True, eq=False)
class ObservabilityReport:
    r"""Structural (generic-rank) observability of a model; see :func:`nlobs.analysis.analyze`.

    Attributes
    ----------
    model : str
    states, unknown_params, unknown_input_coefficients : tuple of str
        The unknowns, in the column order of the Jacobian and of the directions.
    rank : int
        Generic rank of the Jacobian of the output jets with respect to the unknowns.
    observable : bool
        The generic rank condition holds: rank = number of unknowns.
    observable_states, identifiable_params : tuple of str
        Unknowns whose unit vector lies in the row space (locally observable / identifiable).
    unobservable_directions : numpy.ndarray of shape (n_unknowns - rank, n_unknowns)
        An orthonormal basis of the kernel at the real point `point`.
    point : numpy.ndarray
        The real point where the directions were computed.
    orders : tuple of int
        Per output, the highest derivative order that contributed a new independent row.
    method : str
    prime : int
    error_probability : float
        Upper bound on the probability that `rank` is below the true generic rank (0 when the
        rank is full: a full rank at one point is a proof).
    symmetries : tuple of Symmetry
        Sign symmetries found (each proves global non-observability of the flipped unknowns).
    functions : tuple of FunctionCheck
    notes : tuple of str
    seconds : float
    global_check : GlobalResult or None
        Global verdicts (``analyze(..., global_check=True)``): globally / locally only (with the
        number of solutions) / not identifiable, or the reason the check was refused.
    identifiable_functions : IdentifiableFunctions or None
        Generators of the identifiable (observable) functions (``identifiable_functions=True``).
    experiments : MultiExperiment or None
        Multi-experiment identifiability of the parameters (``experiments=N``).
    """

    model: str
    states: tuple[str, ...]
    unknown_params: tuple[str, ...]
    unknown_input_coefficients: tuple[str, ...]
    inputs: str
    rank: int
    observable: bool
    observable_states: tuple[str, ...]
    identifiable_params: tuple[str, ...]
    unobservable_directions: np.ndarray
    point: np.ndarray
    orders: tuple[int, ...]
    method: str
    prime: int
    error_probability: float
    symmetries: tuple[Symmetry, ...] = ()
    symmetry_search: str = ""
    functions: tuple[FunctionCheck, ...] = ()
    notes: tuple[str, ...] = ()
    seconds: float = 0.0
    numerical_gap: float = float("inf")
    extra: dict[str, Any] = field(default_factory=dict)
    global_check: Any = None
    identifiable_functions: Any = None
    experiments: Any = None

    @property
    def unknowns(self) -> tuple[str, ...]:
        return (*self.states, *self.unknown_params, *self.unknown_input_coefficients)

    @property
    def n_states(self) -> int:
        return len(self.states)

    @property
    def globally_observable(self) -> bool | None:
        """False when a symmetry or the global check proves two values indistinguishable; True when the global
        check proved every unknown globally determined; None when not decided (only the local test ran)."""
        if not self.observable:
            return False
        if self.symmetries:
            return False
        g = self.global_check
        if g is not None and g.ok:
            if g.locally_only or g.non_identifiable:
                return False
            return None if getattr(g, "undecided", ()) else True
        return None

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dictionary (the ``nlobs analyze --json`` contract plus evidence)."""
        return {
            "model": self.model,
            "n_states": self.n_states,
            "rank": self.rank,
            "observable": self.observable,
            "observable_states": list(self.observable_states),
            "unobservable_directions": [[float(v) for v in row] for row in self.unobservable_directions],
            "method": self.method,
            "unknowns": list(self.unknowns),
            "unknown_params": list(self.unknown_params),
            "identifiable_params": list(self.identifiable_params),
            "inputs": self.inputs,
            "point": [float(v) for v in self.point],
            "orders": list(self.orders),
            "prime": self.prime,
            "error_probability": self.error_probability,
            "globally_observable": self.globally_observable,
            "symmetries": [list(s.flipped) for s in self.symmetries],
            "functions": {c.expr: c.observable for c in self.functions},
            "notes": list(self.notes),
            "seconds": self.seconds,
        } | self._extensions()

    def _extensions(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.global_check is not None:  # "global": exactly the three lists (null when refused); evidence apart
            d = self.global_check.to_dict()
            out["global"] = None if self.global_check.refused else {
                k: d[k] for k in ("globally", "locally_only", "non_identifiable", "undecided") if k in d}
            out["global_detail"] = d
        if self.identifiable_functions is not None:
            idf = self.identifiable_functions
            out["identifiable_functions"] = None if idf.refused else idf.to_list()
            out["identifiable_functions_detail"] = self.identifiable_functions.to_dict()
            out["identifiable_functions_field"] = "parameters" if not idf.with_states else "states and parameters"
        if self.experiments is not None:
            out["experiments"] = self.experiments.to_dict()
        return out

    def __repr__(self) -> str:
        return (f"ObservabilityReport(model={self.model!r}, observable={self.observable}, rank={self.rank}/{len(self.unknowns)}, "
                f"observable_states={self.observable_states}, globally_observable={self.globally_observable})")

    def _repr_html_(self) -> str:
        return html_block(f"Observability of {self.model!r}", str(self))

    def __str__(self) -> str:
        M = len(self.unknowns)
        what = "observable" if not (self.unknown_params or self.unknown_input_coefficients) else "observable and identifiable"
        head = f"Model {self.model!r}: "
        if self.observable:
            head += f"locally {what} (generic rank {self.rank} = {M} unknowns)"
        else:
            head += f"NOT {what.replace(' and ', '/')} (generic rank {self.rank} < {M} unknowns)"
        lines = [head, f"  inputs: {self.inputs}"]
        lines.append(f"  observable states: {', '.join(self.observable_states) or '(none)'}")
        bad = [s for s in self.states if s not in self.observable_states]
        if bad:
            lines.append(f"  unobservable states: {', '.join(bad)}")
        if self.unknown_params:
            lines.append(f"  identifiable parameters: {', '.join(self.identifiable_params) or '(none)'}")
            badp = [p for p in self.unknown_params if p not in self.identifiable_params]
            if badp:
                lines.append(f"  unidentifiable parameters: {', '.join(badp)}")
        if len(self.unobservable_directions):
            lines.append(f"  unobservable directions at {fmt_vec(self.point, 3)} (columns {', '.join(self.unknowns)}):")
            for v in self.unobservable_directions:
                lines.append(f"    {fmt_vec(clean_direction(v))}")
        for c in self.functions:
            lines.append(f"  {c}")
        if self.symmetries:
            lines.append("  NOT globally observable: the output is invariant under " + "; ".join(str(s) for s in self.symmetries)
                         + " (proved symbolically: f(σx) = σf(x), h(σx) = h(x)); these are known only up to sign")
        elif self.observable and (self.global_check is None or not self.global_check.ok):
            lines.append(f"  the rank condition is local ({cite('002')}): it proves local weak observability, not global; "
                         + (self.symmetry_search or "no symmetry search was run"))
        word = "observable/identifiable" if (self.unknown_params or self.unknown_input_coefficients) else "observable"
        if self.global_check is not None:
            lines.append("  global check:")
            lines += [f"    {t}" for t in self.global_check.describe(word)]
        if self.identifiable_functions is not None:
            lines += [f"  {t}" for t in self.identifiable_functions.describe()]
        if self.experiments is not None:
            lines += [f"  {t}" for t in self.experiments.describe()]
        lines.append(f"  method: {self.method}")
        if self.error_probability > 0:
            lines.append(f"  probability that the rank is underestimated: <= {self.error_probability:.2g}")
        for n in self.notes:
            lines.append(f"  note: {n}")
        lines.append(f"  ({self.seconds * 1e3:.1f} ms)")
        return "\n".join(lines)
