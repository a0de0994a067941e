r"""KKL (Yi, Ortega & Zhang (2019), Prop. 1), PEBO (Prop. 2) and KKL+PEBO (Prop. 3) observers.

All three rest on one PDE for an injection :math:`B(y, u)` and a map φ with a left inverse
:math:`\phi^L(\phi(x), h(x)) = x` (Yi, Ortega & Zhang (2019), eqs. 4-5):

.. math::

    \nabla\phi^\top(x) f(x, u) = \Lambda\phi(x) + B(h(x), u).

With :math:`\Lambda = \operatorname{diag}(\Lambda_L, 0)` (eq. 14) the components with λ < 0 form a
KKL observer (:math:`\xi_L - \phi_L(x) \to 0`) and those with λ = 0 a PEBO
(:math:`\phi_P(x) = \xi_P + \theta`, θ constant, eq. 9); θ is estimated from a regression on the
outputs and their (filtered) derivatives, Yi, Ortega & Zhang (2019), eq. (11):

.. math::

    \dot y = \nabla h^\top f\big(\phi^L(\xi + E\theta, y), u\big) = a(\xi, y, u) + b(\xi, y, u)^\top\theta
    \;\Longrightarrow\; W[y] - F[a] = F[b]^\top\theta + \epsilon_t ,

with :math:`F = \alpha/(p+\alpha)`, :math:`W = \alpha p/(p+\alpha)` (Yi, Ortega & Zhang (2019), eq. 37) when the right-hand
side is affine in θ (possibly after a reparametrisation Θ = Θ(θ), as Yi, Ortega & Zhang (2019), §V-A does with
:math:`\Theta = e^\theta`), and otherwise a windowed nonlinear least-squares fit of θ
(:class:`WindowedNLS`). R5: a constant Λ that is only *similar* to the form (14),
:math:`\Lambda = P^{-1}\operatorname{diag}(\Lambda_L, 0)P`, is handled in the coordinates Pφ.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ...algebra._identity import decide_identity
from ...engine import to_casadi
from ...errors import FormError, PreconditionError, ShapeError
from ...model import TIME, System, symbol
from ...model._forms import matrix_of
from ...model._system import exact
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign
from .._checks import identity_check
from .._constructions import kkl_linear, pebo_linear
from .._tune import needs_only
from .._kind import Tuning, kind
from ._regression import ExcitationMonitor, Gradient, Regression, StateStack, estimator_from, lowpass, sx_matrix
from .._tune import clean_message, output_injection_form

__all__ = ["design_kkl", "design_pebo", "design_kkl_pebo", "WindowedNLS"]

REF_KKL = f"{cite('004')} Proposition 1: PDE (4), left inverse (5), observer (6)"
REF_PEBO = f"{cite('004')} Proposition 2: eqs. (7)-(13); regression (11) filtered as in (37)"
REF_KKLPEBO = f"{cite('004')} Proposition 3: eqs. (14)-(15), remarks R4-R5; regression (11) filtered as in (37)"


# ---------------------------------------------------------------------------------------------
# Symbolic helpers
# ---------------------------------------------------------------------------------------------
def _pde_hint(phi_i: sp.Expr, drift_i: sp.Expr) -> str:
    """Which λ would make component i satisfy its PDE, when one exists (drift = ∇φ_iᵀf - B_i)."""
    if phi_i == 0:
        return ""
    mu = sp.simplify(drift_i / phi_i)
    if mu.free_symbols:
        return ""
    mu_f = float(mu)
    if mu_f == 0:
        return (f" This component obeys d/dt φ = B(y, u) (λ = 0): it is a PEBO component ({cite('004')} Prop. 2), not a KKL one; "
                f"put it in the PEBO part with design_kkl_pebo ({cite('004')} Prop. 3).")
    if mu_f < 0:
        return (f" This component obeys d/dt φ = {mu}·φ + B(y, u): it is a KKL component with λ = {mu} ({cite('004')} Prop. 1), not a "
                f"PEBO one; put it in the KKL part with design_kkl_pebo ({cite('004')} Prop. 3).")
    return f" This component obeys d/dt φ = {mu}·φ + B(y, u) with {mu} > 0: an unstable mode, neither KKL nor PEBO applies."


@dataclass(frozen=True)
class _Maps:
    phi: sp.Matrix      # (n_xi, 1) in the states
    left: sp.Matrix     # (n, 1) in xi1.., the outputs
    B: sp.Matrix        # (n_xi, 1) in the outputs, inputs, t
    Lam: sp.Matrix      # (n_xi, n_xi) in the inputs, t
    xi: tuple[sp.Symbol, ...]


def _parse_maps(system: System, phi: Any, left_inverse: Any, B: Any, Lambda: Any, caller: str) -> _Maps:
    params = {symbol(k): exact(v) for k, v in system.params.items()}
    base = {k: symbol(k) for k in system.params}
    base["t"] = TIME
    if isinstance(phi, (str, sp.Basic)) or not isinstance(phi, Sequence) and not isinstance(phi, sp.MatrixBase):
        raise ShapeError(f"{caller}: `phi` must be a list of expressions (one per component of ξ), got {phi!r}")
    n_xi = len(phi) if not isinstance(phi, sp.MatrixBase) else phi.shape[0]
    if n_xi == 0:
        raise ShapeError(f"{caller}: `phi` is empty; give at least one component")
    xi = tuple(symbol(f"xi{i + 1}") for i in range(n_xi))
    clash = [s.name for s in xi if s.name in (*system.states, *system.inputs, *system.outputs, *system.params)]
    if clash:
        raise PreconditionError(f"{caller}: the model declares `{clash[0]}`, which is the name nlobs gives to ξ in "
                                "`left_inverse`; rename that state, input, output or parameter")
    phi_m = matrix_of(phi, n_xi, 1, {**base, **{k: symbol(k) for k in system.states}}, name="phi").xreplace(params)
    left_m = matrix_of(left_inverse, system.n_states, 1,
                       {**base, **{k: symbol(k) for k in system.outputs}, **{s.name: s for s in xi}},
                       name="left_inverse").xreplace(params)
    B_m = matrix_of(B, n_xi, 1, {**base, **{k: symbol(k) for k in (*system.outputs, *system.inputs)}}, name="B").xreplace(params)
    lam_allowed = {**base, **{k: symbol(k) for k in system.inputs}}
    if Lambda is None:
        Lam = sp.zeros(n_xi, n_xi)
    elif isinstance(Lambda, sp.MatrixBase) or np.ndim(np.array(Lambda, dtype=object)) == 2:
        Lam = matrix_of(Lambda, n_xi, n_xi, lam_allowed, name="Lambda")
    else:  # the diagonal (a scalar for a single component)
        Lam = sp.diag(*matrix_of(np.array(Lambda, dtype=object).reshape(-1), n_xi, 1, lam_allowed, name="Lambda"))
    return _Maps(phi_m, left_m, B_m, Lam.xreplace(params), xi)


def _check_left_inverse(system: System, m: _Maps, caller: str) -> Check:
    _, h = system.substituted()
    subs = {**dict(zip(m.xi, m.phi)), **{symbol(k): h[i] for i, k in enumerate(system.outputs)}}
    verdicts = []
    for i, x in enumerate(system.x):
        v = decide_identity(m.left[i].xreplace(subs), x, seed=i)
        if v.fails:
            raise PreconditionError(
                f"{caller}: `left_inverse` is not a left inverse of φ ({cite('004')} eq. 5): φ^L(φ(x), h(x)) gives "
                f"{sp.simplify(m.left[i].xreplace(subs))} for {system.states[i]}, not {system.states[i]}{v.where()}. "
                "φ must be injective (given y) and φ^L must invert it.")
        verdicts.append(v)
    return identity_check(f"φ^L(φ(x), h(x)) = x ({cite('004')} eq. 5)", verdicts, [f"state {s_}" for s_ in system.states])


def _check_pde(system: System, m: _Maps, caller: str, what: str) -> Check:
    f, h = system.substituted()
    B_hx = m.B.xreplace({symbol(k): h[i] for i, k in enumerate(system.outputs)})
    drift = m.phi.jacobian(sp.Matrix(system.x)) * f - B_hx
    diagonal = all(m.Lam[i, j] == 0 for i in range(m.Lam.shape[0]) for j in range(m.Lam.shape[1]) if i != j)
    verdicts = []
    for i in range(m.phi.shape[0]):
        rhs = (m.Lam * m.phi)[i]
        v = decide_identity(drift[i], rhs, seed=i)
        verdicts.append(v)
        if not v.fails:
            continue
        resid = sp.simplify(drift[i] - rhs)
        states = sorted(s.name for s in resid.free_symbols if s in set(system.x))
        dep = (f"; it depends on the state(s) {', '.join(states)}, which an injection B(y, u) cannot cancel" if states else "")
        hint = _pde_hint(m.phi[i], drift[i]) if diagonal else ""
        lam = f"λ = {m.Lam[i, i]}" if diagonal else "Λ"
        raise PreconditionError(
            f"{caller}: the {what} PDE ∇φᵀf = Λφ + B(h(x), u) ({cite('004')} eq. 4) fails for component {i + 1} "
            f"(φ_{i + 1} = {m.phi[i]}, {lam}): the residual is {resid}, not 0{v.where()}{dep}.{hint}")
    return identity_check(f"{what} PDE ∇φᵀf = Λφ + B(h(x), u) ({cite('004')} eq. 4)", verdicts,
                          [f"component {i + 1}" for i in range(m.phi.shape[0])])


def _partition(Lam: sp.Matrix, caller: str) -> tuple[sp.Matrix, sp.Matrix, list[sp.Expr], list[int], list[int], list[Check]]:
    """(P, P⁻¹, diagonal λ's, KKL indices, PEBO indices, checks) with Λ = P⁻¹ diag(λ) P (R5)."""
    n = Lam.shape[0]
    diagonal = all(Lam[i, j] == 0 for i in range(n) for j in range(n) if i != j)
    checks: list[Check] = []
    if diagonal:
        P = Pinv = sp.eye(n)
        lam = [Lam[i, i] for i in range(n)]
    else:
        if Lam.free_symbols:
            raise PreconditionError(f"{caller}: a non-diagonal Λ must be constant ({cite('004')} R5: Λ = P⁻¹ diag(Λ_L, 0) P); it contains "
                                    f"{', '.join(sorted(s.name for s in Lam.free_symbols))}")
        Lr = Lam.applyfunc(lambda e: sp.nsimplify(e, rational=True))
        try:
            V, D = Lr.diagonalize()
        except sp.matrices.exceptions.NonSquareMatrixError as e:  # pragma: no cover - Λ is square by construction
            raise PreconditionError(f"{caller}: Λ must be square") from e
        except sp.matrices.exceptions.MatrixError as e:
            raise PreconditionError(f"{caller}: Λ = {Lam.tolist()} is not diagonalisable, so it is not similar to the form (14) "
                                    f"({cite('004')} R5): a Jordan block makes ξ grow; choose another Λ") from e
        lam = [sp.nsimplify(D[i, i]) for i in range(n)]
        bad = [v for v in lam if not v.is_real]
        if bad:
            raise PreconditionError(f"{caller}: Λ has the complex eigenvalue {bad[0]}; {cite('004')} R5 needs Λ similar to the real "
                                    f"diagonal form (14) (footnote 3 of {cite('004')} covers imaginary eigenvalues, which nlobs does not)")
        Pinv, P = V, V.inv()
        checks.append(Check(f"Λ similar to the form (14): Λ = P⁻¹ diag(λ) P ({cite('004')} R5)", True, f"eigenvalues {lam}"))
    kkl, pebo = [], []
    for i, v in enumerate(lam):
        if v == 0:
            pebo.append(i)
            continue
        if not v.free_symbols:
            if float(v) > 0:
                raise PreconditionError(f"{caller}: λ_{i + 1} = {v} > 0; a KKL component needs λ < 0 ({cite('004')} A1) and a PEBO "
                                        "component λ = 0. Change Λ.")
        kkl.append(i)
    return P, Pinv, lam, kkl, pebo, checks


# ---------------------------------------------------------------------------------------------
# Windowed nonlinear least squares for θ
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class WindowedNLS:
    r"""Windowed nonlinear least squares for the constant θ of a PEBO (used when the regression
    (11) is not linear in θ).

    Every ``window / (samples - 1)`` seconds the observer stores the sample
    :math:`s_j = (t_j, y_j, u_j, \xi_j)`; once the window is full, θ̂ is refined by `iterations`
    Levenberg-Marquardt steps on

    .. math::

        \min_\theta \sum_{j=1}^{M-1}\Big|y_j - y_0 - \int_{t_0}^{t_j} g(\theta; s)\,dt\Big|^2
        \quad\big(+ \sum_j |y_j - h(\phi^L(\xi_j + E\theta, y_j))|^2 \text{ for algebraic rows}\big),

    with :math:`g = \nabla h^\top f(\phi^L(\xi + E\theta, y), u)` (the right-hand side of Yi, Ortega & Zhang (2019), eq. 11)
    and the integral on the stored samples by Simpson's rule (odd `samples`, residuals at every
    second sample, error O(h⁴)) or the trapezoidal rule (even `samples`, O(h²)). The data enter through
    output increments, so no derivative of y is taken. The fit runs at sample instants (the
    observer's update, :math:`z^+ = J(t, z^-, u, y)`); samples with a missing output are skipped.

    Parameters
    ----------
    window : float
        Length of the data window (seconds).
    samples : int
        Stored samples M ≥ 3, spaced window / (M - 1); odd M uses Simpson's rule.
    iterations : int
        Levenberg-Marquardt steps per new sample.
    damping : float
        Levenberg-Marquardt damping μ > 0: :math:`(J^\top J + \mu(I + \operatorname{diag}J^\top J))\delta = -J^\top r`.
    """

    window: float
    samples: int = 21
    iterations: int = 2
    damping: float = 1e-6
    kind = "windowed_nls"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.window) and self.window > 0):
            raise PreconditionError(f"WindowedNLS: `window` must be a positive number of seconds, got {self.window!r}")
        if int(self.samples) != self.samples or self.samples < 3:
            raise PreconditionError(f"WindowedNLS: `samples` must be an integer >= 3, got {self.samples!r}")
        if int(self.iterations) != self.iterations or self.iterations < 1:
            raise PreconditionError(f"WindowedNLS: `iterations` must be an integer >= 1, got {self.iterations!r}")
        if not (np.isfinite(self.damping) and self.damping > 0):
            raise PreconditionError(f"WindowedNLS: `damping` must be positive, got {self.damping!r}")

    def describe(self) -> dict[str, Any]:
        return {"windowed_nls.window": self.window, "windowed_nls.samples": self.samples,
                "windowed_nls.iterations": self.iterations, "windowed_nls.damping": self.damping}


