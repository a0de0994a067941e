r"""Lookup tables: measured characteristics (a battery's open-circuit voltage OCV(SOC), a motor's efficiency map
eff(speed, torque), a valve curve) used as functions in any model expression.

A model file declares them::

    [tables.ocv]                 # ocv(SOC) in any expression
    x = [0.0, 0.1, ..., 1.0]     # strictly increasing breakpoints
    y = [3.0, 3.45, ..., 4.2]
    method = "cubic"             # or "linear" (default)
    outside = "hold"             # or "extrapolate" (default "hold")

    [tables.eff]                 # eff(speed, torque): 2-D, len(x) rows of len(z) values
    x = [...]
    z = [...]
    y = [[...], ...]

Evaluation goes through CasADi's ``interpolant`` ("linear", or "bspline" for cubic: a C² interpolating spline),
so simulations, filters and the C export get exact derivatives. Outside the breakpoints the argument is clamped to
the end values ("hold", the default: a characteristic is not invented where it was not measured) or the interpolant
extrapolates ("extrapolate": the end polynomial piece continued).

In SymPy a table call is a function object (a subclass of :class:`TableCall` per table) whose derivative is another
table-call object (the interpolant's derivative), so symbolic Jacobians and the numeric backends all see it. The
structural analysis replaces each table by a generic smooth function (see :func:`generic_surrogates`).
"""

from __future__ import annotations

import hashlib
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ..errors import ModelError

__all__ = ["Table", "TableCall", "MAX_TABLE_POINTS", "table_calls", "generic_surrogates"]

#: The most values (breakpoints × breakpoints for a 2-D table) a table may hold.
MAX_TABLE_POINTS = 100_000
METHODS = ("linear", "cubic")
OUTSIDE = ("hold", "extrapolate")


@dataclass(frozen=True, eq=False)
class Table:
    """A 1-D table y(x) or a 2-D table y(x, z) with its interpolation `method` and `outside` policy."""

    name: str
    x: tuple[float, ...]
    y: tuple[Any, ...]
    z: tuple[float, ...] | None = None
    method: str = "linear"
    outside: str = "hold"
    _cache: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        where = f"table `{self.name}`"
        if self.method not in METHODS:
            raise ModelError(f"{where}: `method` must be \"linear\" or \"cubic\", got {self.method!r}")
        if self.outside not in OUTSIDE:
            raise ModelError(f"{where}: `outside` must be \"hold\" or \"extrapolate\", got {self.outside!r}")
        grids = [("x", self.x)] + ([("z", self.z)] if self.z is not None else [])
        for label, g in grids:
            a = np.asarray(g, dtype=float)
            if a.ndim != 1 or a.size < 2:
                raise ModelError(f"{where}: `{label}` needs at least 2 breakpoints, got {a.size}")
            if not np.all(np.isfinite(a)):
                raise ModelError(f"{where}: `{label}` has a value that is not finite")
            bad = np.flatnonzero(np.diff(a) <= 0)
            if bad.size:
                raise ModelError(f"{where}: `{label}` must be strictly increasing; {label}[{bad[0] + 1}] = {a[bad[0] + 1]:g} "
                                 f"follows {a[bad[0]]:g}")
        shape = (len(self.x),) if self.z is None else (len(self.x), len(self.z))
        try:
            y = np.asarray(self.y, dtype=float)
        except (TypeError, ValueError):
            raise ModelError(f"{where}: `y` must be numbers" + (" (len(x) rows of len(z) values)" if self.z else "")) from None
        if y.shape != shape:
            raise ModelError(f"{where}: `y` must have shape {shape} (" + ("one value per x" if self.z is None else
                             "len(x) rows of len(z) values") + f"), got {y.shape}")
        if y.size > MAX_TABLE_POINTS:
            raise ModelError(f"{where}: {y.size:,} values, more than the limit of {MAX_TABLE_POINTS:,}")
        if not np.all(np.isfinite(y)):
            i = np.argwhere(~np.isfinite(y))[0]
            raise ModelError(f"{where}: `y` has a value that is not finite at index {tuple(int(v) for v in i)}")
        if self.method == "cubic" and min(shape) < 4:
            raise ModelError(f"{where}: a cubic table needs at least 4 breakpoints per axis, got {min(shape)}; use "
                             "method = \"linear\"")

    @property
    def dims(self) -> int:
        return 1 if self.z is None else 2

    @property
    def values(self) -> np.ndarray:
        return np.asarray(self.y, dtype=float)

    @property
    def ranges(self) -> list[tuple[float, float]]:
        """[low, high] of each argument's breakpoints."""
        return [(self.x[0], self.x[-1])] + ([(self.z[0], self.z[-1])] if self.z is not None else [])

    @property
    def digest(self) -> str:
        data = repr((self.name, self.x, np.asarray(self.y, dtype=float).tolist(), self.z, self.method, self.outside))
        return hashlib.sha256(data.encode()).hexdigest()[:12]

    def interpolant(self) -> Any:
        """The CasADi interpolant (cached): "linear", or "bspline" for cubic; y flattened column-major as CasADi wants."""
        if "f" not in self._cache:
            import casadi as ca

            grid = [list(map(float, self.x))] + ([list(map(float, self.z))] if self.z is not None else [])
            data = self.values.ravel(order="F").tolist()
            self._cache["f"] = ca.interpolant(f"table_{self.name}", "linear" if self.method == "linear" else "bspline",
                                              grid, data)
        return self._cache["f"]

    def clamp(self, args: Sequence[Any], fmin: Any, fmax: Any) -> list[Any]:
        """The arguments held inside the breakpoints (policy "hold"), or unchanged ("extrapolate")."""
        if self.outside == "extrapolate":
            return list(args)
        return [fmax(fmin(a, hi), lo) for a, (lo, hi) in zip(args, self.ranges)]

    def function(self) -> type[TableCall]:
        """The SymPy function of this table (one class per table's data)."""
        return _function_class(self, ())

    def __call__(self, *args: Any) -> np.ndarray:
        """Numeric values at points (arrays broadcast), through the interpolant with the outside policy."""
        arrs = np.broadcast_arrays(*[np.asarray(a, dtype=float) for a in args])
        pts = self.clamp(arrs, np.minimum, np.maximum)
        flat = np.vstack([p.ravel() for p in pts])
        out = np.asarray(self.interpolant()(flat), dtype=float).reshape(arrs[0].shape)
        return out


