"""Linear and along-trajectory observability: Kalman decomposition, LTV Gramian and UCO (000),
empirical Gramian and indistinguishability (002)."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import DataError, ShapeError, StateAffine, System
from nlobs.analysis import (empirical_gramian, indistinguishable, kalman_decomposition, kalman_rank, ltv_gramian,
                            state_affine_ltv, uco_test)


def vanishing_A(t):
    """000 §1 / M8 item 7: A = [[0, u(t)], [0, 0]], C = [1, 0], u(t) = e^{-t}."""
    return [[0.0, np.exp(-t)], [0.0, 0.0]]


def exact_delta(t, T):
    r"""Independent closed form: Φ(τ, t) = [[1, U], [0, 1]] with U = e^{-t}(1 - e^{-(τ-t)}), so
    W(t, t+T) = [[T, e^{-t} a], [e^{-t} a, e^{-2t} b]], a = ∫_0^T g, b = ∫_0^T g², g(s) = 1 - e^{-s}."""
    a = T - 1 + np.exp(-T)
    b = T - 2 * (1 - np.exp(-T)) + (1 - np.exp(-2 * T)) / 2
    W11, W12, W22 = T, np.exp(-t) * a, np.exp(-2 * t) * b
    tr, det = W11 + W22, W11 * W22 - W12**2
    return tr / 2 - np.sqrt(tr**2 / 4 - det)


class TestKalmanDecomposition:
    def test_blocks_and_modes(self):
        # a double integrator seen through its position plus a decoupled stable mode the output ignores
        A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -2.0]])
        C = np.array([[1.0, 0.0, 0.0]])
        d = kalman_decomposition(A, C)
        assert d.n_observable == 2
        np.testing.assert_allclose(d.A_bar[:2, 2:], 0, atol=1e-12)
        np.testing.assert_allclose(d.C_bar[:, 2:], 0, atol=1e-12)
        np.testing.assert_allclose(d.T.T @ d.T, np.eye(3), atol=1e-12)
        assert kalman_rank(d.A_o, d.C_o).observable
        np.testing.assert_allclose(d.unobservable_eigenvalues, [-2.0])
        assert d.detectable and "detectable" in str(d)

    def test_001_toy_augmented_pair(self):
        # 001 §IV-C eq. (21): O = [[1,0,0],[0,0,1],[0,2c,0]] is full rank iff c != 0
        for c, rank in ((0.5, 3), (0.0, 2)):
            A = [[0, 0, 1], [0, 0, 0], [0, 2 * c, 0]]
            assert kalman_decomposition(A, [[1, 0, 0]]).n_observable == rank

    @pytest.mark.parametrize("A, C, match", [
        ([[0, 1, 0], [0, 0, 1]], [[1, 0, 0]], "square"),
        (np.eye(2), [[1, 0, 0]], "incompatible dimensions of `C`"),
        ([[np.nan, 0], [0, 0]], [[1, 0]], "non-finite"),
    ])
    def test_bad_pairs(self, A, C, match):
        with pytest.raises(ShapeError, match=match):
            kalman_decomposition(A, C)


class TestLTVGramian:
    def test_000_observable_but_not_uco(self):
        # 000: rank W(0, T) = n (Prop. 1) while W(t, t+T) ≥ δI (eq. 4) fails: δ(t) -> 0
        t = np.linspace(0, 12, 1201)
        g = ltv_gramian(vanishing_A, [[1, 0]], t[:301])
        assert g.observable and g.rank == 2
        u = uco_test(vanishing_A, [[1, 0]], t, 1.0, stride=10)
        np.testing.assert_allclose(u.delta, exact_delta(u.starts, 1.0), rtol=1e-5)
        assert not u.uniform and u.worst_start == pytest.approx(11.0)
        assert u.delta[-1] < 1e-9 * u.delta[0]
        assert "excitation is lost" in str(u)

    def test_constant_input_is_uco(self):
        # u = 1 (002: a universal input): W(t, t+T) = [[T, T²/2], [T²/2, T³/3]] for every t;
        # with T = 1 its smallest eigenvalue is 2/3 - sqrt(4/9 - 1/12)
        t = np.linspace(0, 5, 501)
        u = uco_test([[0, 1], [0, 0]], [[1, 0]], t, 1.0)
        assert u.uniform and np.ptp(u.delta) < 1e-10
        np.testing.assert_allclose(u.delta, 2 / 3 - np.sqrt(4 / 9 - 1 / 12), rtol=1e-9)

    def test_unobservable_direction(self):
        g = ltv_gramian([[0, 0], [0, 0]], [[1, 0]], np.linspace(0, 1, 11))
        assert not g.observable and g.rank == 1
        np.testing.assert_allclose(np.abs(g.unobservable_directions), [[0, 1]], atol=1e-12)

    def test_state_affine_along_measured_input(self):
        # the same example written as a state-affine model (000 eq. 1), frozen along u(t) = e^{-t}
        t = np.linspace(0, 12, 1201)
        sa = StateAffine([["0", "u"], ["0", "0"]], [0, 0], [[1], [0]], inputs=["u"])
        A, C = state_affine_ltv(sa, t, u=np.exp(-t))
        np.testing.assert_allclose(A, np.array([vanishing_A(x) for x in t]), atol=1e-15)
        u = uco_test(A, C, t, 1.0, stride=10)
        np.testing.assert_allclose(u.delta, exact_delta(u.starts, 1.0), rtol=1e-4)

    def test_bad_input(self):
        t = np.linspace(0, 1, 11)
        sa = StateAffine([["0", "u"], ["0", "0"]], [0, 0], [[1], [0]], inputs=["u"])
        with pytest.raises(ShapeError, match="has 5 samples but the time grid has 11"):
            state_affine_ltv(sa, t, u=np.zeros(5))
        with pytest.raises(DataError, match="not finite"):
            state_affine_ltv(sa, t, u=np.full(11, np.nan))
        with pytest.raises(ShapeError, match="square"):
            ltv_gramian([[0, 1, 2]], [[1, 0, 0]], t)
        with pytest.raises(ShapeError, match="sampled at 3 times"):
            ltv_gramian(np.zeros((3, 2, 2)), [[1, 0]], t)
        with pytest.raises(DataError, match="uniform grid"):
            uco_test(np.zeros((2, 2)), [[1, 0]], np.r_[0, 0.1, 0.3, 0.4], 0.1)
        with pytest.raises(DataError, match="window"):
            uco_test(np.zeros((2, 2)), [[1, 0]], t, 5.0)


class TestAlongTrajectory:
    def bilinear(self):
        return System(states=["x1", "x2"], f=["u*x2", "0"], outputs=["y"], h=["x1"], inputs=["u"])

    def test_002_universal_and_singular_input(self):
        # 002: u = 1 universal, u = 0 singular; for u = 1, y = x1 + x2 t so W = [[T, T²/2], [T²/2, T³/3]]
        s, T = self.bilinear(), 2.0
        g1 = empirical_gramian(s, [1.0, 2.0], t_final=T, dt=0.01, inputs=1)
        np.testing.assert_allclose(g1.W, [[T, T**2 / 2], [T**2 / 2, T**3 / 3]], rtol=1e-4)
        assert g1.observable
        g0 = empirical_gramian(s, [1.0, 2.0], t_final=T, dt=0.01, inputs=0)
        assert not g0.observable and np.allclose(np.abs(g0.unobservable_directions), [[0, 1]])
        gd = empirical_gramian(s, [1.0, 2.0], t_final=T, dt=0.01, inputs=1, method="difference")
        np.testing.assert_allclose(gd.W, g1.W, rtol=1e-6)

    def test_001_toy_indistinguishable_pair(self):
        # 001 §IV-C with c = 0: y = x1 + x2² t, so (2, -2) and (2, 2) give the same output; for
        # c = 0.5 the outputs differ by 2 c x2 t² = 2 t² (50 at t = 5)
        toy = System(states=["x1", "x2"], f=["x2**2", "c"], outputs=["y"], h=["x1"], params={"c": 0.0})
        r0 = indistinguishable(toy, [2, -2], [2, 2], t_final=5)
        assert r0.indistinguishable and r0.max_difference < 1e-9
        r1 = indistinguishable(toy, [2, -2], [2, 2], t_final=5, params={"c": 0.5})
        assert not r1.indistinguishable and r1.max_difference == pytest.approx(50, rel=1e-6)

    def test_bad_initial_state(self):
        with pytest.raises(ShapeError, match="2 finite numbers"):
            empirical_gramian(self.bilinear(), [1.0], t_final=1)
        with pytest.raises(DataError, match="dt"):
            indistinguishable(self.bilinear(), [1, 2], [1, 3], t_final=1, dt=-1)
