r"""Linear regression equations and their on-line parameter estimators.

A linear regression equation (LRE) relates measurable signals :math:`\mathcal Y(t) \in \mathbb R^q`
and :math:`\psi(t) \in \mathbb R^{n_\theta \times q}` to a constant unknown vector θ:

.. math::

    \mathcal Y = \psi^\top \theta + d .

Four estimators are provided, each as a small option object that adds its states to an
observer's internal state (they are building blocks of GPEBO, PEBO and KKL+PEBO observers),
and each as a design function on a regression model (θ as constant states, ψ from the inputs)
so an estimator runs, is simulated and compared like any observer:

- :class:`Gradient`: :math:`\dot{\hat\theta} = \Gamma\psi(\mathcal Y - \psi^\top\hat\theta)`;
- :class:`LeastSquares`: with forgetting, :math:`\dot P = \beta P - P\psi\psi^\top P`;
- :class:`DREM`: dynamic regressor extension (stable LTI filters) and mixing with the adjugate,
  one scalar regression :math:`\mathcal Y_i = \Delta\theta_i` per parameter;
- :class:`GD`: the G+D interlaced estimator of Wang, Ortega & Bobtsov (2021), eqs. (16)-(17), which converges under
  interval excitation only (identifiability of the LRE).

The filters :math:`F(p) = \alpha/(p+\alpha)` and :math:`W(p) = \alpha p/(p + \alpha)` of
Yi, Ortega & Zhang (2019), eq. (37) are :func:`lowpass` and :func:`derivative_filter`.

Every estimator reports the excitation it saw: :func:`excitation_report` evaluates the
regressor along a run and returns the interval-excitation level
:math:`\lambda_{\min}\int_0^t\psi\psi^\top` (Wang, Ortega & Bobtsov (2021), eq. 15), the persistent-excitation level over a
window, and for DREM and G+D the mixed regressor Δ and the time it became non-zero.

References
----------
Wang, Ortega & Bobtsov (2021), eqs. (9), (15), (16)-(17), Lemma 2; Yi, Ortega & Zhang (2019), eqs. (34), (37),
(47); DREM: Aranovskiy, Bobtsov, Ortega, Pyrkin, IEEE TAC 62 (2017) 3546-3550 (Wang, Ortega & Bobtsov (2021), ref. [1]);
least squares with forgetting: Ioannou & Sun (1996), §4.3.6.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import casadi as ca
import numpy as np
import sympy as sp

from ...engine import to_casadi
from ...errors import FormError, PreconditionError, ShapeError
from ...model import TIME, System, symbol
from ...model._forms import matrix_of
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign, Symbols
from .._checks import check_matrix, check_positive
from .._common import leaves_of
from .._constructions import evaluate
from .._kind import Tuning, kind

__all__ = [
    "StateStack", "Regression", "sx_matrix", "lowpass", "derivative_filter", "adjugate",
    "AbstractEstimator", "Gradient", "LeastSquares", "DREM", "GD", "Estimate", "estimator_from",
    "LinearRegression", "design_gradient", "design_least_squares", "design_drem", "design_gd",
    "ExcitationMonitor", "ExcitationReport", "excitation_report",
]

REF_GD = f"{cite('000')} eqs. (16)-(17), Lemma 2 (G+D interlaced estimator)"
REF_DREM = f"DREM: {cite('000')} ref. [1] (Aranovskiy et al., IEEE TAC 2017); mixing as in {cite('000')} eqs. (17c)-(19)"
REF_GRADIENT = f"gradient estimator: {cite('004')} eqs. (34), (47); {cite('000')} eq. (16a)"
REF_LS = f"least squares with forgetting ({cite('ioannou1996', '§4.3.6')})"


# ---------------------------------------------------------------------------------------------
# Building the internal state block by block
# ---------------------------------------------------------------------------------------------
class StateStack:
    """The internal state z of an observer, assembled block by block.

    Designs that combine filters, dynamic extensions and estimators add each block with
    :meth:`add` (a fresh CasADi symbol with its initial value), write its flow with
    :meth:`set_flow`, and finally :meth:`build` the :class:`ObserverDesign`; z is the
    concatenation of the blocks in the order they were added.

    Parameters
    ----------
    system : System
        The plant model (its inputs and outputs are the symbols :attr:`u`, :attr:`y`).
    """

    def __init__(self, system: System):
        self.system = system
        self.t = ca.SX.sym("t")
        self.u = ca.SX.sym("u", system.n_inputs)
        self.y = ca.SX.sym("y", system.n_outputs)
        self.m = ca.SX.sym("m", system.n_outputs)
        self.xhat0 = ca.SX.sym("xhat0", system.n_states)
        self._blocks: list[tuple[ca.SX, list[str], ca.SX]] = []
        self._flows: dict[int, ca.SX] = {}
        self._jumps: dict[int, ca.SX] = {}

    def add(self, name: str, rows: int, cols: int = 1, init: Any = 0.0) -> ca.SX:
        """A new block of `rows` x `cols` states named `name`, starting at `init`
        (a number, a NumPy array or an SX expression in :attr:`xhat0`)."""
        sym = ca.SX.sym(name, rows, cols)
        if cols == 1:
            names = [name] if rows == 1 else [f"{name}[{i}]" for i in range(rows)]
        else:
            names = [f"{name}[{i},{j}]" for j in range(cols) for i in range(rows)]
        if isinstance(init, (ca.SX, ca.DM)):
            z0 = ca.SX(init)
            if z0.shape == (1, 1) and rows * cols > 1:
                z0 = ca.repmat(z0, rows, cols)
        else:
            a = np.asarray(init, dtype=float)
            if a.ndim == 1 and cols == 1:
                a = a.reshape(-1, 1)
            z0 = ca.SX(ca.DM(np.broadcast_to(a, (rows, cols)).copy()))
        if z0.shape != (rows, cols):
            raise ShapeError(f"StateStack.add: the initial value of `{name}` has shape {z0.shape}, expected ({rows}, {cols})")
        self._blocks.append((sym, names, ca.vec(z0)))
        return sym

    def set_flow(self, sym: ca.SX, flow: Any) -> None:
        """The time derivative of a block returned by :meth:`add` (same shape)."""
        f = ca.SX(flow)
        if f.shape != sym.shape:
            raise ShapeError(f"StateStack.set_flow: flow of shape {f.shape} for a block of shape {sym.shape}")
        self._flows[id(sym)] = f

    def set_update(self, sym: ca.SX, value: Any) -> None:
        """The value of a block right after a sample instant (z⁺ = J(t, z⁻, u, y, m)); blocks
        without one are continuous across samples."""
        v = ca.SX(value)
        if v.shape != sym.shape:
            raise ShapeError(f"StateStack.set_update: value of shape {v.shape} for a block of shape {sym.shape}")
        self._jumps[id(sym)] = v

    @property
    def n_z(self) -> int:
        return sum(b[0].numel() for b in self._blocks)

    @property
    def z(self) -> ca.SX:
        return ca.vertcat(*[ca.vec(b[0]) for b in self._blocks]) if self._blocks else ca.SX(0, 1)

    def symbols(self) -> Symbols:
        return Symbols(self.t, self.z, self.u, self.y, self.m)

    def leaves(self, x: Any = None) -> dict[sp.Symbol, Any]:
        """The model's t, inputs, outputs (and states, if `x` is given) -> this stack's CasADi symbols."""
        return leaves_of(self.system, self, x)  # type: ignore[arg-type]  # StateStack has the t, u, y of Symbols

    def build(self, method: str, *, xhat: ca.SX, certificate: Certificate, xhat0: Any = None) -> ObserverDesign:
        """Assemble the design: flow = the blocks' flows in order, z0 = their initial values, and
        an update at the sample instants when a block has one (:meth:`set_update`)."""
        missing = [b[1][0] for b in self._blocks if id(b[0]) not in self._flows]
        if missing:  # a bug in a design, not a user error
            raise RuntimeError(f"StateStack.build: no flow for block(s) {missing}")
        flow = ca.vertcat(*[ca.vec(self._flows[id(b[0])]) for b in self._blocks])
        z0 = ca.vertcat(*[b[2] for b in self._blocks])
        names = [n for b in self._blocks for n in b[1]]
        update = None
        if self._jumps:
            update = ca.vertcat(*[ca.vec(self._jumps.get(id(b[0]), b[0])) for b in self._blocks])
        x0 = np.zeros(self.system.n_states) if xhat0 is None else xhat0
        return ObserverDesign.build(method, self.system, self.symbols(), z_names=names, flow=flow, xhat=xhat,
                                    xhat0_sym=self.xhat0, z0=z0, xhat0=x0, certificate=certificate, update=update)


def lowpass(stack: StateStack, signal: Any, alpha: float, name: str) -> ca.SX:
    r"""The filter :math:`F(p) = \alpha/(p + \alpha)` applied to `signal` (Yi, Ortega & Zhang (2019), eq. 37).

    Adds the state :math:`w` with :math:`\dot w = -\alpha w + \alpha s`, :math:`w(0) = 0`, and
    returns it.

    Parameters
    ----------
    stack : StateStack
        The observer state the filter state is added to.
    signal : casadi.SX
        The filtered signal, a vector or a matrix (filtered entry-wise).
    alpha : float
        The filter constant α > 0.
    name : str
        Name of the filter state.

    References
    ----------
    Yi, Ortega & Zhang (2019), eq. (37).
    """
    a = check_positive(alpha, "alpha", "lowpass")
    s = ca.SX(signal)
    w = stack.add(name, s.shape[0], s.shape[1])
    stack.set_flow(w, -a * w + a * s)
    return w


def derivative_filter(stack: StateStack, signal: Any, alpha: float, name: str) -> ca.SX:
    r"""The filter :math:`W(p) = \alpha p/(p + \alpha)` applied to `signal` (Yi, Ortega & Zhang (2019), eq. 37).

    Since :math:`W = \alpha(1 - F)`, it is :math:`\alpha(s - F[s])` with one filter state;
    :math:`W[s]` is the filtered derivative: :math:`W[s] = F[\dot s] + \alpha s(0)e^{-\alpha t}`
    (the second term is the exponentially decaying :math:`\epsilon_t` of Yi, Ortega & Zhang (2019), §V-A).

    Parameters
    ----------
    stack : StateStack
        The observer state the filter state is added to.
    signal : casadi.SX
        The signal whose filtered derivative is wanted (vector or matrix).
    alpha : float
        The filter constant α > 0.
    name : str
        Name of the filter state.

    References
    ----------
    Yi, Ortega & Zhang (2019), eq. (37), §V-A.
    """
    a = check_positive(alpha, "alpha", "derivative_filter")
    s = ca.SX(signal)
    return a * (s - lowpass(stack, s, a, name))


def sx_matrix(M: sp.Matrix, leaves: Mapping[sp.Symbol, Any]) -> ca.SX:
    """A SymPy matrix as a CasADi SX matrix of the same shape."""
    if M.shape[0] * M.shape[1] == 0:
        return ca.SX(M.shape[0], M.shape[1])
    return ca.reshape(to_casadi(list(M.T), leaves), M.shape[0], M.shape[1])  # list(M.T): column-major, as reshape


#: Above this size the determinant and the adjugate come from the Faddeev–LeVerrier recursion (O(n⁴) operations)
#: instead of cofactors (CasADi's det expands them: n! terms, which at n = 10 does not finish).
COFACTOR_MAX = 3


def det_adj(M: ca.SX) -> tuple[ca.SX, ca.SX]:
    r"""det(M) and adj(M) of a square SX matrix, both defined also when M is singular.

    Up to :data:`COFACTOR_MAX` by cofactors; beyond, by the Faddeev–LeVerrier recursion on the characteristic
    polynomial :math:`\det(\lambda I - M) = \sum_k c_k \lambda^k`: :math:`N_1 = I`,
    :math:`c_{n-k} = -\operatorname{tr}(M N_k)/k`, :math:`N_{k+1} = M N_k + c_{n-k} I`; then
    :math:`\det M = (-1)^n c_0` and :math:`\operatorname{adj} M = (-1)^{n+1} N_n` (Cayley–Hamilton). Division-free but
    for the integers k, so it stays exact at a singular M (the estimators start there: Ω(0) = I)."""
    n = M.shape[0]
    if n <= COFACTOR_MAX:
        return ca.det(M), adjugate(M)
    I = ca.SX.eye(n)
    N = I
    for k in range(1, n + 1):
        MN = M @ N
        c = -ca.trace(MN) / k
        if k == n:
            return (-1) ** n * c, (-1) ** (n + 1) * N
        N = MN + c * I
    raise AssertionError("unreachable")


def adjugate(M: ca.SX) -> ca.SX:
    r"""The adjugate (transposed cofactor matrix) of a small square SX matrix:
    :math:`\operatorname{adj}(M) M = \det(M) I`, defined also when M is singular (see :func:`det_adj` for larger)."""
    n = M.shape[0]
    if n > COFACTOR_MAX:
        return det_adj(M)[1]
    if n == 1:
        return ca.SX(1)
    out = ca.SX(n, n)
    for i in range(n):
        for j in range(n):
            rows = [r for r in range(n) if r != i]
            cols = [c for c in range(n) if c != j]
            out[j, i] = (-1) ** (i + j) * ca.det(M[rows, cols])
    return out


# ---------------------------------------------------------------------------------------------
# Regressions and estimators (SX level)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Regression:
    r"""A linear regression :math:`\mathcal Y = \psi^\top\theta + d` in CasADi expressions.

    Attributes
    ----------
    Y : casadi.SX of shape (q, 1)
    psi : casadi.SX of shape (n_theta, q)
    names : tuple of str
        The parameters' names (for the estimator's states and reports).
    """

    Y: ca.SX
    psi: ca.SX
    names: tuple[str, ...]

    def __post_init__(self) -> None:
        if self.psi.shape[1] != self.Y.shape[0] or self.Y.shape[1] != 1:
            raise ShapeError(f"Regression: Y has shape {self.Y.shape} and ψ {self.psi.shape}; "
                             "need Y (q, 1) and ψ (n_theta, q)")
        if len(self.names) != self.psi.shape[0]:
            raise ShapeError(f"Regression: {len(self.names)} parameter names for {self.psi.shape[0]} parameters")

    @property
    def n_theta(self) -> int:
        return self.psi.shape[0]

    @property
    def q(self) -> int:
        return self.Y.shape[0]


@dataclass(frozen=True, eq=False)
class Estimate:
    """What an estimator adds to an observer: θ̂ as an expression of the internal state, and the
    signals :func:`excitation_report` evaluates (ψ always; Δ for DREM and G+D)."""

    theta: ca.SX
    psi: ca.SX
    delta: ca.SX | None = None


class AbstractEstimator(ABC):
    """An on-line estimator of θ in a linear regression; see the module docstring."""

    #: Short name used in reports and model files.
    kind: ClassVar[str] = ""
    #: The paper and equations implemented.
    reference: ClassVar[str] = ""

    @abstractmethod
    def build(self, stack: StateStack, reg: Regression, theta0: Any, prefix: str = "theta") -> Estimate:
        """Add the estimator's states to `stack`; θ̂(0) = `theta0` (numbers or SX)."""

    @abstractmethod
    def n_states(self, n_theta: int, q: int) -> int:
        """How many internal states the estimator adds for n_theta parameters and q rows."""

    def describe(self) -> dict[str, Any]:
        """Its tuning, for certificates."""
        return {f"{self.kind}.{k}": v for k, v in self.__dict__.items() if v is not None}