def _build_nls(stack: StateStack, nls: WindowedNLS, xi_sx: ca.SX, g_der: ca.Function | None, der_rows: list[int],
               g_alg: ca.Function | None, alg_rows: list[int], n_theta: int, theta0: Any) -> ca.SX:
    """Add θ̂, the sample buffer and its fill count; return θ̂. g(θ, ξ, y, u) -> rows."""
    sysm = stack.system
    p, m, n_xi = sysm.n_outputs, sysm.n_inputs, xi_sx.shape[0]
    d, M = 1 + p + m + n_xi, int(nls.samples)
    spacing = nls.window / (M - 1)
    th = stack.add("theta_hat", n_theta, init=theta0)
    buf = stack.add("nls_buffer", M, d)
    count = stack.add("nls_count", 1)
    for blk in (th, buf, count):
        stack.set_flow(blk, ca.SX.zeros(*blk.shape))
    # the Levenberg-Marquardt step as a function of (θ, buffer)
    T, Bs = ca.SX.sym("theta", n_theta), ca.SX.sym("B", M, d)
    rows = []
    ts, ys, us, xs = Bs[:, 0], Bs[:, 1:1 + p], Bs[:, 1 + p:1 + p + m], Bs[:, 1 + p + m:]
    if g_der is not None:
        gs = [g_der(T, xs[j, :].T, ys[j, :].T, us[j, :].T) for j in range(M)]
        acc = ca.SX.zeros(len(der_rows), 1)
        if M % 2:  # Simpson's rule on pairs of (possibly unequal) intervals: residuals at even j, error O(h^4)
            for j in range(2, M, 2):
                h1, h2 = ts[j - 1] - ts[j - 2], ts[j] - ts[j - 1]
                acc = acc + (h1 + h2) / 6 * ((2 - h2 / h1) * gs[j - 2] + (h1 + h2) ** 2 / (h1 * h2) * gs[j - 1]
                                             + (2 - h1 / h2) * gs[j])
                rows.append(ys[j, der_rows].T - ys[0, der_rows].T - acc)
        else:      # trapezoidal rule, residual at every sample, error O(h^2)
            for j in range(1, M):
                acc = acc + (ts[j] - ts[j - 1]) / 2 * (gs[j] + gs[j - 1])
                rows.append(ys[j, der_rows].T - ys[0, der_rows].T - acc)
    if g_alg is not None:
        for j in range(M):
            rows.append(ys[j, alg_rows].T - g_alg(T, xs[j, :].T, ys[j, :].T, us[j, :].T))
    r = ca.vertcat(*rows)
    J = ca.jacobian(r, T)
    JtJ = J.T @ J
    step = T - ca.solve(JtJ + nls.damping * (ca.DM.eye(n_theta) + ca.diag(ca.diag(JtJ))), J.T @ r)
    lm = ca.Function("nls_step", [T, Bs], [step])
    # the update at sample instants
    sample = ca.vertcat(stack.t, stack.y, stack.u, xi_sx).T
    measured = ca.SX(1) if p == 0 else ca.mmin(stack.m)
    due = ca.logic_and(measured > 0.5, ca.logic_or(count < 0.5, stack.t - buf[M - 1, 0] >= spacing * (1 - 1e-9)))
    shifted = ca.vertcat(buf[1:, :], sample)
    new_buf = ca.if_else(due, shifted, buf)
    new_count = ca.if_else(due, ca.fmin(count + 1, M), count)
    fit = th
    for _ in range(int(nls.iterations)):
        fit = lm(fit, new_buf)
    stack.set_update(buf, new_buf)
    stack.set_update(count, new_count)
    stack.set_update(th, ca.if_else(ca.logic_and(due, new_count > M - 0.5), fit, th))
    return th


