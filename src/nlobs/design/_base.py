"""What a design returns: the observer's equations with the evidence behind them.

An observer is a dynamical system (Yi, Ortega & Zhang (2019), eq. 2, Wang, Ortega & Bobtsov (2021), eq. 6)

.. math::

    \\dot z = F(t, z, u, y), \\qquad \\hat x = H(t, z, u, y),

optionally with an update at the sample instants, :math:`z^+ = J(t, z^-, u, y, m)`
(continuous-discrete filters; `m` marks which outputs were measured). A design function
checks its preconditions, computes the gains and returns an :class:`ObserverDesign`
holding F, H, J as CasADi functions and a :class:`Certificate`. The ``observer`` layer
turns a design into something that runs.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from .._display import html_block
from ..errors import ShapeError
from ..model import System

__all__ = ["Check", "Certificate", "ObserverDesign", "Symbols"]


_STATUS = ("holds", "assumed", "fails")
_MARK = {"holds": "ok", "assumed": "assumed", "fails": "FAILED"}


@dataclass(frozen=True)
class Check:
    """One precondition or guarantee: what was checked, its status, and the numbers.

    Attributes
    ----------
    condition : str
        The condition, in words.
    status : {"holds", "assumed", "fails"}
        ``"holds"``: verified, with the numbers in `detail`; ``"assumed"``: stated by the
        design (a paper's hypothesis, a property of data not seen at design time) but **not**
        verified; ``"fails"``: verified to be false. ``True`` and ``False`` are accepted for
        ``"holds"`` and ``"fails"``.
    detail : str
        The numbers behind the status, or why the condition could not be verified.
    evidence : str
        What kind of evidence decided a ``"holds"``/``"fails"`` (e.g. ``"symbolic"``,
        ``"exact arithmetic"``, ``"floating point"``, ``"sampled over the region (a lower bound
        of the supremum)"``, ``"heuristic threshold"``); empty when obvious from `detail`.
    """

    condition: str
    status: str | bool
    detail: str = ""
    evidence: str = ""

    def __post_init__(self) -> None:
        status = {True: "holds", False: "fails"}.get(self.status, self.status) if isinstance(self.status, bool) else self.status
        if status not in _STATUS:
            raise ValueError(f"Check: `status` must be one of {', '.join(_STATUS)} (or True/False), got {self.status!r}")
        object.__setattr__(self, "status", status)

    @classmethod
    def assumed(cls, condition: str, detail: str = "") -> Check:
        """A condition the design relies on but does not verify."""
        return cls(condition, "assumed", detail)

    @property
    def holds(self) -> bool:
        """True only when the condition was verified (never for an assumed one)."""
        return self.status == "holds"

    @property
    def fails(self) -> bool:
        return self.status == "fails"

    def __str__(self) -> str:
        text = f"[{_MARK[self.status]}] {self.condition}"
        if self.detail:
            text += f": {self.detail}"
        if self.evidence:
            text += f" ({self.evidence})"
        return text


def _fmt(value: Any) -> str:
    if isinstance(value, np.ndarray):
        if np.iscomplexobj(value):
            return "[" + ", ".join(f"{complex(v):.4g}" for v in value.ravel()) + "]"
        return np.array2string(value, precision=4, suppress_small=True, separator=", ").replace("\n", "\n      ")
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


@dataclass(frozen=True, eq=False)
class Certificate:
    """The evidence a design returns with its observer.

    Attributes
    ----------
    method : str
        What was designed, in words.
    reference : str
        The work and the equation implemented, cited by author and year (:func:`nlobs.references.cite`).
    checks : tuple of Check
        Preconditions and guarantees, each with its numbers.
    values : mapping
        Gains, matrices, eigenvalues, rates: everything a reader may want to verify.
    """

    method: str
    reference: str
    checks: tuple[Check, ...] = ()
    values: Mapping[str, Any] = field(default_factory=dict)

    def __str__(self) -> str:
        lines = [f"{self.method}", f"  reference: {self.reference}"]
        lines += [f"  {c}" for c in self.checks]
        lines += [f"  {k} = {_fmt(v)}" for k, v in self.values.items()]
        return "\n".join(lines)

    def __repr__(self) -> str:
        counts = ", ".join(f"{sum(c.status == s for c in self.checks)} {s}" for s in _STATUS if any(c.status == s for c in self.checks))
        return f"Certificate({self.method!r}, reference={self.reference!r}, checks: {counts or 'none'}, values: {', '.join(self.values)})"

    def _repr_html_(self) -> str:
        return html_block(f"Certificate: {self.method}", str(self))


@dataclass(frozen=True)
class Symbols:
    """The CasADi symbols a design writes its equations in."""

    t: ca.SX
    z: ca.SX
    u: ca.SX
    y: ca.SX
    m: ca.SX

    @classmethod
    def make(cls, system: System, n_z: int) -> Symbols:
        return cls(ca.SX.sym("t"), ca.SX.sym("z", n_z), ca.SX.sym("u", system.n_inputs),
                   ca.SX.sym("y", system.n_outputs), ca.SX.sym("m", system.n_outputs))


@dataclass(frozen=True, eq=False)
class ObserverDesign:
    """A designed observer: its equations (CasADi functions) and its certificate.

    Attributes
    ----------
    method : str
        The design's kind (``"luenberger"``, ``"ekf"``, ...), as used in model files.
    system : System
        The plant model the observer was designed for (its parameters are baked in).
    z_names : tuple of str
        Names of the observer's internal states z.
    flow : casadi.Function
        ``(t, z, u, y) -> dz/dt``.
    output : casadi.Function
        ``(t, z, u, y) -> xhat`` (one entry per plant state).
    initial : casadi.Function
        ``(xhat0) -> z0``: the internal state that starts from the estimate `xhat0`.
    xhat0 : numpy.ndarray
        The default initial estimate.
    certificate : Certificate
    update : casadi.Function or None
        ``(t, z, u, y, m) -> z+``, applied at each sample instant (``m[i] = 1`` when output i
        was measured); None for purely continuous observers.
    covariance : casadi.Function or None
        ``(z) -> P``, the n x n covariance of the estimate x̂ that the observer carries (the
        Kalman filters: EKF, UKF, Kalman-Bucy, Kalman-like without forgetting); None when it
        carries none. Results report ±2σ of estimated parameters from it.
    """

    method: str
    system: System
    z_names: tuple[str, ...]
    flow: ca.Function
    output: ca.Function
    initial: ca.Function
    xhat0: np.ndarray
    certificate: Certificate
    update: ca.Function | None = None
    covariance: ca.Function | None = None

    @classmethod
    def build(cls, method: str, system: System, s: Symbols, *, z_names: Sequence[str], flow: ca.SX,
              xhat: ca.SX, xhat0_sym: ca.SX, z0: ca.SX, xhat0: Any, certificate: Certificate,
              update: ca.SX | None = None, covariance: ca.SX | None = None) -> ObserverDesign:
        """Assemble a design from SX expressions in the symbols `s` (and `xhat0_sym` for z0);
        `covariance` is the covariance of x̂ as an expression of z alone."""
        ins, names = [s.t, s.z, s.u, s.y], ["t", "z", "u", "y"]
        x0 = check_vector(xhat0, system.n_states, "xhat0", method)
        return cls(
            method, system, tuple(z_names),
            ca.Function(f"{method}_flow", ins, [flow], names, ["dz"]),
            ca.Function(f"{method}_output", ins, [xhat], names, ["xhat"]),
            ca.Function(f"{method}_initial", [xhat0_sym], [z0], ["xhat0"], ["z0"]),
            x0, certificate,
            None if update is None else ca.Function(f"{method}_update", [*ins, s.m], [update], [*names, "m"], ["z_plus"]),
            None if covariance is None else ca.Function(f"{method}_covariance", [s.z], [covariance], ["z"], ["P"]),
        )

    @property
    def n_z(self) -> int:
        return len(self.z_names)

    @functools.cached_property
    def needs_mx(self) -> bool:
        """Whether a function is not plain SX (e.g. MHE's update embeds an NLP solver): callers then build
        MX graphs around it, and it runs on CasADi's virtual machine (no C code generation). Asked on every run
        (four CasADi type checks): kept after the first time (the functions of a design never change)."""
        return any(fn is not None and not fn.is_a("SXFunction") for fn in (self.flow, self.output, self.initial, self.update))

    def selects_state(self, n: int) -> bool:
        """Whether the estimate is exactly the first n internal states (x̂ = z[:n]), so that a loop can read x̂
        from z instead of evaluating the output map (False for a design that is not plain SX)."""
        if self.needs_mx:
            return False
        z = ca.SX.sym("z", self.n_z)
        t, u, y = ca.SX.sym("t"), ca.SX.sym("u", self.system.n_inputs), ca.SX.sym("y", self.system.n_outputs)
        xhat = self.output(t, z, u, y)
        return self.n_z >= n and all(ca.is_equal(xhat[i], z[i]) for i in range(n))

    @property
    def sampled(self) -> bool:
        """Whether the observer updates at sample instants (continuous-discrete)."""
        return self.update is not None

    def __str__(self) -> str:
        kind = "discrete time" if self.system.is_discrete else "continuous-discrete" if self.sampled else "continuous"
        return (f"{self.method} observer for {self.system.name!r} ({kind}, {self.n_z} internal states)\n"
                + str(self.certificate))


def check_vector(value: Any, n: int, name: str, caller: str) -> np.ndarray:
    """A finite float vector of length n, or a ShapeError naming `name` and `caller`."""
    try:
        v = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as e:
        raise ShapeError(f"{caller}: `{name}` must be a vector of {n} numbers: {e}") from None
    if v.size != n:
        raise ShapeError(f"{caller}: `{name}` must have {n} entries, got {v.size}")
    if not np.all(np.isfinite(v)):
        raise ShapeError(f"{caller}: `{name}` has non-finite entries: {v}")
    v.setflags(write=False)
    return v
