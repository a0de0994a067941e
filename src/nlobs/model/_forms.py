"""Structured forms of a model: LTI, state-affine (Wang, Ortega & Bobtsov (2021), eq. 1) and output-injection (Besançon (2010)).

Each form converts to a general :class:`~nlobs.System` (``to_system``) and, where the
structure can be read off the equations, is recognised from one (``from_system``), with an
error naming the entry that breaks the form when it is not.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from ..errors import FormError, ShapeError
from ._expr import as_written
from ._system import FORMS, TIME, System, exact, symbol, to_expr

__all__ = ["LTI", "StateAffine", "OutputInjectionForm", "matrix_of"]


def _default_names(prefix: str, n: int) -> tuple[str, ...]:
    return tuple(f"{prefix}{i + 1}" for i in range(n))


def _array(M: Any, name: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    try:
        a = np.array(M, dtype=float)
    except (TypeError, ValueError) as e:
        raise ShapeError(f"`{name}` must be a numeric matrix: {e}") from None
    if a.ndim == 1 and rows is not None and cols == 1:
        a = a.reshape(-1, 1)
    if a.ndim == 1 and cols is not None and rows == 1:
        a = a.reshape(1, -1)
    if a.ndim != 2:
        raise ShapeError(f"`{name}` must be a 2-D matrix, got an array with {a.ndim} dimension(s)")
    if (rows is not None and a.shape[0] != rows) or (cols is not None and a.shape[1] != cols):
        want = f"({rows if rows is not None else '*'}, {cols if cols is not None else '*'})"
        raise ShapeError(f"incompatible dimensions of `{name}`: expected {want}, found {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ShapeError(f"`{name}` has non-finite entries")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, init=False)
class LTI:
    """A linear time-invariant model x' = Ax + Bu, y = Cx + Du.

    Parameters
    ----------
    A : array_like of shape (n, n)
    B : array_like of shape (n, m), optional
    C : array_like of shape (p, n)
    D : array_like of shape (p, m), optional
    states, inputs, outputs : sequence of str, optional
        Names (default ``x1..xn``, ``u1..um``, ``y1..yp``).
    name : str, optional
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    name: str

    def __init__(self, A: Any, B: Any = None, C: Any = None, D: Any = None, *,
                 states: Sequence[str] | None = None, inputs: Sequence[str] | None = None,
                 outputs: Sequence[str] | None = None, name: str = "lti"):
        A_ = _array(A, "A")
        n = A_.shape[0]
        if A_.shape != (n, n):
            raise ShapeError(f"`A` must be square, found {A_.shape}")
        if C is None:
            raise ShapeError("`C` is required: an LTI model needs an output matrix")
        B_ = np.zeros((n, 0)) if B is None else _array(B, "B", n, None if np.ndim(B) == 2 else 1)
        C_ = _array(C, "C", None if np.ndim(C) == 2 else 1, n)
        p, m = C_.shape[0], B_.shape[1]
        D_ = np.zeros((p, m)) if D is None else _array(D, "D", p, m)
        for k, v in (("A", A_), ("B", B_), ("C", C_), ("D", D_)):
            v = np.array(v)
            v.setflags(write=False)
            object.__setattr__(self, k, v)
        object.__setattr__(self, "states", tuple(states) if states is not None else _default_names("x", n))
        object.__setattr__(self, "inputs", tuple(inputs) if inputs is not None else _default_names("u", m))
        object.__setattr__(self, "outputs", tuple(outputs) if outputs is not None else _default_names("y", p))
        object.__setattr__(self, "name", name)
        for label, names, size in (("states", self.states, n), ("inputs", self.inputs, m), ("outputs", self.outputs, p)):
            if len(names) != size:
                raise ShapeError(f"{len(names)} {label} name(s) given for {size} {label}")

    def to_system(self) -> System:
        """The same model as a general :class:`~nlobs.System`."""
        x = sp.Matrix([symbol(s) for s in self.states])
        u = sp.Matrix([symbol(s) for s in self.inputs]) if self.inputs else sp.zeros(0, 1)

        def sym(M: np.ndarray) -> sp.Matrix:
            return sp.Matrix(M.shape[0], M.shape[1], [exact(v) for v in M.ravel()])

        f = sym(self.A) * x + (sym(self.B) * u if self.inputs else sp.zeros(len(self.states), 1))
        h = sym(self.C) * x + (sym(self.D) * u if self.inputs else sp.zeros(len(self.outputs), 1))
        return System(states=self.states, f=list(f), outputs=self.outputs, h=list(h),
                      inputs=self.inputs, name=self.name)

    @classmethod
    def from_system(cls, system: System) -> LTI:
        """Read (A, B, C, D) off a system whose f and h are linear in (x, u) with constant coefficients.

        Raises
        ------
        FormError
            Naming the first equation that is not linear with constant coefficients.
        """
        f, h = system.substituted()
        x, u = sp.Matrix(system.x), sp.Matrix(system.u)
        mats = {}
        for label, eqs, names, written in (("f", f, system.states, system.f), ("h", h, system.outputs, system.h)):
            Jx = eqs.jacobian(x)
            Ju = eqs.jacobian(u) if system.n_inputs else sp.zeros(len(eqs), 0)
            for i, name in enumerate(names):
                row = list(Jx.row(i)) + (list(Ju.row(i)) if system.n_inputs else [])
                bad = [k for k, e in enumerate(row) if e.free_symbols]
                # the message shows the equation as written (parameters by name, decimals as decimals)
                wx = sp.Matrix([written[i]]).jacobian(list(x) + list(u))
                if bad:
                    raise FormError(f"{system.name!r} is not LTI: {label}[{name}] = {as_written(written[i])} is not linear "
                                    f"in (x, u) with constant coefficients (a derivative is {as_written(wx[bad[0]])})")
                rest = sp.expand(eqs[i] - (Jx.row(i) * x)[0] - ((Ju.row(i) * u)[0] if system.n_inputs else 0))
                if rest != 0:
                    rest_w = sp.expand(written[i] - (wx * sp.Matrix(list(x) + list(u)))[0])
                    raise FormError(f"{system.name!r} is not LTI: {label}[{name}] = {as_written(written[i])} has the term "
                                    f"{as_written(rest_w)}, which is not proportional to a state or an input")
            mats[label] = (np.array(Jx, dtype=float), np.array(Ju, dtype=float).reshape(len(eqs), system.n_inputs))
        return cls(mats["f"][0], mats["f"][1], mats["h"][0], mats["h"][1], states=system.states,
                   inputs=system.inputs, outputs=system.outputs, name=system.name)