def _gain(value: Any, n: int, name: str, caller: str) -> np.ndarray:
    """A scalar, a vector (diagonal) or an SPD matrix gain as an (n, n) array."""
    arr = np.asarray(value, dtype=float) if not isinstance(value, np.ndarray) else np.array(value, dtype=float)
    if arr.ndim == 0:
        arr = arr * np.eye(n)
    elif arr.ndim == 1:
        if arr.size != n:
            raise ShapeError(f"{caller}: `{name}` has {arr.size} entries for {n} parameters")
        arr = np.diag(arr)
    return check_matrix(arr, n, n, name, caller, definite="positive")


def _check_gain_value(value: Any, name: str, caller: str) -> None:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise PreconditionError(f"{caller}: `{name}` must be a positive number or a positive definite matrix, got {value!r}") from None
    if arr.size == 0 or not np.all(np.isfinite(arr)):
        raise PreconditionError(f"{caller}: `{name}` must be finite, got {value!r}")
    if arr.ndim <= 1 and np.any(arr <= 0):
        raise PreconditionError(f"{caller}: `{name}` must be positive, got {value!r}")


def _freeze(value: Any) -> Any:
    """Lists/arrays to nested tuples, so estimator objects are hashable and immutable."""
    if isinstance(value, (list, tuple, np.ndarray)):
        return tuple(_freeze(v) for v in (value.tolist() if isinstance(value, np.ndarray) else value))
    return value


