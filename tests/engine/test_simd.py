"""The lane-parallel batch (SIMD across trajectories) agrees with the scalar batch and the VM."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from nlobs.engine import find_compiler, rk4_step
from nlobs.engine._codegen import CompiledBatch
from nlobs.engine._integrate import run_batch
from nlobs.engine._simd import CompiledSimdBatch, simd_supported

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="the lane-parallel batch is generated C: needs a C compiler")


def _zoo_step():
    """A step using most operations the generator translates (and if_else, sign, fabs, atan2, pow)."""
    s, a, c = ca.SX.sym("s", 3), ca.SX.sym("a", 2), ca.SX.sym("c", 2)

    def rhs(t, x, k):
        return ca.vertcat(
            ca.sin(x[1]) * ca.exp(-x[2] ** 2) + ca.atan2(x[0], 1 + x[1] ** 2) - c[1] * x[0],
            ca.tanh(x[0] - x[2]) + ca.sqrt(1 + x[1] ** 2) * ca.cos(t) - ca.fabs(x[1]) ** 1.5 + a[1],
            ca.if_else(x[0] > 0, -x[2], x[2] / 2) + ca.sign(x[1]) * 0.1 + ca.log(2 + x[0] ** 2) - ca.fmax(x[2], -1),
        )

    nxt = rk4_step(rhs, a[0], s, c[0])
    return ca.Function("zoo", [s, a, c], [nxt, ca.vertcat(s[0] * s[1], ca.asinh(s[2]), ca.cosh(s[1] / 10))])


def test_every_operation_agrees_with_the_scalar_batch_for_an_odd_batch_size():
    step = _zoo_step()
    assert simd_supported(step)
    rng = np.random.default_rng(0)
    M, N = 13, 400  # 13 = one full block of 8 and a padded one
    S0 = rng.uniform(-1, 1, (M, 3))
    A = np.column_stack([np.arange(N + 1) * 0.01, np.sin(np.arange(N + 1) * 0.05)])
    C = np.column_stack([np.full(M, 0.01), rng.uniform(0.1, 1.0, M)])
    out = []
    for Batch in (CompiledBatch, CompiledSimdBatch):
        batch = Batch(step)
        S = np.full((M, 5, 3), np.nan)
        O = np.full((M, 5, 3), np.nan)
        status = np.zeros(M, dtype=np.int64)
        batch(S0, A, 0, C, C.shape[1], S, O, N, 100, np.inf, status)
        out.append((S, O, status))
    (S1, O1, st1), (S2, O2, st2) = out
    assert np.array_equal(st1, st2) and (st1 == N).sum() >= 8  # same runs finish, same ones stop, at the same step
    assert np.allclose(S1, S2, rtol=1e-12, atol=1e-12, equal_nan=True) and np.allclose(O1, O2, rtol=1e-12, atol=1e-12, equal_nan=True)


def test_per_lane_blow_up_and_per_trajectory_inputs_match_the_vm():
    s, a, c = ca.SX.sym("s", 1), ca.SX.sym("a", 1), ca.SX.sym("c", 1)
    step = ca.Function("riccati", [s, a, c], [rk4_step(lambda t, x, k: x**2 + a[0], 0, s, c[0]), s * 2])
    M, N = 10, 300
    S0 = np.linspace(0.1, 2.0, M)[:, None]
    A = np.random.default_rng(1).normal(0, 0.1, (M, N + 1, 1))  # a different input sequence per trajectory
    vm = run_batch(step, S0, A, np.array([1e-2]), N, stride=7, bound=1e6, backend="vm")
    simd = run_batch(step, S0, A, np.array([1e-2]), N, stride=7, bound=1e6, backend="c")
    assert np.array_equal(vm[2], simd[2]) and (vm[2] < N).sum() >= 4  # the larger x0 escape within t = 3
    assert np.allclose(vm[0], simd[0], rtol=1e-12, equal_nan=True) and np.allclose(vm[1], simd[1], rtol=1e-12, equal_nan=True)


def test_erfinv_remainder_and_lift_are_lane_parallel_and_agree_with_the_scalar_batch():
    s, a, c = ca.SX.sym("s", 2), ca.SX.sym("a", 1), ca.SX.sym("c", 1)
    nxt = ca.vertcat(ca.erfinv(ca.tanh(s[0])), ca.remainder(s[1] + c[0], 0.7) + ca.erf(s[0]))
    step = ca.Function("ops", [s, a, c], [nxt, ca.vertcat(ca.erfinv(0.999999 * ca.sin(s[1])))])
    assert simd_supported(step)
    M, N = 11, 40
    S0 = np.random.default_rng(2).uniform(-2, 2, (M, 2))
    A, C = np.zeros((N + 1, 1)), np.array([0.3])
    out = []
    for Batch in (CompiledBatch, CompiledSimdBatch):
        S, O = np.full((M, 2, 2), np.nan), np.full((M, 2, 1), np.nan)
        status = np.zeros(M, dtype=np.int64)
        Batch(step)(S0, A, 0, C, 0, S, O, N, N, np.inf, status)
        out.append((S, O))
    # erfinv is CasADi's own in the scalar code and Giles' approximation + 2 Newton steps in the lanes
    assert np.allclose(out[0][0], out[1][0], rtol=1e-12, atol=1e-13) and np.allclose(out[0][1], out[1][1], rtol=1e-12, atol=1e-13)
    assert abs(float(ca.erf(out[1][1][0, 0, 0])) - 0.999999 * np.sin(S0[0, 1])) < 1e-14  # erf(erfinv(v)) = v


def test_calls_to_non_inlined_functions_fall_back_to_the_scalar_batch():
    x = ca.SX.sym("x")
    g = ca.Function("g", [x], [ca.sin(x)], {"never_inline": True})
    f = ca.Function("f", [x], [g(x) * 2])  # an SX call node: no lane-parallel form
    assert not simd_supported(f)