# ---------------------------------------------------------------------------------------------
# The designs
# ---------------------------------------------------------------------------------------------
def _kkl_pebo(system: System, *, phi: Any, left_inverse: Any, B: Any, Lambda: Any, estimator: Any, alpha: float,
              Theta: Any, theta_from_Theta: Any, xhat0: Any, caller: str, method: str, require: str) -> ObserverDesign:
    if not isinstance(system, System):
        raise TypeError(f"{caller}: expected a System, got {type(system).__name__}")
    maps = _parse_maps(system, phi, left_inverse, B, Lambda, caller)
    n, n_xi, p = system.n_states, maps.phi.shape[0], system.n_outputs
    if n_xi < n - p:
        raise PreconditionError(f"{caller}: φ has {n_xi} components but n - p = {n} - {p} = {n - p}: ξ is too small to "
                                f"reconstruct the unmeasured states ({cite('004')} A1 needs n_ξ ≥ n - p)")
    P, Pinv, lam, kkl, pebo, checks = _partition(maps.Lam, caller)
    if require == "kkl" and pebo:
        raise PreconditionError(f"{caller}: Λ has zero eigenvalue(s) (component(s) {[i + 1 for i in pebo]}); a KKL observer "
                                f"needs λ < 0 for every component ({cite('004')} A1): use design_pebo or design_kkl_pebo for λ = 0")
    if require == "pebo" and kkl:
        raise PreconditionError(f"{caller}: PEBO needs Λ = 0 ({cite('004')} Prop. 2); use design_kkl_pebo for λ ≠ 0")
    what = {"kkl": "KKL", "pebo": "PEBO", "kkl_pebo": "KKL+PEBO"}[require]
    checks.append(_check_pde(system, maps, caller, what))
    checks.append(_check_left_inverse(system, maps, caller))
    _, h = system.substituted()
    if any(s in (*system.u, TIME) for e in h for s in e.free_symbols):
        raise PreconditionError(f"{caller}: the outputs must be functions of the state only, y = h(x) ({cite('004')} eq. 1)")

    stack = StateStack(system)
    leaves = stack.leaves()
    phi0 = to_casadi(list(maps.phi), {s: stack.xhat0[i] for i, s in enumerate(system.x)})
    xi = stack.add("xi", n_xi, init=ca.DM(np.array(P, dtype=float)) @ phi0)
    Lam_d = sp.diag(*lam)
    PB = P * maps.B
    stack.set_flow(xi, sx_matrix(Lam_d, leaves) @ xi + sx_matrix(PB, leaves))   # (6), (15), R5
    values: dict[str, Any] = {"phi": str(list(maps.phi)), "left inverse": str(list(maps.left)), "B": str(list(maps.B)),
                              "Lambda": str(maps.Lam.tolist()), "KKL components": [i + 1 for i in kkl],
                              "PEBO components": [i + 1 for i in pebo]}
    if P != sp.eye(n_xi):
        values["P"] = str(P.tolist())
    assumed = [f"λ_{i + 1} = {lam[i]}" for i in kkl if lam[i].free_symbols]
    if assumed:
        values["assumption"] = (f"{', '.join(assumed)} must stay negative (uniformly) along the input; "
                                "not decidable symbolically")
    for i in kkl:
        if not lam[i].free_symbols:
            checks.append(Check(f"KKL component {i + 1}: λ = {lam[i]} < 0 ({cite('004')} A1)", bool(lam[i] < 0), "", "exact"))
    if assumed:
        checks.append(Check.assumed(f"input-dependent λ negative along the input ({cite('004')} A1)", values["assumption"]))

    theta_hat = ca.SX(0, 1)
    n_th = len(pebo)
    if pebo:
        theta_hat, est_values, est_checks = _theta_estimator(system, maps, stack, xi, P, Pinv, pebo, estimator, alpha,
                                                             Theta, theta_from_Theta, leaves, caller)
        values.update(est_values)
        checks.extend(est_checks)
    elif estimator is not None or Theta is not None:
        raise PreconditionError(f"{caller}: `estimator`/`Theta` were given but Λ has no zero eigenvalue, so there is no "
                                "PEBO component and no θ to estimate")
    E = np.zeros((n_xi, n_th))
    for k, i in enumerate(pebo):
        E[i, k] = 1.0
    xi_full = ca.DM(np.array(Pinv, dtype=float)) @ (xi + (ca.DM(E) @ theta_hat if n_th else 0))
    left_leaves = {**leaves, **{s: xi_full[i] for i, s in enumerate(maps.xi)}}
    xhat = to_casadi(list(maps.left), left_leaves)                      # (6), (10), (15)
    values["internal states"] = stack.n_z
    ref = {"kkl": REF_KKL, "pebo": REF_PEBO, "kkl_pebo": REF_KKLPEBO}[require]
    title = {"kkl": "KKL observer", "pebo": "PEBO", "kkl_pebo": "KKL+PEBO observer"}[require]
    cert = Certificate(title, ref, tuple(checks), values)
    return stack.build(method, xhat=xhat, certificate=cert, xhat0=xhat0)


