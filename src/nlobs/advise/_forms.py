r"""Form recognition for the advisor: the exact checks of :mod:`nlobs.analysis`, behind a numeric screen.

The exact recognisers simplify ∂f/∂x·K symbolically (K a basis of ker C), which takes seconds on
trigonometric models such as a cart-pole. Both the output-injection and the state-affine forms require
∂f/∂x·K to be the same at two points with the same (u, y, t); if it differs numerically at random points
(by more than round-off), the model is certainly not in the form and the symbolic work is skipped. The
verdict then names the equation and the unmeasured direction, with the two values found.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from ..analysis import FormCheck, FormsReport, state_affine_form, triangular_form
from ..engine import compile_system
from ..errors import FormError
from ..model import OutputInjectionForm, System
from ..references import cite

__all__ = ["recognise"]


def _linear_output(system: System) -> np.ndarray | None:
    _, h = system.substituted()
    x = sp.Matrix(system.x)
    C = h.jacobian(x)
    if C.free_symbols or any(sp.expand(h[i] - (C.row(i) * x)[0]) != 0 for i in range(system.n_outputs)):
        return None
    return np.array(C, dtype=float)


def _screen(system: System, C: np.ndarray, along_kernel_only: bool, seed: int = 0) -> str:
    """'' when ∂f/∂x·K looks constant (over x, or along ker C only); else the reason it is not."""
    n = system.n_states
    _, s, Vt = np.linalg.svd(C) if C.size else (None, np.zeros(0), np.eye(n))
    r = int(np.sum(s > 1e-12))
    K = Vt[r:].T
    if K.shape[1] == 0:
        return ""
    comp = compile_system(system)
    rng = np.random.default_rng(seed)
    pv = system.param_values
    u = rng.normal(size=system.n_inputs)
    t = float(rng.uniform(0, 1))
    vals = []
    x0 = rng.normal(size=n)
    for _ in range(3):
        x = x0 + K @ rng.normal(size=K.shape[1]) if along_kernel_only else rng.normal(size=n)
        with np.errstate(all="ignore"):
            J = np.array(comp.f_x(t, x, u, pv), dtype=float)
        if not np.all(np.isfinite(J)):
            return ""                      # undecided numerically: leave it to the exact check
        vals.append(J @ K)
    scale = max(1.0, max(float(np.abs(v).max()) for v in vals))
    for v in vals[1:]:
        d = np.abs(v - vals[0])
        if d.max() > 1e-8 * scale:
            i, j = np.unravel_index(int(np.argmax(d)), d.shape)
            f, _ = system.substituted()
            direction = np.round(K[:, j] / np.abs(K[:, j]).max(), 4).tolist()
            what = ("depends on the unmeasured states even at a fixed output" if along_kernel_only else
                    "is not linear in the unmeasured direction")
            return (f"{system.name!r}: {system.states[i]}' = {f[i]} {what}: its derivative along {direction} changes from "
                    f"{vals[0][i, j]:.4g} to {v[i, j]:.4g} between two points (numerically)")
    return ""


def recognise(system: System) -> FormsReport:
    """Output injection, state-affine, triangular and Lipschitz forms (Besançon (2010); Wang, Ortega & Bobtsov (2021) eq. 1), as
    :func:`nlobs.analysis.recognise_forms`, with the numeric screen of this module in front of the symbolic work."""
    checks = []
    C = _linear_output(system)
    oi = f"output injection ({cite('002')})"
    why = _screen(system, C, False) if C is not None else ""
    if why:
        checks.append(FormCheck(oi, False, f"not in output-injection form: {why}"))
    else:
        try:
            form = OutputInjectionForm.from_system(system)
            checks.append(FormCheck(oi, True, "ẋ = Ax + B(u, y), y = Cx", {"A": form.A, "C": form.C, "B": form.B}))
        except FormError as e:
            checks.append(FormCheck(oi, False, str(e)))
    why = _screen(system, C, True) if C is not None else ""
    if why:
        checks.append(FormCheck(f"state-affine ({cite('000')} eq. 1)", False, f"not state-affine: {why}"))
    else:
        checks.append(state_affine_form(system))
    checks.append(triangular_form(system))
    lip = f"Lipschitz ({cite('002')})"
    if C is None:
        checks.append(FormCheck(lip, False, "the output is not y = Cx with a constant C"))
    else:
        checks.append(FormCheck(lip, True, "y = Cx; the Lipschitz constant of φ = f − Ax is bounded on the visited region "
                                "by the `lipschitz` candidate"))
    return FormsReport(system.name, tuple(checks))

