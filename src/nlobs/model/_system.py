"""The model an engineer writes: x' = f(x, u, t, p), y = h(x, u, t, p)."""

from __future__ import annotations

import hashlib
import keyword
import re
from collections.abc import Iterable, Mapping, Sequence
from types import MappingProxyType
from typing import Any

import numpy as np
import sympy as sp

from .._text import LabelError, check_label, shorten, shorten_list
from ..errors import ModelError
from ._budget import check_tree, short_str
from ._expr import CONSTANTS, FUNCTIONS, ExpressionError, parse_expression
from ._tables import TableCall

__all__ = ["System", "TIME", "symbol", "exact", "ExprLike"]

ExprLike = str | sp.Expr | int | float

_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")  # used with fullmatch: `$` would accept a trailing newline
#: Names a model may not declare: time, the functions and constants of expressions. SymPy's own
#: names (I, E, N, S, O, Q, beta, ...) are free: expressions are parsed into nlobs's own symbols.
RESERVED = frozenset({"t", *FUNCTIONS, *CONSTANTS})

#: SymPy function classes the numeric engine can translate (see ``nlobs.engine``).
SUPPORTED_FUNCTIONS = (
    sp.sin, sp.cos, sp.tan, sp.asin, sp.acos, sp.atan, sp.atan2,
    sp.sinh, sp.cosh, sp.tanh, sp.exp, sp.log, sp.Abs, sp.sign,
)


def symbol(name: str) -> sp.Symbol:
    """The canonical SymPy symbol nlobs uses for `name` (real-valued)."""
    return sp.Symbol(name, real=True)


#: The time symbol ``t``.
TIME = symbol("t")

#: The structured forms that :meth:`System.lti` and :meth:`System.state_affine` build through, by class name. Filled
#: by ``model/_forms.py`` (whose classes build Systems) when it is imported, as the package's ``__init__`` does: this
#: module does not import that one, so the two do not import each other.
FORMS: dict[str, Any] = {}


def exact(value: float) -> sp.Rational:
    """The exact rational of a float's shortest decimal form (0.1 -> 1/10)."""
    return sp.Rational(repr(float(value)))


def _check_names(kind: str, names: Iterable[str]) -> tuple[str, ...]:
    if isinstance(names, str):
        raise ModelError(f"`{kind}` must be a list of names, got the string {names!r}; write [{names!r}]")
    out = tuple(names)
    for n in out:
        if not isinstance(n, str) or not _NAME.fullmatch(n) or keyword.iskeyword(n):
            raise ModelError(
                f"{kind[:-1] if kind.endswith('s') else kind} name {shorten(n, 40)} is not valid: names start "
                "with a letter and contain only letters, digits and underscores"
                + (" (and may not be a Python keyword)" if isinstance(n, str) and keyword.iskeyword(n) else "")
            )
        if n in RESERVED:
            raise ModelError(f"the name `{n}` is reserved (time `t`, functions and constants); rename it")
    return out