@dataclass(frozen=True)
class Gradient(AbstractEstimator):
    r"""Gradient estimator :math:`\dot{\hat\theta} = \Gamma\psi(\mathcal Y - \psi^\top\hat\theta)`.

    Converges exponentially iff ψ is persistently exciting; with a scalar regressor, iff ψ is
    not square integrable (Yi, Ortega & Zhang (2019), §V-A).

    Parameters
    ----------
    gamma : float, sequence or (n, n) array
        Adaptation gain Γ (a scalar, the diagonal, or an SPD matrix).

    References
    ----------
    Yi, Ortega & Zhang (2019), eqs. (34) and (47); Wang, Ortega & Bobtsov (2021), eq. (16a).
    """

    gamma: Any = 1.0
    kind = "gradient"
    reference = REF_GRADIENT

    def __post_init__(self) -> None:
        _check_gain_value(self.gamma, "gamma", "Gradient")
        object.__setattr__(self, "gamma", _freeze(self.gamma))

    def n_states(self, n_theta: int, q: int) -> int:
        return n_theta

    def build(self, stack: StateStack, reg: Regression, theta0: Any, prefix: str = "theta") -> Estimate:
        G = ca.DM(_gain(self.gamma, reg.n_theta, "gamma", "Gradient"))
        th = stack.add(f"{prefix}_hat", reg.n_theta, init=theta0)
        stack.set_flow(th, G @ reg.psi @ (reg.Y - reg.psi.T @ th))
        return Estimate(th, reg.psi)