class TableCall(sp.Function):
    """A table evaluated at its arguments (a subclass per table and derivative order; see :class:`Table`)."""

    table: Table
    order: tuple[int, ...] = ()       # partial derivatives taken, by argument index

    @classmethod
    def eval(cls, *args: Any) -> None:   # never simplified symbolically
        return None

    def fdiff(self, argindex: int = 1) -> sp.Expr:
        return _function_class(self.table, tuple(sorted((*self.order, argindex - 1))))(*self.args)

    def _sympystr(self, printer: Any) -> str:
        name = self.table.name + "".join("'" if i == 0 else "_z" for i in self.order)
        return f"{name}({', '.join(printer.doprint(a) for a in self.args)})"

    def _latex(self, printer: Any, exp: str | None = None) -> str:
        """The table's declared name, as the model file calls it (``cop(T_o)``); a derivative with a prime per
        derivative in the first argument and ∂_z per derivative in the second (``cop'(T_o)``)."""
        name = self.table.name
        tex = rf"\operatorname{{{name}}}" if name.isalnum() else rf"\mathrm{{{name.replace('_', chr(92) + '_')}}}"
        primes = sum(i == 0 for i in self.order)
        tex = r"\partial_{z}" * (len(self.order) - primes) + tex + ("'" * primes if primes else "")
        if exp is not None:
            tex = rf"{{{tex}}}^{{{exp}}}"
        return rf"{tex}{{\left({', '.join(printer._print(a) for a in self.args)} \right)}}"

    @classmethod
    def function(cls) -> Any:
        """The CasADi function of this call (or derivative) of one vector argument: the interpolant at the clamped
        arguments, differentiated by AD (cached per table and order)."""
        import casadi as ca

        key = ("ca", cls.order)
        cache = cls.table._cache
        if key not in cache:
            s = ca.SX.sym("a", cls.table.dims)
            e = cls.table.interpolant()(ca.vertcat(*cls.table.clamp(ca.vertsplit(s), ca.fmin, ca.fmax)))
            for i in cls.order:
                e = ca.jacobian(e, s[i])
            cache[key] = ca.Function(f"table_{cls.table.name}_d{''.join(map(str, cls.order))}", [s], [e])
        return cache[key]

    @classmethod
    def casadi(cls, *args: Any) -> Any:
        import casadi as ca

        return cls.function()(ca.vertcat(*args))

    @classmethod
    def numeric(cls, *args: Any) -> np.ndarray:
        arrs = np.broadcast_arrays(*[np.asarray(a, dtype=float) for a in args])
        out = np.asarray(cls.function()(np.vstack([a.ravel() for a in arrs])), dtype=float)
        return out.reshape(arrs[0].shape)


