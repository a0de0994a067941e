r"""Observer forms (Besançon (2010)): is a model — possibly after adding unknown constant parameters as states —
in output-injection, state-affine, Lipschitz or triangular (high-gain) form? And if not, which
entry breaks the form.

* Output injection: :math:`\dot x = Ax + B(u, y)`, y = Cx, A and C constant (reuses
  :class:`nlobs.model.OutputInjectionForm`).
* State-affine (Wang, Ortega & Bobtsov (2021), eq. 1, Besançon (2010) "Kalman-like"): :math:`\dot x = A(u, y, t)x + b(u, y, t)`,
  :math:`y = C(u, t)^\top x`.
* Lipschitz: :math:`\dot x = Ax + \varphi(x, u)`, y = Cx, with a Lipschitz constant of φ over a box.
* Triangular (high gain): y = x1 and :math:`\partial f_i/\partial x_j = 0` for j > i + 1, with
  :math:`\partial f_i/\partial x_{i+1}` bounded away from 0 (Besançon (2010), "High Gain Observer").
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ..._deprecate import renamed
from ...errors import FormError, ModelError, ShapeError
from ...model import OutputInjectionForm, System
from ._conditions import LipschitzEstimate, check_box, lipschitz_bound
from ...references import cite

__all__ = ["FormCheck", "FormsReport", "with_params_as_states", "state_affine_form", "lipschitz_constant",
           "triangular_form", "recognise_forms"]


def with_params_as_states(system: System, params: Sequence[str] | str = "all") -> System:
    """The model with the given parameters moved to the state (p' = 0), e.g. Besançon (2010)'s robot arm with unknown b.

    Parameters
    ----------
    system : System
    params : sequence of str or "all"
        The parameters to move.
    """
    names = system.param_names if params == "all" else tuple([params] if isinstance(params, str) else params)
    bad = [k for k in names if k not in system.params]
    if bad:
        raise ModelError(f"with_params_as_states: {', '.join(map(repr, bad))} is not a parameter of {system.name!r}")
    keep = {k: v for k, v in system.params.items() if k not in names}
    return System(states=(*system.states, *names), f=(*system.f, *[0] * len(names)), outputs=system.outputs, h=system.h,
                  inputs=system.inputs, params=keep, name=system.name + (f"+{','.join(names)}" if names else ""))


@dataclass(frozen=True)
class FormCheck:
    """One form: whether the model is in it, and the entry that breaks it when it is not."""

    form: str
    holds: bool
    reason: str
    details: Mapping[str, Any] = field(default_factory=dict)

    def __str__(self) -> str:
        return f"{self.form}: {'yes' if self.holds else 'no'} - {self.reason}"


def _output_matrix(system: System, f: sp.Matrix, h: sp.Matrix) -> tuple[sp.Matrix | None, str]:
    x = sp.Matrix(system.x)
    Cm = h.jacobian(x)
    for i, name in enumerate(system.outputs):
        if any(e.free_symbols & set(system.x) for e in Cm.row(i)):
            return None, f"output {name} = {h[i]} is not linear in the states"
        if sp.expand(h[i] - (Cm.row(i) * x)[0]) != 0:
            return None, f"output {name} = {h[i]} has a term without a state (y must be C x)"
    return Cm, ""


def state_affine_form(system: System) -> FormCheck:
    r"""Recognise :math:`\dot x = A(u, y, t)x + b(u, y, t)`, :math:`y = C(u, t)^\top x` (Wang, Ortega & Bobtsov (2021), eq. 1).

    With a constant C, write :math:`x = C^+y + K\xi` (K an orthonormal basis of ker C): the model is
    state-affine iff :math:`\partial f/\partial x\,K` depends on x only through y. Then
    :math:`A = (\partial f/\partial x\,K)K^\top` and :math:`b = f(C^+ y)`. With C depending on u or t,
    f must be affine in x with coefficients in (u, t).

    References
    ----------
    Wang, Ortega & Bobtsov (2021), eq. (1); Besançon (2010) "state affine systems".
    """
    form = f"state-affine ({cite('000')} eq. 1)"
    f, h = system.substituted()
    x = sp.Matrix(system.x)
    Cm, why = _output_matrix(system, f, h)
    if Cm is None:
        return FormCheck(form, False, why)
    J = f.jacobian(x)
    xs = set(system.x)
    if any(e.free_symbols - {sp.Symbol("t", real=True)} - set(system.u) for e in Cm):  # constant C required for y-dependence
        for i, name in enumerate(system.states):
            for j, e in enumerate(J.row(i)):
                if e.free_symbols & xs:
                    return FormCheck(form, False, f"{name}' = {f[i]} is not affine in the states (∂/∂{system.states[j]} = {e}), "
                                     "and C depends on u or t, so A may not depend on y")
        return FormCheck(form, True, "f is affine in x with coefficients in (u, t)", {"A": J, "C": Cm})
    n = system.n_states
    K = sp.Matrix.hstack(*Cm.nullspace()) if Cm.rank() < n else sp.zeros(n, 0)
    if K.shape[1]:
        K = sp.Matrix.hstack(*sp.GramSchmidt([K[:, j] for j in range(K.shape[1])], True))
    ys = sp.Matrix(system.y)
    xi = sp.Matrix(sp.symbols(f"xi_1:{K.shape[1] + 1}", real=True)) if K.shape[1] else sp.zeros(0, 1)
    x_of = Cm.pinv() * ys + (K * xi if K.shape[1] else sp.zeros(n, 1))
    sub = dict(zip(system.x, x_of))
    G = (J * K).xreplace(sub) if K.shape[1] else sp.zeros(n, 0)
    for i, name in enumerate(system.states):
        for j in range(G.shape[1]):
            g = sp.simplify(G[i, j])
            if g.free_symbols & set(xi):
                return FormCheck(form, False, f"{name}' = {f[i]} is not affine in the unmeasured direction {list(K[:, j])}: "
                                 f"its derivative {g} still depends on it (a product or nonlinearity of unmeasured states)")
    A = sp.simplify(G * K.T) if K.shape[1] else sp.zeros(n, n)
    b = sp.simplify(f.xreplace(dict(zip(system.x, Cm.pinv() * ys))))
    return FormCheck(form, True, "A(u, y, t) = ∂f/∂x·K·Kᵀ depends on x only through y", {"A": A, "b": b, "C": Cm})


@renamed(box="region", input_box="input_region")
def lipschitz_constant(system: System, region: Any, *, A: Any = None, input_region: Any = None, samples: int = 2000,
                       seed: int = 0) -> LipschitzEstimate:
    r"""Estimate the Lipschitz constant of :math:`\varphi(x, u) = f(x, u) - Ax` over a box.

    On a convex set, :math:`\|\varphi(x) - \varphi(z)\| \le \gamma\|x - z\|` with
    :math:`\gamma = \sup\|\partial\varphi/\partial x\|_2`; γ is estimated by the largest spectral norm
    of the Jacobian over random samples of the box (and of `input_region`), refined by a local
    maximisation from the best samples. Sampling can only under-estimate the sup.

    Parameters
    ----------
    system : System
    region : mapping of str to (low, high), or array_like of shape (n, 2)
        The box of the states, by name (``{"x1": (-1, 1), ...}``; input names in it count as `input_region`)
        or as [low, high] per state in their order. Old name: ``box``.
    A : (n, n) array_like, optional
        The linear part; default the Jacobian of f at the box centre with u = 0 (or the input box centre).
    input_region : mapping or array_like of shape (m, 2), optional
        Range of the inputs (default: u = 0). Old name: ``input_box``.
    samples, seed : int
        Random points of the box and their seed.

    Returns
    -------
    LipschitzEstimate

    Raises
    ------
    ShapeError, DataError
        On a box of the wrong shape, NaN bounds, or low > high.

    References
    ----------
    Besançon (2010) "LTI + Lipschitz NL" (γ and the condition eigmin(Q)/(2 eigmax(P)) > γ).
    """
    caller = "lipschitz_constant"
    n, m = system.n_states, system.n_inputs
    region, input_region = _split_region(system, region, input_region)
    B = check_box(region, n, "region", caller, system.states)
    U = (check_box(input_region, m, "input_region", caller, system.inputs) if input_region is not None
         else np.zeros((m, 2)))
    f, _ = system.substituted()
    x, u = sp.Matrix(system.x), sp.Matrix(system.u)
    names = (*system.states, *system.inputs)
    if A is None:
        at = {**dict(zip(system.x, B.mean(axis=1))), **dict(zip(system.u, U.mean(axis=1)))}
        A_ = np.array(f.jacobian(x).xreplace({k: sp.Float(v) for k, v in at.items()}), dtype=float)
    else:
        A_ = np.array(A, dtype=float)
    if A_.shape != (n, n):
        raise ShapeError(f"{caller}: incompatible dimensions of `A`: expected ({n}, {n}), found {A_.shape}")
    phi = list(f - sp.Matrix(A_) * x)
    est = lipschitz_bound(phi, names, np.vstack([B, U]), wrt=n, samples=samples, seed=seed)
    return LipschitzEstimate(est.gamma, est.worst_point, est.variables, samples, "φ = f - Ax", A_)


def _split_region(system: System, region: Any, input_region: Any) -> tuple[Any, Any]:
    """A region mapping that also bounds inputs: its states' part, and its inputs' part merged into `input_region`."""
    if not isinstance(region, Mapping) or not any(k in system.inputs for k in region):
        return region, input_region
    ins = {k: v for k, v in region.items() if k in system.inputs}
    if input_region is not None and not isinstance(input_region, Mapping):
        raise ShapeError("lipschitz_constant: the inputs are bounded twice: in `region` by name and in `input_region`")
    return {k: v for k, v in region.items() if k not in system.inputs}, {**ins, **(input_region or {})}


def triangular_form(system: System) -> FormCheck:
    r"""Recognise the triangular (high-gain) form of Besançon (2010): y = x1 and f_i depends on x_1..x_{i+1} only.

    Two levels are reported: the general form (∂f_i/∂x_j = 0 for j > i + 1, and the coupling
    :math:`\partial f_i/\partial x_{i+1}` never zero: it must be bounded away from 0 for the
    high-gain observer) and the special form :math:`\dot x = A_0x + B(u, x)` with
    :math:`\partial f_i/\partial x_{i+1} = 1`.

    References
    ----------
    Besançon (2010) "LTI + structured NL", "High Gain Observer" and its extension.
    """
    form = f"triangular / high-gain ({cite('002')})"
    f, h = system.substituted()
    x = system.x
    if system.n_outputs != 1 or sp.expand(h[0] - x[0]) != 0:
        return FormCheck(form, False, f"the output must be y = {system.states[0]} (C0 = (1 0 … 0)); here "
                         + ", ".join(f"{n} = {e}" for n, e in zip(system.outputs, h)))
    n = system.n_states
    couplings = []
    for i in range(n):
        for j in range(i + 2, n):
            d = sp.diff(f[i], x[j])
            if d != 0:
                return FormCheck(form, False, f"{system.states[i]}' = {f[i]} depends on {system.states[j]} "
                                 f"(∂/∂{system.states[j]} = {d}); only x1..x{i + 2} may appear in the equation of x{i + 1}")
        if i + 1 < n:
            d = sp.simplify(sp.diff(f[i], x[i + 1]))
            couplings.append(d)
            if d == 0:
                return FormCheck(form, False, f"{system.states[i]}' = {f[i]} does not depend on {system.states[i + 1]}: the "
                                 "chain is broken (∂f_i/∂x_{i+1} must stay away from 0)")
    unit = all(c == 1 for c in couplings)
    varying = [str(c) for c in couplings if c.free_symbols]
    if unit:
        reason = "ẋ = A0 x + B(u, x) with B lower-triangular (∂B_i/∂x_j = 0 for j ≥ i + 1)"
    elif varying:
        reason = ("general triangular form; the couplings ∂f_i/∂x_{i+1} = " + ", ".join(varying)
                  + " vary and must stay away from 0 on the operating region")
    else:
        reason = "general triangular form with constant nonzero couplings " + ", ".join(map(str, couplings))
    return FormCheck(form, True, reason, {"couplings": couplings, "A0_B_form": unit})


@dataclass(frozen=True)
class FormsReport:
    """Which observer forms a model is in (Besançon (2010)), with the breaking entry for each one it is not in."""

    model: str
    checks: tuple[FormCheck, ...]
    lipschitz: LipschitzEstimate | None = None

    def holds(self, form_prefix: str) -> bool:
        return any(c.holds for c in self.checks if c.form.startswith(form_prefix))

    def __str__(self) -> str:
        lines = [f"Observer forms of {self.model!r}:"] + [f"  {c}" for c in self.checks]
        if self.lipschitz is not None:
            lines.append(f"  {self.lipschitz}")
        return "\n".join(lines)


@renamed(box="region", input_box="input_region")
def recognise_forms(system: System, *, unknown_params: Sequence[str] | str = (), region: Any = None,
                    input_region: Any = None) -> FormsReport:
    """Check the observer forms of Besançon (2010) on a model (optionally with parameters added as constant states).

    Parameters
    ----------
    system : System
    unknown_params : sequence of str or "all"
        Parameters to estimate, added as states with p' = 0 before the check (Besançon (2010)'s robot arm with
        unknown b is state-affine only in (x1, x2, b)).
    region, input_region : mapping of str to (low, high), or array_like of shape (n, 2) / (m, 2), optional
        When given, the Lipschitz constant of φ = f - Ax is estimated over the box (see :func:`lipschitz_constant`;
        old names ``box``, ``input_box``).

    Returns
    -------
    FormsReport
    """
    s = with_params_as_states(system, unknown_params) if unknown_params else system
    checks = []
    try:
        oi = OutputInjectionForm.from_system(s)
        checks.append(FormCheck(f"output injection ({cite('002')})", True, "ẋ = Ax + B(u, y), y = Cx", {"A": oi.A, "C": oi.C, "B": oi.B}))
    except FormError as e:
        checks.append(FormCheck(f"output injection ({cite('002')})", False, str(e)))
    checks.append(state_affine_form(s))
    checks.append(triangular_form(s))
    lip = None
    f, h = s.substituted()
    Cm, why = _output_matrix(s, f, h)
    if Cm is None:
        checks.append(FormCheck(f"Lipschitz ({cite('002')})", False, why))
    elif region is not None:
        lip = lipschitz_constant(s, region, input_region=input_region)
        checks.append(FormCheck(f"Lipschitz ({cite('002')})", True, f"y = Cx; φ = f - Ax has γ ≈ {lip.gamma:.4g} on the box "
                                "(global Lipschitz is not checked: only the box)", {"gamma": lip.gamma}))
    else:
        checks.append(FormCheck(f"Lipschitz ({cite('002')})", True, "y = Cx; give `region` to estimate the Lipschitz constant of φ = f - Ax"))
    return FormsReport(system.name, tuple(checks), lip)