def _theta_estimator(system: System, maps: _Maps, stack: StateStack, xi: ca.SX, P: sp.Matrix, Pinv: sp.Matrix,
                     pebo: list[int], estimator: Any, alpha: float, Theta: Any, theta_from_Theta: Any,
                     leaves: Mapping[sp.Symbol, Any], caller: str) -> tuple[ca.SX, dict[str, Any], list[Check]]:
    """The regression (11) for θ, and its estimator (linear, or windowed NLS)."""
    n_xi, n_th = maps.phi.shape[0], len(pebo)
    th = [symbol(f"theta{k + 1}") for k in range(n_th)]
    xib = [sp.Dummy(f"xib{i + 1}", real=True) for i in range(n_xi)]
    shifted = sp.Matrix(xib) + sp.Matrix([th[pebo.index(i)] if i in pebo else 0 for i in range(n_xi)])
    x_of = maps.left.xreplace(dict(zip(maps.xi, Pinv * shifted)))       # x = φ^L(P⁻¹(ξ̄ + Eθ), y)
    f, h = system.substituted()
    xsub = dict(zip(system.x, x_of))
    Lfh = (h.jacobian(sp.Matrix(system.x)) * f).xreplace(xsub)         # ẏ, right-hand side of (11)
    alg = h.xreplace(xsub)                                              # y, left of (11)
    der_rows = [k for k in range(system.n_outputs) if Lfh[k].has(*th)]
    alg_rows = [k for k in range(system.n_outputs) if alg[k].has(*th)]
    if not der_rows and not alg_rows:
        raise PreconditionError(f"{caller}: θ (the PEBO components {[i + 1 for i in pebo]}) does not appear in the regression "
                                "(11): neither y nor ẏ depends on it, so it cannot be estimated; choose φ so that the outputs "
                                "see the PEBO components")
    xi_leaves = {s: xi[i] for i, s in enumerate(xib)}
    values: dict[str, Any] = {"regression rows": f"ẏ rows {[k + 1 for k in der_rows]}, y rows {[k + 1 for k in alg_rows]}"}
    checks: list[Check] = []
    if isinstance(estimator, WindowedNLS) or (isinstance(estimator, Mapping) and estimator.get("kind") == "windowed_nls"):
        nls = estimator if isinstance(estimator, WindowedNLS) else WindowedNLS(**{k: v for k, v in estimator.items() if k != "kind"})
        if Theta is not None:
            raise PreconditionError(f"{caller}: `Theta` reparametrises a linear regression; WindowedNLS estimates θ directly")
        T, X = ca.SX.sym("theta", n_th), ca.SX.sym("xi", n_xi)
        lv = {**{s: T[k] for k, s in enumerate(th)}, **{s: X[i] for i, s in enumerate(xib)},
              **{sym: stack.y[i] for i, sym in enumerate(system.y)}, **{sym: stack.u[i] for i, sym in enumerate(system.u)}}
        fns = []
        for rows, exprs in ((der_rows, Lfh), (alg_rows, alg)):
            fns.append(ca.Function("g", [T, X, stack.y, stack.u], [to_casadi([exprs[k] for k in rows], lv)]) if rows else None)
        theta_hat = _build_nls(stack, nls, xi, fns[0], der_rows, fns[1], alg_rows, n_th, np.zeros(n_th))
        values.update(nls.describe())
        checks.append(Check.assumed("θ identifiable from the window: the nonlinear least-squares fit of the regression (11) "
                                    "has a unique minimiser", f"{n_th} parameter(s); depends on the data, not checked at "
                                    "design time"))
        return theta_hat, values, checks
    est = estimator_from(estimator, default=Gradient(1.0), caller=caller)
    alpha = float(alpha)
    if not (np.isfinite(alpha) and alpha > 0):
        raise PreconditionError(f"{caller}: the filter constant `alpha` must be positive ({cite('004')} eq. 37), got {alpha!r}")
    # reparametrisation Θ = Θ(θ), θ = θ(Θ)
    Th = [symbol(f"Theta{k + 1}") for k in range(n_th)]
    if (Theta is None) != (theta_from_Theta is None):
        raise PreconditionError(f"{caller}: give both `Theta` (Θ as expressions of theta1..) and `theta_from_Theta` "
                                "(θ as expressions of Theta1..), or neither")
    if Theta is not None:
        Th_of = matrix_of(Theta, n_th, 1, {s.name: s for s in th}, name="Theta")
        th_of = matrix_of(theta_from_Theta, n_th, 1, {s.name: s for s in Th}, name="theta_from_Theta")
        verdicts = []
        for k in range(n_th):
            v = decide_identity(th_of[k].xreplace(dict(zip(Th, Th_of))), th[k], seed=k)
            if v.fails:
                raise PreconditionError(f"{caller}: `theta_from_Theta` does not invert `Theta`: θ(Θ(θ))_{k + 1} = "
                                        f"{sp.simplify(th_of[k].xreplace(dict(zip(Th, Th_of))))}, not theta{k + 1}"
                                        f"{v.where()}")
            verdicts.append(v)
        chk = identity_check(f"reparametrisation θ(Θ(θ)) = θ, Θ = {list(Th_of)}", verdicts, [f"theta{k + 1}" for k in range(n_th)])
        checks.append(chk)
    else:
        Th_of, th_of = sp.Matrix(th), sp.Matrix(Th)
    to_Th = dict(zip(th, th_of))
    a_rows, b_rows = [], []
    for kind, rows, exprs in (("ẏ", der_rows, Lfh), ("y", alg_rows, alg)):
        for k in rows:
            g = sp.expand(exprs[k].xreplace(to_Th))
            J = sp.Matrix([g]).jacobian(sp.Matrix(Th))
            if any(s in set(Th) for s in J.free_symbols):
                raise PreconditionError(
                    f"{caller}: the regression (11) is not linear in θ: {kind}_{k + 1} = {sp.simplify(exprs[k])} with "
                    f"x = φ^L(ξ + θ, y). Give a reparametrisation Θ(θ) in which it is linear (`Theta`, `theta_from_Theta`, "
                    f"as {cite('004')} §V-A does with Θ = exp(θ)), or use estimator=WindowedNLS(window=...)")
            a_rows.append(sp.expand(g - (J * sp.Matrix(Th))[0]))
            b_rows.append(J)
    nd = len(der_rows)
    ysel = ca.vertcat(*[stack.y[k] for k in der_rows]) if nd else ca.SX(0, 1)
    lv = {**leaves, **xi_leaves}
    a_sx = to_casadi(a_rows, lv)
    b_sx = ca.vertcat(*[sx_matrix(b, lv) for b in b_rows])             # rows x n_th
    Y_parts, psi_parts = [], []
    if nd:
        # (37): W[y] - F[a] = αy - F[αy + a] since W = α(1 - F): one filter state per row
        Y_parts.append(alpha * ysel - lowpass(stack, alpha * ysel + a_sx[:nd], alpha, "F_Y"))
        Fb = ca.SX(nd, n_th)                            # F[b], filtering only the entries that are not identically 0
        nz = [(i, j) for i in range(nd) for j in range(n_th) if b_rows[i][0, j] != 0]
        if nz:
            Fnz = lowpass(stack, ca.vertcat(*[b_sx[i, j] for i, j in nz]), alpha, "F_b")
            for k, (i, j) in enumerate(nz):
                Fb[i, j] = Fnz[k]
        psi_parts.append(Fb)
    if alg_rows:
        Y_parts.append(ca.vertcat(*[stack.y[k] for k in alg_rows]) - a_sx[nd:])
        psi_parts.append(b_sx[nd:, :])
    reg = Regression(ca.vertcat(*Y_parts), ca.vertcat(*psi_parts).T, tuple(s.name for s in Th))
    Theta0 = np.array([float(e) for e in Th_of.xreplace({s: 0 for s in th})], dtype=float)
    out = est.build(stack, reg, Theta0, prefix="Theta" if Theta is not None else "theta")
    theta_hat = to_casadi(list(th_of), {s: out.theta[k] for k, s in enumerate(Th)}) if Theta is not None else out.theta
    shown = {d: symbol(f"xi{i + 1}" if P == sp.eye(n_xi) else f"xibar{i + 1}") for i, d in enumerate(xib)}
    values.update({"regression Y": f"W[y_k] - F[a_k] = αy_k - F[αy_k + a_k], a = {[e.xreplace(shown) for e in a_rows]}",
                   "regressor psi": f"F[b_k], b = {[list(b.xreplace(shown)) for b in b_rows]}",
                   "alpha": alpha, **est.describe(), "excitation monitor": ExcitationMonitor.of(stack, out, est)})
    checks.append(Check("regression (11) linear in " + ("Θ" if Theta is not None else "θ") + f"; filtered with F, W ({cite('004')} eq. 37)",
                        True, f"{len(a_rows)} row(s), {n_th} parameter(s); {est.reference}", "symbolic (Jacobian in θ free of θ)"))
    checks.append(Check.assumed("the regressor F[b] is exciting enough for the estimator (PE, or interval excitation for G+D)",
                                "depends on the trajectory; measure it with nlobs.design.excitation_report after a run"))
    return theta_hat, values, checks


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_kkl(ctx: Any) -> Tuning:
    why = output_injection_form(ctx)
    need = ("φ(x), a stable Λ and B(y, u) with ∇φ·f = Λφ + B(h(x), u) (the PDE of " + f"{cite('004', 'eq. 4')}"
            + "), and a left inverse φᴸ(ξ, y); or use kkl_learned, which learns φᴸ numerically")
    if why:
        return Tuning.needs(need + f" (nlobs constructs φ only for the output-injection form: {why})",
                       phi="...", left_inverse="...", B="...", Lambda="...")
    try:
        opts, reason = kkl_linear(ctx.system, ctx.omega_o)
    except (FormError, ValueError, ZeroDivisionError) as e:
        opts, reason = None, clean_message(e)
    if opts is None:
        return Tuning.needs(need + f" ({reason})")
    return Tuning.tuned(opts, "constructed: φ = Tx with TA − ΛT = B_kC (Sylvester, exact), Λ = −ω_o·diag(1, 1.25, ...)")


