"""Evaluate a CasADi function at many points, through fixed-size maps and NumPy buffers."""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import casadi as ca
import numpy as np

from ._deferred import raise_deferred

__all__ = ["evaluate_many", "evaluate_one"]

CHUNK = 4096
_MAPS: OrderedDict[tuple[int, int], tuple[ca.Function, ca.Function]] = OrderedDict()


def _mapped(fn: ca.Function, K: int) -> ca.Function:
    key = (id(fn), K)
    hit = _MAPS.get(key)
    if hit is not None and hit[0] is fn:
        _MAPS.move_to_end(key)
        return hit[1]
    m = fn.map(K)
    _MAPS[key] = (fn, m)  # keep fn alive so its id is not reused while cached
    if len(_MAPS) > 256:
        _MAPS.popitem(last=False)
    return m


def evaluate_many(fn: ca.Function, *args: np.ndarray) -> np.ndarray:
    """Evaluate `fn` (first output) at N points.

    Each argument is an array of shape (N, k) (one row per point) or (k,) (the same for every
    point). Returns an array of shape (N, m).
    """
    N = max((a.shape[0] for a in args if np.ndim(a) == 2), default=1)
    m = fn.size1_out(0) * fn.size2_out(0)
    out = np.empty((N, m))
    k = 0
    while k < N:
        K = min(CHUNK, N - k)
        g = _mapped(fn, K)
        buf, ev = g.buffer()
        keep: list[Any] = []
        for i, a in enumerate(args):
            a = np.asarray(a, dtype=float)
            block = a[k:k + K] if a.ndim == 2 else np.broadcast_to(a.reshape(1, -1), (K, a.size))
            block = np.ascontiguousarray(block)
            keep.append(block)
            buf.set_arg(i, memoryview(block))
        res = out[k:k + K]
        buf.set_res(0, memoryview(res))
        ev()
        raise_deferred()
        k += K
    return out


def evaluate_one(fn: ca.Function, *args: Any) -> np.ndarray:
    """The first output of `fn` at one point, as a flat NumPy vector (column-major for a matrix).

    Through a NumPy buffer when the output is dense (no DM conversion of the arguments and the
    result: a few microseconds instead of tens, which matters for the set-up of short runs);
    through the plain call otherwise.
    """
    if not fn.sparsity_out(0).is_dense() or any(fn.nnz_in(i) != fn.numel_in(i) for i in range(fn.n_in())):
        out = np.asarray(fn(*args)[0] if fn.n_out() > 1 else fn(*args), dtype=float).reshape(-1, order="F")
        raise_deferred()
        return out
    buf, ev = fn.buffer()
    keep = [np.ascontiguousarray(a, dtype=float).reshape(-1) for a in args]
    for i, a in enumerate(keep):
        if a.size != fn.numel_in(i):
            raise ValueError(f"{fn.name()}: argument {i} has {a.size} entries, expected {fn.numel_in(i)}")
        buf.set_arg(i, memoryview(a))
    out = np.empty(fn.numel_out(0))
    buf.set_res(0, memoryview(out))
    for i in range(1, fn.n_out()):  # other outputs: computed into scratch buffers
        scratch = np.empty(fn.nnz_out(i))
        keep.append(scratch)
        buf.set_res(i, memoryview(scratch))
    ev()
    raise_deferred()
    return out