_CLASSES: dict[tuple[str, tuple[int, ...]], type[TableCall]] = {}


def _function_class(table: Table, order: tuple[int, ...]) -> type[TableCall]:
    """One TableCall subclass per (table data, derivative order), registered in this module so that expressions
    holding it pickle (within a process where the table is loaded)."""
    key = (table.digest, order)
    if key not in _CLASSES:
        name = f"{table.name}" if not order else f"d{''.join(map(str, order))}_{table.name}"
        clsname = f"_table_{table.digest}_{'_'.join(map(str, order)) or 'v'}"
        cls = type(clsname, (TableCall,), {"table": table, "order": order, "nargs": table.dims,
                                            "__module__": __name__, "_name_shown": name})
        cls.__qualname__ = clsname
        setattr(sys.modules[__name__], clsname, cls)
        _CLASSES[key] = cls
    return _CLASSES[key]


def table_calls(exprs: Sequence[sp.Expr]) -> list[TableCall]:
    """The table calls in `exprs` (each once, in order of appearance)."""
    out: list[TableCall] = []
    for e in exprs:
        for a in sp.preorder_traversal(e):
            if isinstance(a, TableCall) and a not in out:
                out.append(a)
    return out


def generic_surrogates(exprs: Sequence[sp.Expr], seed: int = 0) -> tuple[list[sp.Expr], list[str]]:
    """`exprs` with every table replaced by a generic smooth function of its arguments: a cubic polynomial (in each
    argument for a 2-D table) with random rational coefficients. A rank computed on the surrogate is the generic
    rank with the table treated as an unknown smooth function; it holds where the table's derivatives do not vanish
    (the returned notes say which tables)."""
    calls = table_calls(exprs)
    if not calls:
        return list(exprs), []
    rng = np.random.default_rng(seed + 7919)
    subs: dict[sp.Basic, sp.Expr] = {}
    names = []
    for c in calls:
        if c.order:
            continue
        coeffs = [sp.Rational(int(rng.integers(1, 97)), int(rng.integers(1, 13))) for _ in range(16)]
        a = c.args
        if len(a) == 1:
            poly = sum(coeffs[i] * a[0] ** i for i in range(4))
        else:
            poly = sum(coeffs[4 * i + j] * a[0] ** i * a[1] ** j for i in range(4) for j in range(4))
        subs[c] = poly
        names.append(c.table.name)
    out = [e.xreplace(subs) for e in exprs]
    if table_calls(out):
        raise ModelError("a derivative of a table appears in the model; the structural analysis handles table values only")
    note = (f"the table{'s' if len(set(names)) > 1 else ''} {', '.join(sorted(set(names)))} "
            f"{'are' if len(set(names)) > 1 else 'is'} treated as a generic smooth function of its arguments (a random "
            "cubic): the verdict holds where the table's derivatives are non-zero (a flat stretch of a table can hide a "
            "state)")
    return out, [note]


def parse_table(name: str, spec: Mapping[str, Any]) -> Table:
    """A table from its model-file table (keys x, y, optional z, method, outside)."""
    allowed = ("x", "y", "z", "method", "outside")
    extra = [k for k in spec if k not in allowed]
    if extra:
        raise ModelError(f"table `{name}`: unknown key `{extra[0]}`; a table has {', '.join(allowed)}")
    for k in ("x", "y"):
        if k not in spec:
            raise ModelError(f"table `{name}`: `{k}` is required")
    for k in ("x", "z"):
        if k in spec and (not isinstance(spec[k], list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                                    for v in spec[k])):
            raise ModelError(f"table `{name}`: `{k}` must be a list of numbers")
    z = tuple(float(v) for v in spec["z"]) if "z" in spec else None
    y = spec["y"]
    if not isinstance(y, list):
        raise ModelError(f"table `{name}`: `y` must be a list" + (" of rows" if z is not None else " of numbers"))
    if len(spec["x"]) * (len(z) if z is not None else 1) > MAX_TABLE_POINTS:
        raise ModelError(f"table `{name}`: more than the limit of {MAX_TABLE_POINTS:,} values")
    yy = tuple(tuple(r) if isinstance(r, list) else r for r in y)
    return Table(name, tuple(float(v) for v in spec["x"]), yy, z, str(spec.get("method", "linear")),
                 str(spec.get("outside", "hold")))