@dataclass(frozen=True)
class LeastSquares(AbstractEstimator):
    r"""Least squares with forgetting factor β ≥ 0 (optionally with a bound on P):

    .. math::

        \dot{\hat\theta} = P\psi(\mathcal Y - \psi^\top\hat\theta), \qquad
        \dot P = \beta\Big(1 - \frac{\|P\|_F}{p_{\max}}\Big)P - P\psi\psi^\top P,
        \quad P(0) = P_0 .

    Without `p_max` the first term is :math:`\beta P`; with β > 0 and a regressor that is not
    persistently exciting P then grows without bound (the "covariance wind-up"), which
    `p_max` prevents. P is stored in full and kept exactly symmetric.

    Parameters
    ----------
    P0 : float or (n, n) array
        Initial gain P(0) (a scalar means P0·I), positive definite.
    forgetting : float
        β ≥ 0.
    p_max : float, optional
        Bound on the Frobenius norm of P (must exceed ‖P0‖_F).

    References
    ----------
    Ioannou & Sun (1996), §4.3.6 (least squares with forgetting and
    modified least squares with bounded gain).
    """

    P0: Any = 1.0
    forgetting: float = 0.0
    p_max: float | None = None
    kind = "least_squares"
    reference = REF_LS

    def __post_init__(self) -> None:
        _check_gain_value(self.P0, "P0", "LeastSquares")
        object.__setattr__(self, "P0", _freeze(self.P0))
        if not (np.isfinite(self.forgetting) and self.forgetting >= 0):
            raise PreconditionError(f"LeastSquares: `forgetting` must be a number >= 0, got {self.forgetting!r}")
        if self.p_max is not None:
            check_positive(self.p_max, "p_max", "LeastSquares")

    def n_states(self, n_theta: int, q: int) -> int:
        return n_theta + n_theta * n_theta

    def build(self, stack: StateStack, reg: Regression, theta0: Any, prefix: str = "theta") -> Estimate:
        n = reg.n_theta
        P0 = _gain(self.P0, n, "P0", "LeastSquares")
        if self.p_max is not None and np.linalg.norm(P0) >= self.p_max:
            raise PreconditionError(f"LeastSquares: `p_max` = {self.p_max:g} must exceed ‖P0‖_F = {np.linalg.norm(P0):.4g}")
        th = stack.add(f"{prefix}_hat", n, init=theta0)
        Pm = stack.add("P", n, n, init=P0)
        P = (Pm + Pm.T) / 2
        stack.set_flow(th, P @ reg.psi @ (reg.Y - reg.psi.T @ th))
        shrink = 1 if self.p_max is None else 1 - ca.norm_fro(P) / self.p_max
        dP = self.forgetting * shrink * P - P @ reg.psi @ reg.psi.T @ P
        stack.set_flow(Pm, (dP + dP.T) / 2)
        return Estimate(th, reg.psi)


@dataclass(frozen=True)
class DREM(AbstractEstimator):
    r"""Dynamic regressor extension and mixing.

    *Extension.* Either with stable LTI filters :math:`H_i(p) = \lambda_i/(p + \lambda_i)`
    (`lambdas`, one per extra block of rows; :math:`q(1 + k) = n_\theta` rows in all):

    .. math::

        \mathcal Y_e = \operatorname{col}(\mathcal Y, H_1[\mathcal Y], \dots), \qquad
        \Psi_e = \operatorname{col}(\psi^\top, H_1[\psi^\top], \dots),

    or, for any number of rows, with the Kreisselmeier filter (`kreisselmeier` = a > 0):
    :math:`\dot\Psi_e = -a\Psi_e + \psi\psi^\top`, :math:`\dot{\mathcal Y}_e = -a\mathcal Y_e + \psi\mathcal Y`.
    Either way :math:`\mathcal Y_e = \Psi_e\theta` (up to decaying transients).

    *Mixing.* With :math:`\Delta = \det\Psi_e` and :math:`\mathcal Y_m = \operatorname{adj}(\Psi_e)\mathcal Y_e`,
    one scalar regression per parameter, :math:`\mathcal Y_{m,i} = \Delta\theta_i`, estimated by

    .. math::

        \dot{\hat\theta}_i = \gamma_i\Delta(\mathcal Y_{m,i} - \Delta\hat\theta_i),

    which converges (monotonically, element by element) iff Δ is not square integrable.

    Parameters
    ----------
    gamma : float or sequence
        Gains γ_i (one for all, or one per parameter).
    lambdas : sequence of float, optional
        Filter poles λ_i > 0 for the LTI-filter extension.
    kreisselmeier : float, optional
        The pole a > 0 of the Kreisselmeier extension. Give exactly one of `lambdas`,
        `kreisselmeier` (default: Kreisselmeier with a = 1).

    References
    ----------
    Wang, Ortega & Bobtsov (2021), ref. [1] (Aranovskiy et al., IEEE TAC 62, 2017) and eqs. (17c)-(19)
    for the mixing step.
    """

    gamma: Any = 1.0
    lambdas: Sequence[float] | None = None
    kreisselmeier: float | None = None
    kind = "drem"
    reference = REF_DREM

    def __post_init__(self) -> None:
        _check_gain_value(self.gamma, "gamma", "DREM")
        object.__setattr__(self, "gamma", _freeze(self.gamma))
        if self.lambdas is not None and self.kreisselmeier is not None:
            raise PreconditionError("DREM: give either `lambdas` (LTI filters) or `kreisselmeier`, not both")
        if self.lambdas is not None:
            lam = tuple(float(v) for v in np.atleast_1d(np.asarray(self.lambdas, dtype=float)))
            for v in lam:
                if not (np.isfinite(v) and v > 0):
                    raise PreconditionError(f"DREM: every filter pole in `lambdas` must be positive (stable filter λ/(p+λ)), got {v}")
            if len(set(lam)) != len(lam):
                raise PreconditionError(f"DREM: the filter poles {lam} must be distinct, or the extended regressor is singular")
            object.__setattr__(self, "lambdas", lam)
        if self.kreisselmeier is not None:
            check_positive(self.kreisselmeier, "kreisselmeier", "DREM")

    def _rows(self, n: int, q: int) -> None:
        if self.lambdas is not None and q * (1 + len(self.lambdas)) != n:
            raise PreconditionError(
                f"DREM: the LTI-filter extension gives q·(1 + len(lambdas)) = {q}·{1 + len(self.lambdas)} = "
                f"{q * (1 + len(self.lambdas))} rows, but {n} parameters need exactly {n}: give "
                f"{n // q - 1 if n % q == 0 else 'a different number of'} filter pole(s), or use `kreisselmeier`")

    def n_states(self, n_theta: int, q: int) -> int:
        self._rows(n_theta, q)
        if self.lambdas is not None:
            return len(self.lambdas) * (q + n_theta * q) + n_theta
        return n_theta * n_theta + n_theta + n_theta

    def build(self, stack: StateStack, reg: Regression, theta0: Any, prefix: str = "theta") -> Estimate:
        n, q = reg.n_theta, reg.q
        self._rows(n, q)
        if self.lambdas is not None:
            Ys, Ps = [reg.Y], [reg.psi.T]
            for k, lam in enumerate(self.lambdas):
                Ys.append(lowpass(stack, reg.Y, lam, f"drem_Y{k + 1}"))
                Ps.append(lowpass(stack, reg.psi.T, lam, f"drem_psi{k + 1}"))
            Ye, Pe = ca.vertcat(*Ys), ca.vertcat(*Ps)
        else:
            a = 1.0 if self.kreisselmeier is None else float(self.kreisselmeier)
            Pe = stack.add("drem_Psi", n, n)
            Ye = stack.add("drem_Y", n)
            stack.set_flow(Pe, -a * Pe + reg.psi @ reg.psi.T)
            stack.set_flow(Ye, -a * Ye + reg.psi @ reg.Y)
        delta, adj = det_adj(Pe)
        Ym = adj @ Ye
        g = np.broadcast_to(np.asarray(self.gamma, dtype=float).ravel() if np.ndim(self.gamma) else float(self.gamma), (n,))
        th = stack.add(f"{prefix}_hat", n, init=theta0)
        stack.set_flow(th, ca.DM(g) * delta * (Ym - delta * th))
        return Estimate(th, reg.psi, delta)