def matrix_of(value: Any, rows: int, cols: int, allowed: Mapping[str, sp.Symbol], *, name: str) -> sp.Matrix:
    """A SymPy matrix of the given shape from numbers, strings or SymPy entries.

    Every entry goes through the safe converter *before* the matrix is built (SymPy's
    ``Matrix`` constructor would otherwise parse strings with ``sympify``).
    """
    if isinstance(value, sp.MatrixBase):
        shape, entries = value.shape, list(value)
    else:
        try:
            arr = np.array(value, dtype=object)
        except Exception as e:  # noqa: BLE001 - anything unconvertible is a shape error
            raise ShapeError(f"`{name}` must be a matrix: {e}") from None
        if arr.ndim == 1 and cols == 1:
            arr = arr.reshape(-1, 1)
        elif arr.ndim == 1 and rows == 1:
            arr = arr.reshape(1, -1)
        elif arr.ndim == 0 and rows == cols == 1:
            arr = arr.reshape(1, 1)
        if arr.ndim != 2:
            raise ShapeError(f"`{name}` must be 2-D, got {arr.ndim} dimension(s)")
        shape, entries = arr.shape, list(arr.ravel())
    if tuple(shape) != (rows, cols):
        raise ShapeError(f"incompatible dimensions of `{name}`: expected ({rows}, {cols}), found {tuple(shape)}")
    converted = [to_expr(e, allowed, where=f"{name}[{k // cols}, {k % cols}]") for k, e in enumerate(entries)]
    return sp.Matrix(rows, cols, converted)


