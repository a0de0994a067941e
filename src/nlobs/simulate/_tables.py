"""Notes on a run that leaves the breakpoints of a model's lookup tables (where the table holds its end value or
extrapolates, by its `outside` policy, instead of giving measured values)."""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..engine import to_casadi
from ..model import TIME, System, symbol
from ..model._tables import table_calls

__all__ = ["table_range_notes"]


#: Whether a model (by its structure's key: tables do not depend on parameter values) calls a lookup table; a run of a
#: model without one skips the search through its expressions (a millisecond, a fifth of a short compiled run).
_HAS_TABLES: dict[str, bool] = {}


def table_range_notes(plant: System, t: np.ndarray, x: np.ndarray, u: np.ndarray) -> list[str]:
    """One note per table argument that leaves the table's breakpoints along the trajectory (t, x, u)."""
    has = _HAS_TABLES.get(plant.key)
    if has is None:
        has = _HAS_TABLES[plant.key] = bool(table_calls([*plant.f, *plant.h]))
    if not has:
        return []
    f, h = plant.substituted()
    calls = [c for c in table_calls([*f, *h]) if not c.order]
    if not calls or x is None:
        return []
    xs, us, ts = ca.SX.sym("x", plant.n_states), ca.SX.sym("u", plant.n_inputs), ca.SX.sym("t")
    leaves = {**{symbol(n): xs[i] for i, n in enumerate(plant.states)}, **{symbol(n): us[i] for i, n in enumerate(plant.inputs)},
              TIME: ts}
    notes = []
    for c in calls:
        fn = ca.Function("table_args", [xs, us, ts], [to_casadi(list(c.args), leaves)])
        vals = np.asarray(fn.map(t.size)(x.T, u.T if u.size else np.zeros((0, t.size)), t[None, :]), dtype=float)
        for j, (lo, hi) in enumerate(c.table.ranges):
            v = vals[j]
            out = (v < lo - 1e-12 * max(1.0, abs(lo))) | (v > hi + 1e-12 * max(1.0, abs(hi)))
            if out.any():
                k = int(np.argmax(out))
                side = f"below {lo:g} (down to {v.min():.4g})" if v[k] < lo else f"above {hi:g} (up to {v.max():.4g})"
                what = ("holds its end value" if c.table.outside == "hold" else "is extrapolated")
                notes.append(f"the run leaves the table `{c.table.name}`'s range [{lo:g}, {hi:g}] of its argument "
                             f"{c.args[j]}: from t = {t[k]:.6g} it is {side} for {100 * out.mean():.0f} % of the run; the "
                             f"table {what} there (outside = \"{c.table.outside}\"), a value that was not measured")
    return notes