def tune_pebo(ctx: Any) -> Tuning:
    why = output_injection_form(ctx)
    need = "φ(x) with ∇φ·f = B(h(x), u) (a function whose derivative is measured), B, and a left inverse φᴸ(ξ, y)"
    if why:
        return Tuning.needs(need + f" (nlobs constructs φ only for the output-injection form: {why})", phi="...", left_inverse="...", B="...")
    try:
        opts, reason, b = pebo_linear(ctx.system)
    except (FormError, ValueError, ZeroDivisionError) as e:
        opts, reason, b = None, clean_message(e), None
    if opts is None:
        return Tuning.needs(need + f" ({reason})")
    level = float(np.sum(np.array(b, dtype=float) ** 2)) or 1.0
    alpha = round(float(min(ctx.omega_o, ctx.step_limit())), 6)
    opts.update({"alpha": alpha, "estimator": {"kind": "gradient", "gamma": round(ctx.omega_o / level, 9)}})
    return Tuning.tuned(opts, f"constructed: φ = Tx with TA = KC (derivatives measured), [C; T] invertible; filters α = {alpha:.3g}, "
                    "gradient estimator (the regressor is constant, so θ converges exponentially)")


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
tune_kkl_pebo = needs_only("φ(x), Λ with zeros for the components that have no dynamics of their own (PEBO part) and negative "
                           "entries for the others (KKL part), B(y, u) and a left inverse φᴸ(ξ, y) with ∇φ·f = Λφ + B "
                           f"({cite('004', 'Proposition 3')}; its example (31) is the pattern)",
                           phi="...", left_inverse="...", B="...", Lambda="...")


