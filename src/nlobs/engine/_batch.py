"""Evaluate a CasADi function at many points, through fixed-size maps and NumPy buffers."""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import Any

import casadi as ca
import numpy as np

from ._deferred import raise_deferred

__all__ = ["PointEvaluator", "evaluate_many", "evaluate_one", "forget_point"]

CHUNK = 4096
#: Bytes of arguments copied per chunk of :func:`evaluate_many` at most (above 64 rows).
CHUNK_BYTES = 4 << 20
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
    # rows per chunk: at most CHUNK, and at most CHUNK_BYTES of copied arguments (a wide state, e.g. a 24-state
    # square-root UKF's 1,177 sigma-point entries, would otherwise copy 38 MB per chunk)
    width = sum(int(np.shape(a)[1]) for a in args if np.ndim(a) == 2)
    rows = max(64, min(CHUNK, CHUNK_BYTES // max(8 * width, 1)))
    k = 0
    while k < N:
        K = min(rows, N - k)
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
    with _POINT_LOCK:
        hit = _POINT.get(id(fn))
        if hit is not None and hit[0] is fn:
            _POINT.move_to_end(id(fn))
    if hit is not None and hit[0] is fn:   # a function evaluated before: its buffer is set up (a third of the cost)
        return hit[1](*args)[0]
    if not fn.sparsity_out(0).is_dense() or any(fn.nnz_in(i) != fn.numel_in(i) for i in range(fn.n_in())):
        out = np.asarray(fn(*args)[0] if fn.n_out() > 1 else fn(*args), dtype=float).reshape(-1, order="F")
        raise_deferred()
        return out
    if all(fn.nnz_out(i) == fn.numel_out(i) for i in range(fn.n_out())):
        ev_ = PointEvaluator(fn)
        with _POINT_LOCK:
            _POINT[id(fn)] = (fn, ev_)   # fn kept: its id is not reused while it is here
            if len(_POINT) > POINT_CACHE:
                _POINT.popitem(last=False)
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


#: Functions :func:`evaluate_one` keeps a :class:`PointEvaluator` for (the most recently used): a run's start evaluates
#: the same few (an observer's output, its initial state) at every call.
POINT_CACHE = 64
_POINT: OrderedDict[int, tuple[ca.Function, PointEvaluator]] = OrderedDict()
_POINT_LOCK = threading.Lock()


def forget_point(fn: ca.Function) -> None:
    """Drop the evaluator :func:`evaluate_one` keeps for `fn` (a caller done with a design; its functions are freed)."""
    with _POINT_LOCK:
        hit = _POINT.get(id(fn))
        if hit is not None and hit[0] is fn:
            del _POINT[id(fn)]


class PointEvaluator:
    """`fn` evaluated at one point at a time through one NumPy buffer set up once: every output, flat (column-major
    for a matrix). The arguments are copied into arrays the buffer points to, and the outputs copied out (a call costs
    a third of :func:`evaluate_one`'s, which sets the buffer up each time; it counts on short runs). A call made while
    another thread uses the buffer sets up its own. Functions with sparse inputs or outputs take the plain call.

    Parameters
    ----------
    fn : casadi.Function
        The function; its inputs are given as flat vectors (or scalars) of their sizes.
    """

    def __init__(self, fn: ca.Function) -> None:
        self.fn = fn
        n_in, n_out = fn.n_in(), fn.n_out()
        self.dense = (all(fn.nnz_in(i) == fn.numel_in(i) for i in range(n_in))
                      and all(fn.nnz_out(i) == fn.numel_out(i) for i in range(n_out)))
        self.sizes_in = [fn.numel_in(i) for i in range(n_in)]
        self._ins = [np.zeros(k) for k in self.sizes_in]
        self._outs = [np.zeros(fn.numel_out(i)) for i in range(n_out)]
        self._lock = threading.Lock()
        self._buf: Any = None
        self._ev: Any = None
        if self.dense:
            self._buf, self._ev = fn.buffer()
            for i, a in enumerate(self._ins):
                self._buf.set_arg(i, memoryview(a))
            for i, a in enumerate(self._outs):
                self._buf.set_res(i, memoryview(a))

    def __call__(self, *args: Any) -> list[np.ndarray]:
        """Every output of `fn` at the point `args`, as new flat arrays."""
        if not self.dense:
            res = self.fn(*args)   # one output: a DM, not a list
            out = [np.asarray(v, dtype=float).reshape(-1, order="F") for v in (res if isinstance(res, (list, tuple)) else [res])]
            raise_deferred()
            return out
        if not self._lock.acquire(blocking=False):   # in use by another thread: a buffer of its own
            return self._fresh(args)
        try:
            for i, (dst, a) in enumerate(zip(self._ins, args)):
                a = np.asarray(a, dtype=float).reshape(-1)
                if a.size != dst.size:
                    raise ValueError(f"{self.fn.name()}: argument {i} has {a.size} entries, expected {dst.size}")
                dst[:] = a
            self._ev()
            raise_deferred()
            return [o.copy() for o in self._outs]
        finally:
            self._lock.release()

    def _fresh(self, args: tuple[Any, ...]) -> list[np.ndarray]:
        buf, ev = self.fn.buffer()
        ins = [np.ascontiguousarray(a, dtype=float).reshape(-1) for a in args]
        outs = [np.empty(o.size) for o in self._outs]
        for i, (a, k) in enumerate(zip(ins, self.sizes_in)):
            if a.size != k:
                raise ValueError(f"{self.fn.name()}: argument {i} has {a.size} entries, expected {k}")
            buf.set_arg(i, memoryview(a))
        for i, o in enumerate(outs):
            buf.set_res(i, memoryview(o))
        ev()
        raise_deferred()
        return outs