class System:
    r"""A dynamical system with named states, inputs, outputs and parameters.

    .. math::

        \dot x = f(x, u, t, p), \qquad y = h(x, u, t, p)

    `f` and `h` are SymPy expressions over the declared names and the time ``t``. A
    ``System`` is immutable: :meth:`with_params` returns a new one.

    Parameters
    ----------
    states : sequence of str
        State names, in order.
    f : sequence or mapping of expressions
        One time derivative per state: a list in state order, or a mapping
        ``{state: expression}``. Expressions are SymPy expressions, numbers or strings
        (parsed safely, see :func:`nlobs.model.parse_expression`).
    outputs : sequence of str
        Output names.
    h : sequence or mapping of expressions
        One expression per output.
    inputs : sequence of str, optional
        Input names.
    params : mapping of str to float, optional
        Parameter names and their values.
    name : str, optional
        A name used in reports.
    estimated_params : sequence of str, optional
        States that are unknown constant parameters appended to the state (their derivative
        is 0; in a discrete-time model their map is p[k+1] = p[k]); set by :meth:`augmented`, so
        that results can report them as parameters.
    time : {"continuous", "discrete"}, default "continuous"
        The time base. ``"discrete"``: `f` gives the next state, x[k+1] = f(x[k], u[k], t[k], p),
        with t[k] = k·`sample_time`, and y[k] = h(x[k], u[k], t[k], p).
    sample_time : float, optional
        Seconds per step of a discrete-time model (default 1); not allowed for a continuous one.
    tables : mapping of str to Table, optional
        Lookup tables the expressions may call by name (``"ocv(SOC)"``); see :class:`nlobs.model.Table`.

    Raises
    ------
    ModelError
        On duplicate or invalid names, a wrong number of equations, an unknown symbol or an
        unsupported function in an expression.

    Examples
    --------
    >>> vdp = System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1"],
    ...              outputs=["y"], h=["x1"], params={"mu": 1.0}, name="vdp")
    >>> vdp.n_states, vdp.with_params(mu=2.0).params["mu"]
    (2, 2.0)
    """

    __slots__ = ("_name", "_states", "_inputs", "_outputs", "_params", "_f", "_h", "_key", "_estimated", "_time",
                 "_sample_time")

    def __init__(
        self,
        *,
        states: Sequence[str],
        f: Sequence[ExprLike] | Mapping[str, ExprLike],
        outputs: Sequence[str],
        h: Sequence[ExprLike] | Mapping[str, ExprLike],
        inputs: Sequence[str] = (),
        params: Mapping[str, float] | None = None,
        name: str = "system",
        estimated_params: Sequence[str] = (),
        time: str = "continuous",
        sample_time: float | None = None,
        tables: Mapping[str, Any] | None = None,
    ):
        time_, ts = _time_base(time, sample_time)
        states_ = _check_names("states", states)
        inputs_ = _check_names("inputs", inputs)
        outputs_ = _check_names("outputs", outputs)
        params = dict(params or {})
        params_ = _check_names("params", params)
        if not states_:
            raise ModelError("a system needs at least one state")
        seen: dict[str, str] = {}
        for kind, names in (("state", states_), ("input", inputs_), ("output", outputs_), ("parameter", params_)):
            for n in names:
                if n in seen:
                    raise ModelError(f"the name `{n}` is declared twice (as {seen[n]} and as {kind}); names must be unique")
                seen[n] = kind
        values = {}
        for k, v in params.items():
            try:
                fv = float(v)
            except (TypeError, ValueError):
                raise ModelError(f"parameter `{k}` must be a number, got {v!r}") from None
            if not np.isfinite(fv):
                raise ModelError(f"parameter `{k}` must be finite, got {fv}")
            values[k] = fv

        allowed = {n: symbol(n) for n in (*states_, *inputs_, *params_)}
        allowed["t"] = TIME
        for tname, table in (tables or {}).items():
            if tname in allowed or tname in FUNCTIONS:
                raise ModelError(f"the table name `{tname}` is already a state, input, parameter or function name")
            allowed[tname] = table.function()
        try:
            object.__setattr__(self, "_name", check_label(name, "model name"))
        except LabelError as e:
            raise ModelError(f"{e} (got {shorten(name, 40)})") from None
        object.__setattr__(self, "_states", states_)
        object.__setattr__(self, "_inputs", inputs_)
        object.__setattr__(self, "_outputs", outputs_)
        object.__setattr__(self, "_params", MappingProxyType(values))
        object.__setattr__(self, "_f", _equations("f", f, states_, allowed))
        object.__setattr__(self, "_h", _equations("h", h, outputs_, allowed))
        estimated = tuple(estimated_params)
        for n in estimated:
            if n not in states_:
                raise ModelError(f"estimated parameter `{n}` is not a state of this system; states: {', '.join(states_)}")
            constant = symbol(n) if time_ == "discrete" else 0      # p[k+1] = p[k], or p' = 0
            if self._f[states_.index(n)] != constant:
                raise ModelError(f"estimated parameter `{n}` must be constant ({n}[k+1] = {n} in a discrete-time model, "
                                 f"{n}' = 0 in a continuous one), got {self._f[states_.index(n)]}")
        object.__setattr__(self, "_estimated", estimated)
        object.__setattr__(self, "_time", time_)
        object.__setattr__(self, "_sample_time", ts)
        structure = (states_, inputs_, outputs_, params_, [sp.srepr(e) for e in (*self._f, *self._h)])
        if time_ == "discrete":   # a continuous model keeps its key (compiled caches stay valid)
            structure = (*structure, time_, ts)
        key = hashlib.sha256(repr(structure).encode()).hexdigest()
        object.__setattr__(self, "_key", key)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError("System is immutable; use with_params() or build a new System")

    def __reduce__(self) -> tuple[Any, ...]:  # pickling (Monte Carlo on other processes)
        return (_rebuild, (self._states, self._f, self._outputs, self._h, self._inputs, dict(self._params), self._name,
                           self._estimated, self._time, self._sample_time))

    # -- names and sizes ---------------------------------------------------------------
    name = property(lambda self: self._name, doc="The system's name.")
    states = property(lambda self: self._states, doc="State names, in order.")
    inputs = property(lambda self: self._inputs, doc="Input names, in order.")
    outputs = property(lambda self: self._outputs, doc="Output names, in order.")
    params = property(lambda self: self._params, doc="Parameter values (read-only mapping).")
    f = property(lambda self: self._f, doc="The time derivatives, one SymPy expression per state.")
    h = property(lambda self: self._h, doc="The outputs, one SymPy expression per output.")
    key = property(lambda self: self._key, doc="A hash of the structure (names and expressions, not parameter values).")
    estimated_params = property(lambda self: self._estimated,
                                doc="States that are unknown constant parameters (see :meth:`augmented`).")
    time = property(lambda self: self._time, doc='The time base: "continuous" (ẋ = f) or "discrete" (x[k+1] = f).')
    sample_time = property(lambda self: self._sample_time,
                           doc="Seconds per step of a discrete-time model; None for a continuous one.")

    @property
    def is_discrete(self) -> bool:
        """Whether f is a map x[k+1] = f(x[k], ...) (``time="discrete"``)."""
        return self._time == "discrete"

    def _copy(self, **changes: Any) -> System:
        """A new System with some constructor arguments changed (the time base kept)."""
        args = dict(states=self._states, f=self._f, outputs=self._outputs, h=self._h, inputs=self._inputs,
                    params=self._params, name=self._name, estimated_params=self._estimated, time=self._time,
                    sample_time=self._sample_time)
        args.update(changes)
        return System(**args)

    @property
    def n_states(self) -> int:
        return len(self._states)

    @property
    def n_inputs(self) -> int:
        return len(self._inputs)

    @property
    def n_outputs(self) -> int:
        return len(self._outputs)

    @property
    def n_params(self) -> int:
        return len(self._params)

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(self._params)

    @property
    def param_values(self) -> np.ndarray:
        """Parameter values as an array, in the order of :attr:`param_names`."""
        return np.array(list(self._params.values()), dtype=float)

    # -- symbols -----------------------------------------------------------------------
    @property
    def x(self) -> tuple[sp.Symbol, ...]:
        """State symbols."""
        return tuple(symbol(n) for n in self._states)

    @property
    def u(self) -> tuple[sp.Symbol, ...]:
        """Input symbols."""
        return tuple(symbol(n) for n in self._inputs)

    @property
    def p(self) -> tuple[sp.Symbol, ...]:
        """Parameter symbols."""
        return tuple(symbol(n) for n in self._params)

    @property
    def y(self) -> tuple[sp.Symbol, ...]:
        """Output symbols (for forms such as A(u, y, t) that use the measured output)."""
        return tuple(symbol(n) for n in self._outputs)

    t = TIME

    @property
    def is_time_varying(self) -> bool:
        """Whether ``t`` appears explicitly in f or h."""
        return any(e.has(TIME) for e in (*self._f, *self._h))

    # -- derived objects ---------------------------------------------------------------
    def with_params(self, **values: float) -> System:
        """Return a copy with some parameter values replaced.

        Raises
        ------
        ModelError
            If a name is not a parameter of this system.
        """
        unknown = [k for k in values if k not in self._params]
        if unknown:
            raise ModelError(
                f"with_params: {', '.join(f'`{k}`' for k in unknown)} is not a parameter of "
                f"{self._name!r}; its parameters are: {', '.join(self._params) or '(none)'}"
            )
        return self._copy(params={**self._params, **values})

    def augmented(self, params: Sequence[str]) -> System:
        """The system with the parameters `params` appended to the state as unknown constants.

        Each named parameter becomes a state of the same name with derivative 0 (map p[k+1] = p[k] in
        a discrete-time model; so an observer of the augmented system estimates it jointly with the states); the other
        parameters keep their values. The new states are listed in :attr:`estimated_params`.

        Raises
        ------
        ModelError
            If a name is not a parameter of this system.

        Examples
        --------
        >>> s = System(states=["x"], f=["-k*x + u"], inputs=["u"], outputs=["y"], h=["x"], params={"k": 0.3})
        >>> a = s.augmented(["k"])
        >>> a.states, a.estimated_params, dict(a.params)
        (('x', 'k'), ('k',), {})
        """
        if isinstance(params, str):
            params = [params]
        names = tuple(params)
        unknown = [k for k in names if k not in self._params]
        if unknown or len(set(names)) != len(names):
            bad = unknown[0] if unknown else next(k for k in names if names.count(k) > 1)
            raise ModelError(f"augmented: `{bad}` is not a parameter of {self._name!r} (or is named twice); "
                             f"its parameters are: {', '.join(self._params) or '(none)'}")
        if not names:
            return self
        constant = [symbol(k) for k in names] if self.is_discrete else [0] * len(names)
        return self._copy(states=(*self._states, *names), f=(*self._f, *constant),
                          params={k: v for k, v in self._params.items() if k not in names},
                          estimated_params=(*self._estimated, *names))

    def with_name(self, name: str) -> System:
        """Return a copy with another name."""
        return self._copy(name=name)

    def substituted(self) -> tuple[sp.Matrix, sp.Matrix]:
        """f and h with the parameter values substituted (as exact rationals where possible)."""
        subs = {symbol(k): exact(v) for k, v in self._params.items()}
        return sp.Matrix(self._f).xreplace(subs), sp.Matrix(self._h).xreplace(subs)

    # -- dunder ------------------------------------------------------------------------
    def __eq__(self, other: object) -> bool:
        return (isinstance(other, System) and self._key == other._key and dict(self._params) == dict(other._params)
                and self._name == other._name and self._estimated == other._estimated)

    def __hash__(self) -> int:
        return hash((self._key, tuple(self._params.items()), self._name, self._estimated))

    def __repr__(self) -> str:
        base = f"System({self._name!r}, states={list(self._states)}, inputs={list(self._inputs)}, outputs={list(self._outputs)}, params={dict(self._params)}"
        return base + (f", time='discrete', sample_time={self._sample_time!r})" if self.is_discrete else ")")

    def __str__(self) -> str:
        def plural(n: int, word: str) -> str:
            return f"{n} {word}{'' if n == 1 else 's'}"

        head = [
            f"System {self._name!r}: {plural(self.n_states, 'state')} ({', '.join(self._states)})",
            f"{plural(self.n_inputs, 'input')}" + (f" ({', '.join(self._inputs)})" if self._inputs else ""),
            f"{plural(self.n_outputs, 'output')} ({', '.join(self._outputs)})",
        ]
        if self._params:
            head.append(f"{plural(self.n_params, 'parameter')} ({', '.join(f'{k}={v:g}' for k, v in self._params.items())})")
        lines = [", ".join(head)]
        if self.is_discrete:
            lines[0] += f", discrete time (sample_time = {self._sample_time:g} s)"
            lines += [f"  {n}[k+1] = {e}" for n, e in zip(self._states, self._f)]
        else:
            lines += [f"  {n}' = {e}" for n, e in zip(self._states, self._f)]
        lines += [f"  {n} = {e}" for n, e in zip(self._outputs, self._h)]
        return "\n".join(lines)

    # -- constructors for structured forms (see model/_forms.py, which fills FORMS) -----
    @staticmethod
    def lti(A: Any, B: Any = None, C: Any = None, D: Any = None, **names: Any) -> System:
        """An LTI system x' = Ax + Bu, y = Cx + Du; see :class:`nlobs.model.LTI`."""
        return FORMS["LTI"](A, B, C, D, **names).to_system()

    @staticmethod
    def state_affine(A: Any, b: Any, C: Any, **names: Any) -> System:
        """A state-affine system x' = A(u, y, t)x + b(u, y, t), y = C(u, t)ᵀx (Wang, Ortega & Bobtsov (2021), eq. 1).

        See :class:`nlobs.model.StateAffine`.
        """
        return FORMS["StateAffine"](A, b, C, **names).to_system()