@kind('kkl', summary='KKL observer from a solution (φ, Λ, B) of the PDE and a left inverse φᴸ',
      references=(work("004", "Proposition 1"),), tune=tune_kkl)
def design_kkl(system: System, *, phi: Sequence[Any], left_inverse: Sequence[Any], B: Sequence[Any], Lambda: Any,
               xhat0: Any = None) -> ObserverDesign:
    r"""KKL observer (Yi, Ortega & Zhang (2019), Proposition 1) from a solution (φ, Λ, B) of the PDE and a left inverse φ^L.

    .. math::

        \nabla\phi^\top(x) f(x, u) = \Lambda\phi(x) + B(h(x), u), \qquad \phi^L(\phi(x), h(x)) = x, \\
        \dot\xi = \Lambda\xi + B(y, u), \qquad \hat x = \phi^L(\xi, y),

    and :math:`\xi - \phi(x) = e^{\Lambda t}(\xi(0) - \phi(x(0)))`. Both identities are checked
    symbolically before anything is built; ξ(0) = φ(xhat0).

    Parameters
    ----------
    system : System
        ẋ = f(x, u), y = h(x).
    phi : sequence of expressions in the states
        φ(x), n_ξ ≥ n - p components.
    left_inverse : sequence of expressions in ``xi1, xi2, ...`` and the outputs
        φ^L(ξ, y), one expression per state.
    B : sequence of expressions in the outputs, inputs and ``t``
        The injection B(y, u), n_ξ components.
    Lambda : sequence (diagonal) or (n_ξ, n_ξ) matrix
        Λ with negative entries; entries may depend on the inputs (a time-varying stable Λ, as
        in Yi, Ortega & Zhang (2019), Table I), a non-diagonal Λ must be constant and diagonalisable with negative
        real eigenvalues (Yi, Ortega & Zhang (2019), R5).
    xhat0 : array_like, optional
        Initial estimate (zeros); ξ(0) = φ(xhat0).

    Raises
    ------
    PreconditionError
        If the PDE fails (naming the component, its residual, the states it depends on, and
        when the component would satisfy it with another λ, which — e.g. λ = 0, a PEBO
        component), φ^L is not a left inverse, or a λ is not negative.

    References
    ----------
    Yi, Ortega & Zhang (2019), Proposition 1, eqs. (4)-(6), remark R5.
    """
    return _kkl_pebo(system, phi=phi, left_inverse=left_inverse, B=B, Lambda=Lambda, estimator=None, alpha=1.0, Theta=None,
                     theta_from_Theta=None, xhat0=xhat0, caller="design_kkl", method="kkl", require="kkl")