@dataclass(frozen=True)
class GD(AbstractEstimator):
    r"""The G+D interlaced estimator (Wang, Ortega & Bobtsov (2021), Lemma 2, eqs. 16-17).

    .. math::

        \dot{\hat\theta}_g &= \gamma_g\psi(\mathcal Y - \psi^\top\hat\theta_g), \qquad
        \dot\Omega = -\gamma_g\psi\psi^\top\Omega, \quad \Omega(0) = I, \\
        D &= I - \Omega, \quad \Delta = \det D, \quad Y = \operatorname{adj}(D)(\hat\theta_g - \Omega\theta_{g0}), \\
        \dot{\hat\theta} &= \gamma\Delta(Y - \Delta\hat\theta).

    The gradient error is :math:`\tilde\theta_g = \Omega\tilde\theta_g(0)`, so
    :math:`D\theta = \hat\theta_g - \Omega\theta_{g0}` and :math:`Y = \Delta\theta` (Wang, Ortega & Bobtsov (2021), eqs. 18-19).
    If ψ is interval exciting (Wang, Ortega & Bobtsov (2021), eq. 15), Δ > 0 after the excitation interval and θ̂
    converges exponentially: no persistent excitation is needed.

    Choice: :math:`\hat\theta_g(0) = \theta_{g0} = 0`. This loses nothing: the signal
    :math:`\hat\theta_g - \Omega\theta_{g0}` obeys the gradient equation started from 0 whatever
    :math:`\theta_{g0}` is (subtract the two equations), so Y does not depend on it. The states are
    θ̂_g (n), Ω (n²) and θ̂ (n).

    Parameters
    ----------
    gamma_g : float
        Gain of the gradient stage, γ_g > 0.
    gamma : float
        Gain of the scalar-regressor stage, γ > 0.

    References
    ----------
    Wang, Ortega & Bobtsov (2021), eqs. (16)-(19), Lemma 2; interval excitation eq. (15).
    """

    gamma_g: float = 1.0
    gamma: float = 1.0
    kind = "gd"
    reference = REF_GD

    def __post_init__(self) -> None:
        check_positive(self.gamma_g, "gamma_g", "GD")
        check_positive(self.gamma, "gamma", "GD")

    def n_states(self, n_theta: int, q: int) -> int:
        return 2 * n_theta + n_theta * n_theta

    def build(self, stack: StateStack, reg: Regression, theta0: Any, prefix: str = "theta") -> Estimate:
        n = reg.n_theta
        th_g = stack.add(f"{prefix}_g", n)
        Om = stack.add("Omega", n, n, init=np.eye(n))
        th = stack.add(f"{prefix}_hat", n, init=theta0)
        gg = float(self.gamma_g)
        stack.set_flow(th_g, gg * reg.psi @ (reg.Y - reg.psi.T @ th_g))       # (16a)
        stack.set_flow(Om, -gg * reg.psi @ reg.psi.T @ Om)                   # (16b), (17a)
        D = ca.DM.eye(n) - Om                                                # (17b)
        delta, adj = det_adj(D)                                              # (17c)
        Ymix = adj @ th_g                                                    # (17d) with θ_g0 = 0
        stack.set_flow(th, float(self.gamma) * delta * (Ymix - delta * th))  # (16c)
        return Estimate(th, reg.psi, delta)


_ESTIMATORS: dict[str, type[AbstractEstimator]] = {"gradient": Gradient, "least_squares": LeastSquares, "drem": DREM, "gd": GD}


