"""Precondition checks and linear gain computations shared by the designs.

Every check raises :class:`~nlobs.errors.PreconditionError` or
:class:`~nlobs.errors.ShapeError` whose message names the design, the failed condition
with its numbers, and what to change.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from .._text import shorten
from ..algebra._identity import Identity
from ..errors import PreconditionError, ShapeError
from ._base import Check

__all__ = ["check_matrix", "check_positive", "observer_gain", "identity_check"]


def identity_check(condition: str, verdicts: Sequence[Identity], labels: Sequence[str] | None = None) -> Check:
    """The Check of identities decided by :func:`nlobs.analysis.decide_identity` (none of which failed:
    the caller refuses a failed one with its residual).

    All hold: ``"holds"`` with the kind of evidence (symbolic, or exact arithmetic with the
    Schwartz-Zippel bound on the probability of a wrong verdict, summed over the identities).
    Any undecided: ``"assumed"``, naming which and why. Choice: an identity that cannot be
    decided (functions whose relations the exact tests do not know, e.g. atan or log
    identities) does not refuse the design: the user may be right, and the numbers at random
    points back them; but the certificate says that it was not verified.
    """
    labels = list(labels) if labels is not None else [f"identity {k + 1}" for k in range(len(verdicts))]
    open_ = [(lab, v) for lab, v in zip(labels, verdicts) if not v.holds]
    if open_:
        return Check.assumed(condition, "not verified for " + "; ".join(f"{lab} ({v.method})" for lab, v in open_)
                             + ". The design relies on it: check it by hand")
    bound = float(sum(v.error_bound for v in verdicts))
    kinds = sorted({v.evidence.split(" (Schwartz")[0] for v in verdicts})
    evidence = ", ".join(kinds) + (f"; P(wrong) <= {bound:.0e} (Schwartz-Zippel)" if bound > 0 else "")
    n = len(verdicts)
    return Check(condition, "holds", f"{n} identit{'y' if n == 1 else 'ies'} decided exactly", evidence)


def check_matrix(M: Any, rows: int, cols: int, name: str, caller: str, *,
                 symmetric: bool = False, definite: str | None = None) -> np.ndarray:
    """Validate a numeric matrix; a scalar is accepted for a 1x1 matrix.

    Parameters
    ----------
    M : array_like
        The matrix to check.
    rows, cols : int
        The expected shape.
    name, caller : str
        The argument's name and the function checking it, for the message.
    symmetric : bool
        Require (and return) a symmetric matrix.
    definite : {"positive", "semidefinite"}, optional
        Require the (symmetric) matrix to be positive definite or semidefinite.
    """
    try:
        a = np.array(M, dtype=float)
    except (TypeError, ValueError) as e:
        raise ShapeError(f"{caller}: `{name}` must be a numeric matrix: {e}") from None
    if a.ndim == 0 and rows == cols == 1:
        a = a.reshape(1, 1)
    elif a.ndim == 1 and cols == 1 and a.size == rows:
        a = a.reshape(rows, 1)
    elif a.ndim == 1 and rows == 1 and a.size == cols:
        a = a.reshape(1, cols)
    if a.shape != (rows, cols):
        raise ShapeError(f"{caller}: incompatible dimensions of `{name}`: expected ({rows}, {cols}) but found {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ShapeError(f"{caller}: `{name}` has non-finite entries")
    if symmetric or definite:
        if not np.allclose(a, a.T, rtol=1e-10, atol=1e-12 * max(1.0, np.abs(a).max(initial=0))):
            raise PreconditionError(f"{caller}: `{name}` must be symmetric; max |{name} - {name}ᵀ| = {np.abs(a - a.T).max():.3g}")
        a = (a + a.T) / 2
    if definite:
        lam = np.linalg.eigvalsh(a).min()
        if definite == "positive" and lam <= 0:
            raise PreconditionError(f"{caller}: `{name}` must be positive definite; its smallest eigenvalue is {lam:.3g}")
        if definite == "semidefinite" and lam < -1e-12 * max(1.0, np.abs(a).max()):
            raise PreconditionError(f"{caller}: `{name}` must be positive semidefinite; its smallest eigenvalue is {lam:.3g}")
    return a


def check_positive(value: Any, name: str, caller: str) -> float:
    """`value` as a float, or a PreconditionError (a ValueError) naming `name` and `caller` unless it
    is a finite number > 0."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if not (np.isfinite(v) and v > 0):
        raise PreconditionError(f"{caller}: `{name}` must be a positive number (finite and > 0), got {value!r}")
    return v


def _poles(poles: Any, n: int, caller: str) -> np.ndarray:
    try:
        p = np.atleast_1d(np.asarray(poles, dtype=complex)).ravel()
    except (TypeError, ValueError):
        raise ShapeError(f"{caller}: `poles` must be {n} numbers (real, or complex in conjugate pairs such as -1+2j, "
                         f"-1-2j), one per state; got {shorten(str(poles), 60)}") from None
    if p.size != n:
        raise ShapeError(f"{caller}: `poles` must list {n} poles (one per state), got {p.size}")
    if not np.all(np.isfinite(p)):
        raise ShapeError(f"{caller}: `poles` has non-finite entries")
    unstable = p[p.real >= 0]
    if unstable.size:
        raise PreconditionError(f"{caller}: the requested pole {complex(unstable[0]):.4g} is not in the open left half-plane; "
                                "an observer's error dynamics must be stable: choose poles with negative real part")
    cplx = p[np.abs(p.imag) > 0]
    if not np.allclose(np.sort_complex(cplx), np.sort_complex(cplx.conj())):
        raise PreconditionError(f"{caller}: complex poles must come in conjugate pairs; got {p}")
    return p