@kind('pebo', summary='parameter-estimation-based observer (PEBO)',
      references=(work("004", "Proposition 2"),), tune=tune_pebo)
def design_pebo(system: System, *, phi: Sequence[Any], left_inverse: Sequence[Any], B: Sequence[Any],
                estimator: Any = None, alpha: float = 1.0, Theta: Sequence[Any] | None = None,
                theta_from_Theta: Sequence[Any] | None = None, xhat0: Any = None) -> ObserverDesign:
    r"""Parameter estimation-based observer, PEBO (Yi, Ortega & Zhang (2019), Proposition 2).

    .. math::

        \nabla\phi^\top(x) f(x, u) = B(h(x), u), \qquad \dot\xi = B(y, u), \qquad
        \phi(x(t)) = \xi(t) + \theta, \qquad \hat x = \phi^L(\xi + \hat\theta, y),

    with θ̂ from the regression (11). When
    :math:`\dot y = a(\xi, y, u) + b(\xi, y, u)^\top\theta` (or linear in a reparametrisation
    Θ(θ)), the regression :math:`W[y] - F[a] = F[b]^\top\theta` (filters of Yi, Ortega & Zhang (2019), eq. 37) feeds a
    linear estimator (default :class:`Gradient`, gain 1); otherwise pass
    ``estimator=WindowedNLS(window=...)``. ξ(0) = φ(xhat0), θ̂(0) = 0.

    Parameters
    ----------
    system : System
    phi, left_inverse, B :
        As in :func:`design_kkl`; the PDE is checked with Λ = 0.
    estimator : estimator, WindowedNLS or mapping, optional
        :class:`Gradient` (default), :class:`LeastSquares`, :class:`DREM`, :class:`GD`, or
        :class:`WindowedNLS`.
    alpha : float
        Filter constant α > 0 of F = α/(p + α) and W = αp/(p + α).
    Theta : sequence of expressions in ``theta1, ...``, optional
        A reparametrisation Θ(θ) in which the regression is linear (Yi, Ortega & Zhang (2019), §V-A: Θ = exp(θ)).
    theta_from_Theta : sequence of expressions in ``Theta1, ...``, optional
        Its inverse θ(Θ) (checked), used for x̂. Where θ(Θ) is undefined (log of Θ̂ ≤ 0) the
        estimate is NaN: start Θ̂ inside the domain (Θ̂(0) = Θ(0)).
    xhat0 : array_like, optional

    Raises
    ------
    PreconditionError
        If the PDE with Λ = 0 fails (with the component, residual and a hint), φ^L is not a
        left inverse, θ does not enter the regression, or the regression is not linear in θ
        and no WindowedNLS was asked for.

    References
    ----------
    Yi, Ortega & Zhang (2019), Proposition 2, eqs. (7)-(13), R3; filters eq. (37).
    """
    return _kkl_pebo(system, phi=phi, left_inverse=left_inverse, B=B, Lambda=None, estimator=estimator, alpha=alpha,
                     Theta=Theta, theta_from_Theta=theta_from_Theta, xhat0=xhat0, caller="design_pebo", method="pebo",
                     require="pebo")


