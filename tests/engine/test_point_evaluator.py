"""engine/_batch.PointEvaluator: a function at one point through a buffer set up once (the set-up of short runs)."""

from __future__ import annotations

import threading

import casadi as ca
import numpy as np
import pytest

from nlobs.engine._batch import PointEvaluator


def _fn():
    x, t = ca.SX.sym("x", 3), ca.SX.sym("t")
    return ca.Function("f", [x, t], [ca.sin(x) * t, ca.mtimes(x, x.T), ca.sum1(x)])


def test_every_output_equals_the_plain_call_column_major_and_is_a_new_array():
    f, ev = _fn(), PointEvaluator(_fn())
    for x, t in (([0.1, -2.0, 3.0], 0.5), ([1.0, 2.0, 4.0], -1.5)):
        got = ev(np.array(x), t)
        want = [np.asarray(v, dtype=float).reshape(-1, order="F") for v in f(x, t)]
        assert len(got) == 3
        for g, w in zip(got, want):
            np.testing.assert_array_equal(g, w)
    first = ev([0.0, 0.0, 1.0], 2.0)[0]
    ev([5.0, 5.0, 5.0], 1.0)
    np.testing.assert_array_equal(first, np.sin([0.0, 0.0, 1.0]) * 2.0)   # not overwritten by the next call


def test_a_wrong_size_is_refused_with_the_argument():
    with pytest.raises(ValueError, match="argument 0 has 2 entries, expected 3"):
        PointEvaluator(_fn())([1.0, 2.0], 1.0)


def test_threads_sharing_one_evaluator_each_get_their_own_point():
    ev, errors = PointEvaluator(_fn()), []

    def work(seed: int) -> None:
        rng = np.random.default_rng(seed)
        for _ in range(2000):
            x, t = rng.normal(size=3), float(rng.normal())
            if not np.array_equal(ev(x, t)[2], [np.sum(x)]):
                errors.append(seed)
                return

    threads = [threading.Thread(target=work, args=(s,)) for s in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert not errors


def test_a_sparse_output_takes_the_plain_call():
    x = ca.SX.sym("x", 2)
    f = ca.Function("g", [x], [ca.diag(x)])   # a sparse 2x2
    ev = PointEvaluator(f)
    assert not ev.dense
    np.testing.assert_array_equal(ev([1.0, 2.0])[0], [1.0, 0.0, 0.0, 2.0])


def test_evaluate_one_keeps_a_buffer_per_function_and_gives_fresh_results():
    """evaluate_one sets a function's buffer up once (engine._batch._POINT): every later call must still give that
    point's value (against CasADi's own call), as a new array, and another function must not get the first one's."""
    from nlobs.engine._batch import _POINT, evaluate_one

    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 2)
    f = ca.Function("f", [x, p], [ca.vertcat(x[0] * p[0], ca.sin(x[1]) + p[1], x[2] ** 2), ca.sumsqr(x)])
    g = ca.Function("g", [x, p], [ca.vertcat(x[0] - p[0], x[1], x[2] * p[1])])
    rng = np.random.default_rng(1)
    outs = []
    for _ in range(5):
        a, b = rng.normal(size=3), rng.normal(size=2)
        for fn in (f, g):
            got = evaluate_one(fn, a, b)
            np.testing.assert_allclose(got, np.asarray(fn(a, b)[0] if fn.n_out() > 1 else fn(a, b)).reshape(-1),
                                       rtol=0, atol=1e-15)
            outs.append(got)
    assert id(f) in _POINT and _POINT[id(f)][0] is f
    assert len({id(o) for o in outs}) == len(outs)   # a new array each time
    outs[-2][:] = np.nan                              # the caller's array is its own
    assert np.isfinite(evaluate_one(f, np.ones(3), np.ones(2))).all()