def observer_gain(A: np.ndarray, C: np.ndarray, *, poles: Any = None, L: Any = None, Q: Any = None,
                  R: Any = None, caller: str) -> tuple[np.ndarray, list[Check], dict[str, Any]]:
    """An output-injection gain L with A - LC Hurwitz, from poles, LQE weights or given directly.

    Exactly one of `poles`, `L`, or the pair (`Q`, `R`) must be given; `A` (n x n) and `C`
    (p x n) are the pair, `caller` names the design in messages.

    - `poles`: pole placement on the dual pair (Aᵀ, Cᵀ) with
      :func:`scipy.signal.place_poles`; requires (A, C) observable.
    - `Q`, `R`: the steady-state Kalman (LQE) gain L = P Cᵀ R⁻¹, P from the filter Riccati
      equation A P + P Aᵀ - P Cᵀ R⁻¹ C P + Q = 0 (:func:`scipy.linalg.solve_continuous_are`);
      requires (A, C) detectable, Q ⪰ 0, R ≻ 0.
    - `L`: checked for A - LC Hurwitz.

    Returns
    -------
    L : numpy.ndarray of shape (n, p)
    checks : list of Check
    values : dict
        ``L``, ``eigenvalues`` of A - LC, ``decay_rate`` (-max Re), and the design inputs.
    """
    from ..analysis import kalman_rank, pbh_test  # here, not at the top: a Monte Carlo worker loads no analysis
    n, p = A.shape[0], C.shape[0]
    given = [k for k, v in (("poles", poles), ("L", L), ("Q/R", Q if Q is not None else R)) if v is not None]
    if len(given) != 1:
        raise PreconditionError(f"{caller}: give exactly one of `poles`, `L`, or `Q` with `R`; got "
                                f"{', '.join(given) if given else 'none'}")
    obs = kalman_rank(A, C)
    checks: list[Check] = []
    values: dict[str, Any] = {}
    if poles is not None:
        if not obs.observable:
            raise PreconditionError(f"{caller}: {obs}. Choose another output or check the model.")
        checks.append(Check("(A, C) observable (Kalman rank)", True, f"rank O = {obs.rank} = n"))
        wanted = _poles(poles, n, caller)
        import scipy.signal  # deferred: importing scipy.signal costs ~0.6 s, and `nlobs analyze` must start fast

        try:
            res = scipy.signal.place_poles(A.T, C.T, wanted)
        except (ValueError, np.linalg.LinAlgError) as e:
            raise PreconditionError(f"{caller}: the poles {wanted} can't be placed ({e}); with {p} output(s) a pole may be "
                                    f"repeated at most {p} time(s): try distinct poles") from e
        gain = res.gain_matrix.T
        values["requested_poles"] = wanted
    elif L is not None:
        gain = check_matrix(L, n, p, "L", caller)
    else:
        Qm = check_matrix(Q, n, n, "Q", caller, definite="semidefinite")
        if R is None:
            raise PreconditionError(f"{caller}: `Q` was given without `R`; the LQE gain needs both")
        Rm = check_matrix(R, p, p, "R", caller, definite="positive")
        pbh = pbh_test(A, C)
        if not pbh.detectable:
            raise PreconditionError(f"{caller}: (A, C) is not detectable: {pbh}. No stable observer exists for this output.")
        checks.append(Check("(A, C) detectable (PBH)", True, str(pbh)))
        try:
            import scipy.linalg  # deferred: keeps `import nlobs` fast

            P = scipy.linalg.solve_continuous_are(A.T, C.T, Qm, Rm)
        except (ValueError, np.linalg.LinAlgError) as e:
            raise PreconditionError(f"{caller}: the filter Riccati equation has no stabilising solution ({e}); "
                                    "check that (A, Q^(1/2)) has no uncontrollable mode on the imaginary axis") from e
        gain = P @ C.T @ np.linalg.inv(Rm)
        values["P"] = P
    eig = np.linalg.eigvals(A - gain @ C)
    eig = eig[np.lexsort((eig.imag, eig.real))]
    if np.max(eig.real) >= 0:
        worst = eig[np.argmax(eig.real)]
        raise PreconditionError(f"{caller}: the gain L does not make A - LC Hurwitz: eigenvalue {complex(worst):.4g} has "
                                "Re >= 0; the estimation error would not converge. Choose another L.")
    checks.append(Check("A - LC Hurwitz", True, f"max Re(eig) = {eig.real.max():.4g}"))
    values = {"L": gain, "eigenvalues": eig, "decay_rate": float(-eig.real.max()), **values}
    if obs.observable:
        values["observability_rank"] = obs.rank
    return gain, checks, values