@kind('kkl_pebo', summary='KKL+PEBO observer: KKL for the components with λ < 0, PEBO for λ = 0',
      references=(work("004", "Proposition 3"),), tune=tune_kkl_pebo)
def design_kkl_pebo(system: System, *, phi: Sequence[Any], left_inverse: Sequence[Any], B: Sequence[Any], Lambda: Any,
                    estimator: Any = None, alpha: float = 1.0, Theta: Sequence[Any] | None = None,
                    theta_from_Theta: Sequence[Any] | None = None, xhat0: Any = None) -> ObserverDesign:
    r"""KKL+PEBO observer (Yi, Ortega & Zhang (2019), Proposition 3): KKL for the components with λ < 0, PEBO for λ = 0.

    .. math::

        \Lambda &= \operatorname{diag}(\Lambda_L, 0) \;\text{(eq. 14), or } P^{-1}\operatorname{diag}(\Lambda_L, 0)P \;\text{(R5)}, \\
        \dot\xi_L &= \Lambda_L\xi_L + B_L(y, u), \qquad \dot\xi_P = B_P(y, u), \\
        \hat x &= \phi^L\big(P^{-1}(\xi + \operatorname{col}(0, \hat\theta)), y\big) \qquad \text{(eq. 15)},

    with θ̂ as in :func:`design_pebo`. The zero entries of a diagonal Λ may sit anywhere (R5
    with a permutation P). Proposition 1 is the case without zeros, Proposition 2 the case
    Λ = 0 (R4).

    Parameters
    ----------
    system : System
    phi, left_inverse, B : see :func:`design_kkl`
    Lambda : sequence (diagonal) or (n_ξ, n_ξ) matrix
        Negative entries (KKL part) and zeros (PEBO part); or a constant matrix similar to
        that form (R5).
    estimator, alpha, Theta, theta_from_Theta, xhat0 : see :func:`design_pebo`

    Raises
    ------
    PreconditionError
        See :func:`design_kkl` and :func:`design_pebo`.

    References
    ----------
    Yi, Ortega & Zhang (2019), Proposition 3, eqs. (14)-(15), R4-R5; example (31)-(37).
    """
    return _kkl_pebo(system, phi=phi, left_inverse=left_inverse, B=B, Lambda=Lambda, estimator=estimator, alpha=alpha,
                     Theta=Theta, theta_from_Theta=theta_from_Theta, xhat0=xhat0, caller="design_kkl_pebo",
                     method="kkl_pebo", require="kkl_pebo")