@dataclass(frozen=True, init=False)
class StateAffine:
    r"""A state-affine model (Wang, Ortega & Bobtsov (2021), eq. 1):

    .. math::

        \dot x = A(u, y, t)\,x + b(u, y, t), \qquad y = C(u, t)^\top x .

    Parameters
    ----------
    A : (n, n) matrix of expressions in the inputs, outputs, ``t`` and parameters
    b : (n,) vector of expressions in the inputs, outputs, ``t`` and parameters
    C : (n, p) matrix of expressions in the inputs, ``t`` and parameters; y = Cᵀx
    states, inputs, outputs : sequence of str, optional
    params : mapping of str to float, optional
    name : str, optional

    References
    ----------
    Wang, Ortega & Bobtsov (2021), eq. (1); Besançon (2010), "Kalman-like observer".
    """

    A: sp.Matrix
    b: sp.Matrix
    C: sp.Matrix
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    params: Mapping[str, float]
    name: str

    def __init__(self, A: Any, b: Any, C: Any, *, states: Sequence[str] | None = None,
                 inputs: Sequence[str] = (), outputs: Sequence[str] | None = None,
                 params: Mapping[str, float] | None = None, name: str = "state_affine"):
        n = len(states) if states is not None else int(np.shape(A)[0]) if not isinstance(A, sp.MatrixBase) else A.shape[0]
        Cshape = C.shape if isinstance(C, sp.MatrixBase) else np.shape(C)
        p = len(outputs) if outputs is not None else (Cshape[1] if len(Cshape) == 2 else 1)
        states_ = tuple(states) if states is not None else _default_names("x", n)
        outputs_ = tuple(outputs) if outputs is not None else _default_names("y", p)
        params_ = dict(params or {})
        # validate the names once through System (duplicates, reserved words)
        System(states=states_, f=[0] * n, outputs=outputs_, h=[0] * p, inputs=inputs, params=params_)
        base = {k: symbol(k) for k in (*inputs, *params_)}
        base["t"] = TIME
        with_y = {**base, **{k: symbol(k) for k in outputs_}}
        object.__setattr__(self, "A", matrix_of(A, n, n, with_y, name="A"))
        object.__setattr__(self, "b", matrix_of(b, n, 1, with_y, name="b"))
        object.__setattr__(self, "C", matrix_of(C, n, p, base, name="C"))
        object.__setattr__(self, "states", states_)
        object.__setattr__(self, "inputs", tuple(inputs))
        object.__setattr__(self, "outputs", outputs_)
        object.__setattr__(self, "params", dict(params_))
        object.__setattr__(self, "name", name)

    @property
    def n_states(self) -> int:
        return len(self.states)

    def to_system(self) -> System:
        """The general system, with y replaced by Cᵀx inside A and b."""
        x = sp.Matrix([symbol(s) for s in self.states])
        y_of_x = self.C.T * x
        subs = {symbol(k): y_of_x[i] for i, k in enumerate(self.outputs)}
        f = self.A.xreplace(subs) * x + self.b.xreplace(subs)
        return System(states=self.states, f=list(f), outputs=self.outputs, h=list(y_of_x),
                      inputs=self.inputs, params=self.params, name=self.name)


@dataclass(frozen=True)
class OutputInjectionForm:
    r"""A model in output-injection form (Besançon (2010), "Error linearization"):

    .. math::

        \dot x = A x + B(u, y, t), \qquad y = C x ,

    with A and C constant. The decomposition is not unique (terms linear in y may sit in
    A or in B); :meth:`from_system` puts in A only the part acting on ker C, so (A, C) has
    the same observability as any other choice (output injection does not change it).
    """

    A: np.ndarray
    C: np.ndarray
    B: tuple[sp.Expr, ...]
    system: System

    @classmethod
    def from_system(cls, system: System) -> OutputInjectionForm:
        r"""Recognise the form, or say which entry breaks it.

        Method: with K a basis of ker C, the model is in the form iff
        :math:`\partial f/\partial x \cdot K` is constant. Then
        :math:`A = (\partial f/\partial x\,K)(K^\top K)^{-1}K^\top` and
        :math:`B(u, y, t) = f(C^+ y, u, t)`.

        Raises
        ------
        FormError
        """
        f, h = system.substituted()
        x = sp.Matrix(system.x)
        n = system.n_states
        Cm = h.jacobian(x)
        for i, name in enumerate(system.outputs):
            if any(e.free_symbols for e in Cm.row(i)):
                raise FormError(f"{system.name!r} is not in output-injection form: output {name} = {h[i]} is not linear in x "
                                "with constant coefficients")
            if sp.expand(h[i] - (Cm.row(i) * x)[0]) != 0:
                raise FormError(f"{system.name!r} is not in output-injection form: output {name} = {h[i]} is not of the form Cx "
                                "(it has a term without a state)")
        K = sp.Matrix.hstack(*Cm.nullspace()) if Cm.rank() < n else sp.zeros(n, 0)
        J = f.jacobian(x)
        G = sp.simplify(J * K) if K.shape[1] else sp.zeros(n, 0)
        for i, name in enumerate(system.states):
            for j in range(G.shape[1]):
                if G[i, j].free_symbols:
                    bad = sorted(s.name for s in G[i, j].free_symbols)
                    raise FormError(
                        f"{system.name!r} is not in output-injection form: {name}' = {f[i]} depends on the unmeasured "
                        f"direction {list(K[:, j])} through {', '.join(bad)} (derivative {G[i, j]}); only terms in "
                        "the outputs and inputs may be nonlinear"
                    )
        A = G * (K.T * K).inv() * K.T if K.shape[1] else sp.zeros(n, n)
        ysyms = sp.Matrix(system.y)
        x_of_y = Cm.pinv() * ysyms
        B = sp.simplify(f.xreplace(dict(zip(system.x, x_of_y))))
        return cls(np.array(A, dtype=float), np.array(Cm, dtype=float), tuple(B), system)


# System.lti and System.state_affine build through these (model/_system.py reads them here instead of importing this module)
FORMS.update(LTI=LTI, StateAffine=StateAffine)