def _rebuild(states: Any, f: Any, outputs: Any, h: Any, inputs: Any, params: Any, name: str,
             estimated: Any = (), time: str = "continuous", sample_time: float | None = None) -> System:
    return System(states=states, f=f, outputs=outputs, h=h, inputs=inputs, params=params, name=name, estimated_params=estimated,
                  time=time, sample_time=sample_time)


TIME_BASES = ("continuous", "discrete")


def _time_base(time: Any, sample_time: Any) -> tuple[str, float | None]:
    """The checked time base and sample time (1 s by default for a discrete-time model)."""
    if time not in TIME_BASES:
        raise ModelError(f"`time` must be \"continuous\" or \"discrete\", got {shorten(time, 40)}")
    if time == "continuous":
        if sample_time is not None:
            raise ModelError(f"`sample_time` = {shorten(sample_time, 40)} is given for a continuous-time model; a model whose "
                             "dynamics are the next state x[k+1] = f(x[k], ...) needs time = \"discrete\" as well (for "
                             "sampled measurements of a continuous model use [simulation] sample_period)")
        return "continuous", None
    if sample_time is None:
        return "discrete", 1.0
    try:
        ts = float(sample_time)
    except (TypeError, ValueError):
        raise ModelError(f"`sample_time` must be a number of seconds per step, got {shorten(sample_time, 40)}") from None
    if not (np.isfinite(ts) and ts > 0):
        raise ModelError(f"`sample_time` must be positive and finite (seconds per step), got {ts:g}")
    return "discrete", ts