def estimator_from(value: Any, *, default: AbstractEstimator, caller: str) -> AbstractEstimator:
    """An estimator object from an estimator, None (the default) or a model-file table
    ``{kind = "gd", gamma_g = 5, gamma = 50}``."""
    if value is None:
        return default
    if isinstance(value, AbstractEstimator):
        return value
    if isinstance(value, Mapping):
        opts = dict(value)
        kind = opts.pop("kind", None)
        if kind not in _ESTIMATORS:
            raise PreconditionError(f"{caller}: `estimator.kind` must be one of {', '.join(_ESTIMATORS)}, got {kind!r}")
        cls = _ESTIMATORS[kind]
        allowed = [f for f in cls.__dataclass_fields__]
        unknown = [k for k in opts if k not in allowed]
        if unknown:
            raise PreconditionError(f"{caller}: unknown option `{unknown[0]}` for estimator {kind!r}; it accepts: {', '.join(allowed)}")
        return cls(**opts)
    raise PreconditionError(f"{caller}: `estimator` must be an estimator (Gradient, LeastSquares, DREM, GD) or a table with "
                            f"`kind`; got {type(value).__name__}")


# ---------------------------------------------------------------------------------------------
# Excitation monitoring
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ExcitationMonitor:
    """The regressor (and mixed regressor Δ) of an estimator as a function of the observer's
    signals; stored in the certificate as ``values["excitation monitor"]`` and evaluated by
    :func:`excitation_report`."""

    fn: ca.Function
    n_theta: int
    q: int
    has_delta: bool
    estimator: str

    @classmethod
    def of(cls, stack: StateStack, est: Estimate, estimator: AbstractEstimator) -> ExcitationMonitor:
        n, q = est.psi.shape
        outs = [ca.vec(est.psi), est.delta if est.delta is not None else ca.SX(0)]
        fn = ca.Function("excitation_monitor", [stack.t, stack.z, stack.u, stack.y], outs, ["t", "z", "u", "y"], ["psi", "delta"])
        return cls(fn, n, q, est.delta is not None, estimator.kind)

    def __str__(self) -> str:
        return (f"ψ ({self.n_theta}x{self.q})" + (" and Δ" if self.has_delta else "")
                + " along a run: nlobs.design.excitation_report(design, t, z, u, y)")


@dataclass(frozen=True, eq=False)
class ExcitationReport:
    r"""The excitation an estimator saw along a run.

    Attributes
    ----------
    t : numpy.ndarray
    ie_level : numpy.ndarray
        :math:`\lambda_{\min}\int_0^t\psi\psi^\top ds` at each time: the interval-excitation level
        :math:`C_d` reached by t (Wang, Ortega & Bobtsov (2021), eq. 15); 0 while the regression is not identifiable.
    ie_time : float or None
        First time the IE level exceeds `tol` (the :math:`t_d` of Wang, Ortega & Bobtsov (2021), eq. 15).
    pe_level : float or None
        :math:`\min_{t_0}\lambda_{\min}\int_{t_0}^{t_0+T}\psi\psi^\top` over the run for the window T
        (the δ of a PE condition, Yi, Ortega & Zhang (2019), eq. 42); None without a window.
    window : float or None
    delta : numpy.ndarray or None
        The mixed scalar regressor Δ(t) (DREM, G+D).
    delta_time : float or None
        First time abs(Δ) exceeds `tol` (Wang, Ortega & Bobtsov (2021), Lemma 2: Δ ≠ 0 for t ≥ t_d under IE).
    tol : float
    """

    t: np.ndarray
    ie_level: np.ndarray
    ie_time: float | None
    pe_level: float | None
    window: float | None
    delta: np.ndarray | None
    delta_time: float | None
    tol: float

    def __str__(self) -> str:
        parts = [f"IE level λmin∫ψψᵀ = {self.ie_level[-1]:.4g} at t = {self.t[-1]:g}",
                 "IE reached " + ("never" if self.ie_time is None else f"at t_d = {self.ie_time:.4g}")]
        if self.window is not None:
            parts.append(f"PE level over windows of {self.window:g}: {self.pe_level:.4g}")
        if self.delta is not None:
            parts.append(f"|Δ| > {self.tol:g} " + ("never" if self.delta_time is None else f"from t = {self.delta_time:.4g}")
                         + f", final Δ = {self.delta[-1]:.4g}")
        return "; ".join(parts)


def _first_above(t: np.ndarray, v: np.ndarray, tol: float) -> float | None:
    idx = np.flatnonzero(v > tol)
    return None if idx.size == 0 else float(t[idx[0]])


def excitation_report(design: ObserverDesign, t: Any, z: Any, u: Any = None, y: Any = None, *,
                      window: float | None = None, tol: float = 1e-6) -> ExcitationReport:
    """Evaluate an estimator's regressor along a run and measure its excitation.

    Parameters
    ----------
    design : ObserverDesign
        A design built with a regression estimator (its certificate holds an excitation monitor).
    t : array_like of shape (N,)
    z : array_like of shape (N, n_z)
        The observer's internal states (``run.observers[name].z``).
    u, y : array_like of shape (N, m), (N, p), optional
        The inputs and measurements the observer saw (``run.u``, ``run.y``).
    window : float, optional
        Window T for the persistent-excitation level.
    tol : float
        Threshold for "non-zero".

    Raises
    ------
    PreconditionError
        If the design has no regression estimator.
    """
    mon = design.certificate.values.get("excitation monitor")
    if not isinstance(mon, ExcitationMonitor):
        raise PreconditionError(f"excitation_report: the {design.method!r} design has no regression estimator to report on")
    t = np.asarray(t, dtype=float).reshape(-1)
    N = t.size
    s = design.system
    Z = np.asarray(z, dtype=float).reshape(N, -1)
    U = np.zeros((N, s.n_inputs)) if u is None else np.asarray(u, dtype=float).reshape(N, s.n_inputs)
    Yv = np.zeros((N, s.n_outputs)) if y is None else np.asarray(y, dtype=float).reshape(N, s.n_outputs)
    psi_vec, delta = mon.fn.map(N)(ca.DM(t[None, :]), ca.DM(Z.T), ca.DM(U.T), ca.DM(Yv.T))
    psi = np.asarray(psi_vec).T.reshape(N, mon.q, mon.n_theta).transpose(0, 2, 1)  # (N, n, q), column-major vec
    outer = np.einsum("kiq,kjq->kij", psi, psi)
    cum = np.concatenate([np.zeros((1, mon.n_theta, mon.n_theta)),
                          np.cumsum(0.5 * (outer[1:] + outer[:-1]) * np.diff(t)[:, None, None], axis=0)])
    ie = np.linalg.eigvalsh(cum)[:, 0]
    pe = None
    if window is not None:
        check_positive(window, "window", "excitation_report")
        if window > t[-1] - t[0]:
            raise PreconditionError(f"excitation_report: `window` = {window:g} is longer than the run ({t[-1] - t[0]:g})")
        j = np.searchsorted(t, t + window - 1e-12 * max(1.0, window))
        ok = j < N
        pe = float(np.linalg.eigvalsh(cum[j[ok]] - cum[ok])[:, 0].min())
    d = np.asarray(delta).reshape(-1) if mon.has_delta else None
    return ExcitationReport(t, ie, _first_above(t, ie, tol), pe, window, d,
                            None if d is None else _first_above(t, np.abs(d), tol), tol)


