r"""The KKL+PEBO observer for the class of Yi, Ortega & Zhang (2019), Proposition 7 (eqs. 40-47).

Systems of the form (Yi, Ortega & Zhang (2019), eq. 40)

.. math::

    \dot{\mathbf x}_1 &= \mathbf f_1(\mathbf x_1, \mathbf x_2, \mathbf x_3, u) + S(x, u), \qquad
    \dot{\mathbf x}_2 = \mathbf A_2\mathbf x_2 + \mathbf f_2(\mathbf x_1, u), \\
    \dot{\mathbf x}_3 &= \mathbf A_3\mathbf x_3 + \mathbf f_3(\mathbf x_1, \mathbf x_2, u), \qquad
    \dot{\mathbf x}_4 = \mathbf f_4(\mathbf x_1, \mathbf x_2, \mathbf x_3, u), \qquad y = \mathbf x_1,

with one component k of :math:`\dot{\mathbf x}_1` affine in :math:`\mathbf x_4`,
:math:`S_k = b^\top(\mathbf x_1, \mathbf x_2, \mathbf x_3, u)\mathbf x_4` (41), and
:math:`\mathbf A_2`, :math:`\mathbf A_3` Hurwitz, admit the observer (43)-(47): copies of the
stable x2, x3 subsystems driven by y (KKL part), an open integration
:math:`\dot\xi = \mathbf f_4(y, \hat{\mathbf x}_2, \hat{\mathbf x}_3, u)` with
:math:`\mathbf x_4 = \xi + \theta + \epsilon_t` (PEBO part, eq. 49), and a gradient estimator of θ on

.. math::

    \hat Y = W[y_k] - F[f_{1,k}(y, \hat{\mathbf x}_2, \hat{\mathbf x}_3, u)] - F[b^\top\xi], \qquad
    \hat\psi = F[b(y, \hat{\mathbf x}_2, \hat{\mathbf x}_3, u)],

which converges when b is persistently exciting (42).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from ...engine import to_casadi
from ...errors import PreconditionError
from ...model import System
from ...references import cite, work
from .._base import Certificate, Check, ObserverDesign
from .._constructions import cascade_partition, evaluate
from .._kind import Tuning, kind
from ._regression import ExcitationMonitor, Gradient, Regression, StateStack, estimator_from, lowpass

__all__ = ["design_kkl_pebo_cascade"]

REF = f"{cite('004')} Proposition 7: class (40)-(42), observer (43)-(47)"


# -- automatic tuning for the advisor (the kinds' `tune`; see design/_kind.py) ------------------------------
def tune_cascade(ctx: Any) -> Tuning:
    part, why = cascade_partition(ctx.system)
    if part is None:
        return Tuning.fails(f"not in the class of {cite('004', 'Proposition 7')}: {why}")
    alpha = round(float(min(ctx.omega_o, ctx.step_limit())), 6)
    gamma = float(ctx.omega_o)
    if ctx.nominal is not None:  # the gradient acts at the rate γ‖F[b]‖²: scale γ by the regressor b along the run
        f, _ = ctx.system.substituted()
        fk = f[ctx.system.states.index(part["k"])]
        b = [sp.diff(fk, sp.Symbol(v, real=True)) for v in part["x4"]]
        vals = evaluate(b, ctx.system, ctx.samples(300))
        b2 = np.sum(vals ** 2, axis=1)
        if np.all(np.isfinite(b2)) and b2.max() > 0:
            gamma = float(min(ctx.omega_o / max(b2.mean(), 1e-300), ctx.step_limit() / b2.max()))
    opts = {**part, "alpha": alpha, "estimator": {"kind": "gradient", "gamma": float(f"{gamma:.6g}")}}
    return Tuning.tuned(opts, f"blocks found: x2 = {part['x2']}, x3 = {part['x3']}, x4 = {part['x4']}, k = {part['k']}; "
                    f"gradient gain γ = {gamma:.3g} = ω_o / mean ‖b‖² on the run; θ converges if b is persistently exciting")


@kind('kkl_pebo_cascade', summary='KKL+PEBO observer for the cascade class, from a partition of the states',
      references=(work("004", "Proposition 7"),), tune=tune_cascade)
def design_kkl_pebo_cascade(system: System, *, x2: Sequence[str], x3: Sequence[str], x4: Sequence[str], k: str,
                            alpha: float = 1.0, estimator: Any = None, xhat0: Any = None) -> ObserverDesign:
    r"""KKL+PEBO observer for the class of Yi, Ortega & Zhang (2019), Proposition 7, from the partition of the states.

    The model is checked against (40)-(41) block by block; the observer is (43)-(47) with
    :math:`\hat{\mathbf x}_1 = y`.

    Parameters
    ----------
    system : System
        Its outputs must be exactly the states of x1 (the states not in x2, x3, x4), y = x1.
    x2, x3, x4 : sequence of str
        State names of the blocks (x2 or x3 may be empty; x4 must not be).
    k : str
        The state of x1 whose equation carries :math:`b^\top\mathbf x_4` (41).
    alpha : float
        Filter constant of F = α/(p + α), W = αp/(p + α).
    estimator : estimator or mapping, optional
        Estimator of θ (default :class:`Gradient` with Γ = 1, the paper's (47)).
    xhat0 : array_like, optional
        Initial estimate: x̂2(0), x̂3(0) and ξ(0) = x̂4(0) from it, θ̂(0) = 0.

    Raises
    ------
    PreconditionError
        Naming the block equation that breaks (40)-(41), a non-Hurwitz A2 or A3 (with its
        eigenvalue), or outputs that are not x1.

    References
    ----------
    Yi, Ortega & Zhang (2019), Proposition 7, eqs. (40)-(49).
    """
    caller = "design_kkl_pebo_cascade"
    if not isinstance(system, System):
        raise TypeError(f"{caller}: expected a System, got {type(system).__name__}")
    names = list(system.states)
    blocks = {"x2": list(x2), "x3": list(x3), "x4": list(x4)}
    seen: set[str] = set()
    for label, blk in blocks.items():
        for s in blk:
            if s not in names:
                raise PreconditionError(f"{caller}: `{label}` names {s!r}, which is not a state of {system.name!r}")
            if s in seen:
                raise PreconditionError(f"{caller}: the state {s!r} is in two blocks")
            seen.add(s)
    if not blocks["x4"]:
        raise PreconditionError(f"{caller}: `x4` is empty; Proposition 7 estimates x4 with the PEBO part")
    x1 = [s for s in names if s not in seen]
    f, h = system.substituted()
    sym = dict(zip(names, system.x))
    X = {lab: [sym[s] for s in blk] for lab, blk in (("x1", x1), *blocks.items())}
    if sorted(map(str, h)) != sorted(x1) or len(h) != len(x1):
        raise PreconditionError(f"{caller}: Proposition 7 needs y = x1 (the states not in x2, x3, x4: {x1}); the outputs are "
                                f"{list(h)}")
    if k not in x1:
        raise PreconditionError(f"{caller}: `k` = {k!r} must be a state of x1 ({x1}), the one whose equation has bᵀx4 (41)")
    fx = dict(zip(names, f))

    def depends(e: sp.Expr, syms: list[sp.Symbol]) -> list[str]:
        return sorted(s.name for s in e.free_symbols if s in set(syms))

    checks = []
    mats = {}
    for lab, allowed_extra in (("x2", []), ("x3", X["x2"])):
        blk = X[lab]
        if not blk:
            mats[lab] = (np.zeros((0, 0)), sp.zeros(0, 1))
            continue
        F = sp.Matrix([fx[s.name] for s in blk])
        A = F.jacobian(sp.Matrix(blk))
        if A.free_symbols:
            raise PreconditionError(f"{caller}: {lab}' must be A{lab[1]}·{lab} + f{lab[1]}(...) with A{lab[1]} constant ({cite('004')} eq. 40); "
                                    f"∂f/∂{lab} = {A.tolist()} is not constant")
        rest = sp.expand(F - A * sp.Matrix(blk))
        forbidden = [v for lab2 in ("x2", "x3", "x4") if lab2 != "x2" or lab == "x2" for v in X[lab2]
                     if v not in allowed_extra]
        for i, e in enumerate(rest):
            bad = depends(e, forbidden)
            if bad:
                raise PreconditionError(f"{caller}: {blk[i]}' = {fx[blk[i].name]}: f{lab[1]} may depend only on x1"
                                        + (", x2" if lab == "x3" else "") + f" and u ({cite('004')} eq. 40), it depends on {', '.join(bad)}")
        An = np.array(A, dtype=float)
        eig = np.linalg.eigvals(An)
        if eig.real.max() >= 0:
            worst = eig[np.argmax(eig.real)]
            raise PreconditionError(f"{caller}: A{lab[1]} is not Hurwitz ({cite('004')} Prop. 7 (ii)): eigenvalue {complex(worst):.4g}")
        checks.append(Check(f"A{lab[1]} Hurwitz ({cite('004')} Prop. 7 (ii))", True, f"max Re eig = {eig.real.max():.4g}"))
        mats[lab] = (An, rest)
    for s in X["x4"]:
        bad = depends(fx[s.name], X["x4"])
        if bad:
            raise PreconditionError(f"{caller}: {s}' = {fx[s.name]}: f4 must not depend on x4 ({cite('004')} eq. 40); it depends on {', '.join(bad)}")
    fk = fx[k]
    b = sp.Matrix([fk]).jacobian(sp.Matrix(X["x4"]))
    if depends(sum(b, sp.S.Zero), X["x4"]) or any(depends(e, X["x4"]) for e in b):
        raise PreconditionError(f"{caller}: {k}' = {fk} is not affine in x4 = {X['x4']} ({cite('004')} eq. 41: S_k = bᵀ(x1, x2, x3, u)x4)")
    f1k = sp.expand(fk - (b * sp.Matrix(X["x4"]))[0])
    checks.append(Check("model in the class (40)-(41)", True,
                        f"x1 = {x1}, x2 = {list(x2)}, x3 = {list(x3)}, x4 = {list(x4)}, k = {k}, b = {list(b)}"))
    est = estimator_from(estimator, default=Gradient(1.0), caller=caller)
    alpha = float(alpha)
    if not (np.isfinite(alpha) and alpha > 0):
        raise PreconditionError(f"{caller}: `alpha` must be positive ({cite('004')} eq. 37), got {alpha!r}")

    stack = StateStack(system)
    idx = {s: i for i, s in enumerate(names)}
    init = {lab: ca.vertcat(*[stack.xhat0[idx[s]] for s in blocks[lab]]) if blocks[lab] else ca.SX(0, 1)
            for lab in ("x2", "x3", "x4")}
    xh2 = stack.add("xhat2", len(x2), init=init["x2"]) if x2 else ca.SX(0, 1)
    xh3 = stack.add("xhat3", len(x3), init=init["x3"]) if x3 else ca.SX(0, 1)
    xi = stack.add("xi", len(x4), init=init["x4"])
    # x1 = y: the x1 states are read from the measurement (h[j] is the state measured by output j)
    lv = {**stack.leaves(), **{h[j]: stack.y[j] for j in range(len(h))}}
    lv.update({v: xh2[i] for i, v in enumerate(X["x2"])})
    lv.update({v: xh3[i] for i, v in enumerate(X["x3"])})
    if x2:
        stack.set_flow(xh2, ca.DM(mats["x2"][0]) @ xh2 + to_casadi(list(mats["x2"][1]), lv))     # (43)
    if x3:
        stack.set_flow(xh3, ca.DM(mats["x3"][0]) @ xh3 + to_casadi(list(mats["x3"][1]), lv))     # (44)
    stack.set_flow(xi, to_casadi([fx[s] for s in blocks["x4"]], lv))                           # (45)
    b_sx = to_casadi(list(b), lv)
    yk = stack.y[[str(e) for e in h].index(k)]
    # (47): Ŷ = W[y_k] - F[f_1k] - F[bᵀξ] = αy_k - F[αy_k + f_1k + bᵀξ], since W = α(1 - F)
    Yhat = alpha * yk - lowpass(stack, alpha * yk + to_casadi([f1k], lv) + b_sx.T @ xi, alpha, "F_Y")
    psi = lowpass(stack, b_sx, alpha, "F_b")
    out = est.build(stack, Regression(Yhat, psi, tuple(f"theta{i + 1}" for i in range(len(x4)))), np.zeros(len(x4)))
    parts = {str(e): stack.y[i] for i, e in enumerate(h)}
    for i, s in enumerate(x2):
        parts[s] = xh2[i]
    for i, s in enumerate(x3):
        parts[s] = xh3[i]
    x4hat = xi + out.theta                                                                        # (46)
    for i, s in enumerate(x4):
        parts[s] = x4hat[i]
    xhat = ca.vertcat(*[parts[s] for s in names])
    values = {"A2": mats["x2"][0], "A3": mats["x3"][0], "f1k": str(f1k), "b": str(list(b)), "alpha": alpha, **est.describe(),
              "excitation monitor": ExcitationMonitor.of(stack, out, est),
              "assumption (42)": "b along the trajectory must be persistently exciting (see excitation_report)",
              "internal states": stack.n_z}
    cert = Certificate("KKL+PEBO observer for the class of Proposition 7", REF + "; " + est.reference, tuple(checks), values)
    return stack.build("kkl_pebo_cascade", xhat=xhat, certificate=cert, xhat0=xhat0)
