"""The interval driver fed with the samples (Rows: times and one row per sample) instead of the interval table: the
compiled driver assembles each interval's row (t_k, t_{k+1} - t_k, B_k, B_{k+1}) itself, and must run exactly as on
the table."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nlobs.engine import find_compiler
from nlobs.engine._intervals import IntervalRunner, Rows

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler (the compiled driver)")


def _runner(backend: str) -> IntervalRunner:
    """A 2-state flow and jump that read every entry of a row of width w = 3 (so a misplaced column changes the
    result): x' = -a2 x + a3 t + a4 (the row's sample k), the jump adds a5..a7 (sample k + 1) weighted by dt."""
    s, a, th = ca.SX.sym("s", 2), ca.SX.sym("a", 8), ca.SX.sym("th", 2)
    t, h = th[0], th[1]

    def f(x: ca.SX, tt: ca.SX) -> ca.SX:
        return ca.vertcat(-a[2] * x[0] + a[3] * tt + a[4], -x[1] + a[0])

    k1 = f(s, t)
    k2 = f(s + h / 2 * k1, t + h / 2)
    k3 = f(s + h / 2 * k2, t + h / 2)
    k4 = f(s + h * k3, t + h)
    nxt = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    sub = ca.Function("sub", [s, a, th], [nxt, ca.fabs(a[2]) + 1])
    jump = ca.Function("jump", [s, a], [s + a[1] * ca.vertcat(a[5] - a[6], a[7]), ca.vertcat(s[0] * a[6], a[7])])
    return IntervalRunner(sub, jump, backend=backend)


def _samples(n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.05, 0.3, n + 1))   # irregular sample times
    return t, rng.normal(size=(n + 1, 3))


def test_the_table_of_rows_is_the_interval_table():
    t, B = _samples()
    A = Rows(t, B).table()
    for k in range(t.size - 1):   # written out row by row, independently of the vectorised construction
        np.testing.assert_array_equal(A[k], np.r_[t[k], t[k + 1] - t[k], B[k], B[k + 1]])


@pytest.mark.parametrize("backend", ["c", "vm"])
def test_a_run_on_the_samples_equals_the_run_on_the_table(backend):
    t, B = _samples()
    r = _runner(backend)
    s0, nmin = np.array([1.0, -0.5]), np.full(t.size - 1, 3.0)
    A = np.array([np.r_[t[k], t[k + 1] - t[k], B[k], B[k + 1]] for k in range(t.size - 1)])
    ref = r.run(s0, A, nmin, rate0=1.0)       # the first call builds the compiled driver on the table
    got = r.run(s0, Rows(t, B), nmin, rate0=1.0)
    assert got.backend == backend and ref.backend == backend
    np.testing.assert_array_equal(got.states, ref.states)   # bit for bit: the same row, the same arithmetic
    np.testing.assert_array_equal(got.outputs, ref.outputs)
    np.testing.assert_array_equal(got.substeps, ref.substeps)
    if backend == "c":   # rows 1.. of the outputs with a free row 0 for the caller
        assert got.olead is not None and got.olead.shape == (t.size, 2)
        np.testing.assert_array_equal(got.olead[1:], ref.outputs)
    assert np.abs(got.states).max() > 0.1 and np.ptp(got.outputs[:, 0]) > 0.1   # the row's entries moved the run