# ---------------------------------------------------------------------------------------------
# Regression models and the estimator designs
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, init=False)
class LinearRegression:
    r"""A regression model :math:`\mathcal Y = \psi(s, t)^\top\theta + d(s, t)` with θ constant.

    θ is the state of the system :math:`\dot\theta = 0`, the regressor ψ is built from
    measured signals s (the model's inputs) and time, and :math:`\mathcal Y` is its output, so the
    estimators are observers of this system (:func:`design_gradient`, ...) and run on simulated
    or recorded data like any observer.

    Parameters
    ----------
    psi : (n_theta, q) matrix of expressions in the signals and ``t``
        A (n_theta,) vector for a scalar regression.
    signals : sequence of str, optional
        Names of the measured signals ψ is built from (default ``psi1..psin`` with ψ = them).
    theta : sequence of str, optional
        Parameter names (default ``theta1..``).
    outputs : sequence of str, optional
        Names of the rows of :math:`\mathcal Y` (default ``Y`` or ``Y1..``).
    offset : sequence of expressions, optional
        A known term d(s, t) (default 0).
    name : str, optional

    Examples
    --------
    >>> reg = LinearRegression(["psi1", "psi2"], signals=["psi1", "psi2"])
    >>> reg.to_system().h
    (psi1*theta1 + psi2*theta2,)
    """

    psi: sp.Matrix
    offset: sp.Matrix
    signals: tuple[str, ...]
    theta: tuple[str, ...]
    outputs: tuple[str, ...]
    name: str

    def __init__(self, psi: Any = None, *, signals: Sequence[str] | None = None, theta: Sequence[str] | None = None,
                 outputs: Sequence[str] | None = None, offset: Any = None, name: str = "regression"):
        if psi is None and signals is None:
            raise ShapeError("LinearRegression: give `psi` or `signals`")
        arr = np.array(psi if psi is not None else list(signals), dtype=object)
        if arr.ndim == 1:
            arr = arr.reshape(-1, 1)
        n, q = arr.shape
        sig = tuple(signals) if signals is not None else tuple(f"psi{i + 1}" for i in range(n * q))
        th = tuple(theta) if theta is not None else tuple(f"theta{i + 1}" for i in range(n))
        outs = tuple(outputs) if outputs is not None else (("Y",) if q == 1 else tuple(f"Y{i + 1}" for i in range(q)))
        allowed = {k: symbol(k) for k in sig}
        allowed["t"] = TIME
        object.__setattr__(self, "psi", matrix_of(arr, n, q, allowed, name="psi"))
        object.__setattr__(self, "offset", matrix_of(offset if offset is not None else [0] * q, q, 1, allowed, name="offset"))
        object.__setattr__(self, "signals", sig)
        object.__setattr__(self, "theta", th)
        object.__setattr__(self, "outputs", outs)
        object.__setattr__(self, "name", name)
        if len(th) != n or len(outs) != q:
            raise ShapeError(f"LinearRegression: ψ is {n}x{q}: give {n} parameter name(s) and {q} output name(s)")
        self.to_system()  # validates names

    def to_system(self) -> System:
        th = sp.Matrix([symbol(k) for k in self.theta])
        h = self.psi.T * th + self.offset
        return System(states=self.theta, f=[0] * len(self.theta), outputs=self.outputs, h=list(h),
                      inputs=self.signals, name=self.name)

    @staticmethod
    def parts_of(system: System) -> tuple[sp.Matrix, sp.Matrix]:
        """(ψ, d) of a system with :math:`\\dot\\theta = 0` and outputs affine in the states.

        Raises
        ------
        FormError
            Naming the equation that breaks the form.
        """
        f, h = system.substituted()
        for name, e in zip(system.states, f):
            if e != 0:
                raise FormError(f"{system.name!r} is not a regression model: {name}' = {e}; the parameters must be constant (θ' = 0)")
        x = sp.Matrix(system.x)
        J = h.jacobian(x)
        for i, name in enumerate(system.outputs):
            bad = [s.name for s in set().union(*[e.free_symbols for e in J.row(i)]) if s in set(system.x)]
            if bad:
                raise FormError(f"{system.name!r} is not a regression model: output {name} = {h[i]} is not linear in the "
                                f"parameters (its derivative depends on {', '.join(sorted(bad))})")
        return J.T, sp.expand(h - J * x)


def _regression_system(system: System | LinearRegression, caller: str) -> tuple[System, sp.Matrix, sp.Matrix]:
    sys_ = system.to_system() if isinstance(system, LinearRegression) else system
    if not isinstance(sys_, System):
        raise TypeError(f"{caller}: expected a System or a LinearRegression, got {type(system).__name__}")
    try:
        psi, d = LinearRegression.parts_of(sys_)
    except FormError as e:
        raise PreconditionError(f"{caller}: {e}. Build the model with nlobs.design.LinearRegression.") from e
    return sys_, psi, d