def _equations(
    label: str,
    given: Sequence[ExprLike] | Mapping[str, ExprLike],
    names: tuple[str, ...],
    allowed: Mapping[str, sp.Symbol],
) -> tuple[sp.Expr, ...]:
    """Turn the user's f or h into a tuple of validated SymPy expressions, in `names` order."""
    what = "state" if label == "f" else "output"
    if isinstance(given, Mapping):
        extra = [k for k in given if k not in names]
        missing = [n for n in names if n not in given]
        if extra:
            raise ModelError(f"`{label}` has an equation for {', '.join(map(repr, extra))}, which is not a declared {what}; declared: {', '.join(names)}")
        if missing:
            raise ModelError(f"`{label}` has no equation for the {what}(s) {', '.join(map(repr, missing))}; give one per {what}")
        items = [(n, given[n]) for n in names]
    else:
        if isinstance(given, (str, sp.Basic)):
            given = [given]
        seq = list(given)
        if len(seq) != len(names):
            raise ModelError(f"`{label}` has {len(seq)} equation(s) but there are {len(names)} {what}s ({', '.join(names)}); give one per {what}")
        items = list(zip(names, seq))
    return tuple(to_expr(e, allowed, where=f"{label}[{n}]") for n, e in items)


def to_expr(value: ExprLike, allowed: Mapping[str, sp.Symbol], *, where: str) -> sp.Expr:
    """Convert a string, number or SymPy expression to a validated SymPy expression.

    Symbols are matched to `allowed` by name (whatever their SymPy assumptions), so
    expressions built with plain ``sympy.symbols`` work.
    """
    if isinstance(value, str):
        try:
            return check_tree(parse_expression(value, allowed), where)
        except ExpressionError as e:
            raise ModelError(f"{where}: {shorten(value)}: {e}") from None
    if isinstance(value, bool):
        raise ModelError(f"{where}: expected an expression, got {value!r}")
    if isinstance(value, (int, float, np.integer, np.floating)):
        if not np.isfinite(value):
            raise ModelError(f"{where}: the number {value} is not finite")
        return sp.Integer(int(value)) if float(value).is_integer() and abs(value) < 2**53 else sp.Float(float(value))
    if not isinstance(value, sp.Basic):
        raise ModelError(f"{where}: expected a string, number or SymPy expression, got {type(value).__name__}")
    expr = value
    if not isinstance(expr, sp.Expr):
        raise ModelError(f"{where}: expected a scalar expression, got {type(expr).__name__}")
    subs = {}
    check_tree(expr, where)
    for s in expr.free_symbols:
        if s.name not in allowed:
            raise ModelError(f"{where}: unknown symbol `{s.name[:40]}` in {short_str(expr)}; declared names: "
                             f"{shorten_list(sorted(allowed))}")
        subs[s] = allowed[s.name]
    expr = expr.xreplace(subs)
    for fn in expr.atoms(sp.Function):
        if isinstance(fn, TableCall):
            continue
        if isinstance(fn, sp.core.function.AppliedUndef) or not isinstance(fn, SUPPORTED_FUNCTIONS):
            raise ModelError(f"{where}: the function `{fn.func}` is not supported; supported: {', '.join(FUNCTIONS)}")
    if expr.has(sp.zoo, sp.oo, sp.nan, sp.I):
        raise ModelError(f"{where}: the expression {short_str(expr)} is infinite, undefined or complex")
    return expr