def _design_estimator(system: System | LinearRegression, estimator: AbstractEstimator, method: str, caller: str,
                      xhat0: Any) -> ObserverDesign:
    sys_, psi, d = _regression_system(system, caller)
    stack = StateStack(sys_)
    leaves = stack.leaves()
    n, q = psi.shape
    reg = Regression(stack.y - to_casadi(list(d), leaves), sx_matrix(psi, leaves), sys_.states)
    est = estimator.build(stack, reg, stack.xhat0)
    checks = [Check("model is a linear regression Y = ψ(s, t)ᵀθ + d with θ constant", True,
                    f"{n} parameter(s), {q} row(s)")]
    values = {"psi": str(psi.tolist()), **estimator.describe(), "internal states": stack.n_z,
              "excitation monitor": ExcitationMonitor.of(stack, est, estimator)}
    cert = Certificate(f"{type(estimator).__name__} parameter estimator", estimator.reference, tuple(checks), values)
    return stack.build(method, xhat=est.theta, certificate=cert, xhat0=xhat0)


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def regression_tuning(kind: str) -> Callable[[Any], Tuning]:
    def trial(ctx: Any) -> Tuning:
        f, h = ctx.system.substituted()
        moving = [f"{s}' = {e}" for s, e in zip(ctx.system.states, f) if e != 0]
        if moving:
            return Tuning.fails(f"estimates constant parameters θ of a linear regression y = ψ(u, t)ᵀθ (θ' = 0); here {moving[0]}. "
                          "For a state-affine model, gpebo and gpebo_2gd build such a regression from the state")
        if ctx.nominal is None:
            return Tuning.needs("a run ([simulation] x0) to scale the gains")
        H = sp.Matrix(h).jacobian(sp.Matrix(ctx.system.x))
        psi = evaluate(list(H), ctx.system, ctx.samples(400))
        level = float(np.mean(np.sum(psi ** 2, axis=1))) or 1.0
        g = round(float(ctx.omega_o / level), 9)
        opts = {"gradient": {"gamma": g}, "least_squares": {"P0": g}, "drem": {"gamma": g},
                "gd": {"gamma_g": g, "gamma": round(10 * g, 9)}}[kind]
        return Tuning.tuned(opts, f"regression model; gains from ω_o / mean ‖ψ‖² = {g:.3g}")

    return trial


@kind('gradient', summary='gradient estimator of θ in a linear regression Y = ψᵀθ + d',
      references=(work("000", "eq. 16a (gradient)"),), tune=regression_tuning("gradient"))
def design_gradient(system: System | LinearRegression, *, gamma: Any = 1.0, xhat0: Any = None) -> ObserverDesign:
    r"""Gradient estimator of θ in :math:`\mathcal Y = \psi^\top\theta + d` (see :class:`Gradient`).

    Parameters
    ----------
    system : System or LinearRegression
        A regression model (θ' = 0, outputs affine in θ with coefficients in the inputs and t).
    gamma : float, sequence or (n, n) array
        Adaptation gain Γ.
    xhat0 : array_like, optional
        θ̂(0) (zeros).

    Raises
    ------
    PreconditionError
        If the model is not a regression model or Γ is not positive definite.

    References
    ----------
    Yi, Ortega & Zhang (2019), eq. (34); Wang, Ortega & Bobtsov (2021), eq. (16a).
    """
    return _design_estimator(system, Gradient(gamma), "gradient", "design_gradient", xhat0)


@kind('least_squares', summary='least-squares estimator of θ in a linear regression, with forgetting',
      references=(work("000", "regression estimators (least squares)"),), tune=regression_tuning("least_squares"))
def design_least_squares(system: System | LinearRegression, *, P0: Any = 1.0, forgetting: float = 0.0,
                         p_max: float | None = None, xhat0: Any = None) -> ObserverDesign:
    r"""Least-squares estimator with forgetting (see :class:`LeastSquares`).

    Parameters
    ----------
    system : System or LinearRegression
    P0 : float or (n, n) array
        Initial gain, positive definite.
    forgetting : float
        Forgetting factor β ≥ 0.
    p_max : float, optional
        Bound on ‖P‖_F.
    xhat0 : array_like, optional
        θ̂(0).

    References
    ----------
    Ioannou & Sun (1996), §4.3.6.
    """
    return _design_estimator(system, LeastSquares(P0, forgetting, p_max), "least_squares", "design_least_squares", xhat0)


@kind('drem', summary='DREM estimator: extension by stable LTI filters, mixing with the adjugate',
      references=(work("aranovskiy2017"),), tune=regression_tuning("drem"))
def design_drem(system: System | LinearRegression, *, gamma: Any = 1.0, lambdas: Sequence[float] | None = None,
                kreisselmeier: float | None = None, xhat0: Any = None) -> ObserverDesign:
    r"""DREM estimator: extension by stable LTI filters, mixing with the adjugate (see :class:`DREM`).

    Parameters
    ----------
    system : System or LinearRegression
    gamma : float or sequence
        Gains of the scalar regressions.
    lambdas : sequence of float, optional
        Poles of the extension filters λ/(p + λ).
    kreisselmeier : float, optional
        Pole of the Kreisselmeier extension (the default, a = 1, when neither is given).
    xhat0 : array_like, optional
        θ̂(0).

    References
    ----------
    Aranovskiy et al., IEEE TAC 62 (2017) (Wang, Ortega & Bobtsov (2021), ref. [1]).
    """
    return _design_estimator(system, DREM(gamma, lambdas, kreisselmeier), "drem", "design_drem", xhat0)


@kind('gd', summary='G+D interlaced estimator: converges under interval excitation',
      references=(work("000", "Lemma 2"),), tune=regression_tuning("gd"))
def design_gd(system: System | LinearRegression, *, gamma_g: float = 1.0, gamma: float = 1.0,
              xhat0: Any = None) -> ObserverDesign:
    r"""G+D interlaced estimator (Wang, Ortega & Bobtsov (2021), Lemma 2, eqs. 16-17; see :class:`GD`): converges under
    interval excitation (identifiability) only.

    Parameters
    ----------
    system : System or LinearRegression
    gamma_g, gamma : float
        Gains of the gradient stage and of the scalar stage.
    xhat0 : array_like, optional
        θ̂(0).

    References
    ----------
    Wang, Ortega & Bobtsov (2021), eqs. (15)-(19), Lemma 2.
    """
    return _design_estimator(system, GD(gamma_g, gamma), "gd", "design_gd", xhat0)
