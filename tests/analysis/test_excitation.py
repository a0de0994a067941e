"""Excitation: IE (000 eq. 15) vs PE, identifiability (000 S2, Prop. 2), regular persistence and
local regularity (002)."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import DataError, ShapeError, StateAffine
from nlobs.analysis import (identifiability_rank, interval_excitation, local_regularity, persistent_excitation,
                            regular_persistence)

T_GRID = np.linspace(0, 20, 2001)


def gpebo_regressor(t):
    """000 Lemma 1 for A = [[0, e^{-t}], [0, 0]], C = [1, 0]: ψ = Φ_Aᵀ C = [1, 1 - e^{-t}]."""
    return np.column_stack([np.ones_like(t), 1 - np.exp(-t)])


def bilinear_sa():
    return StateAffine([["0", "u"], ["0", "0"]], [0, 0], [[1], [0]], inputs=["u"])


def test_000_regressor_is_ie_but_not_pe():
    # closed form of ∫_0^t ψψᵀ with U = 1 - e^{-s}: [[t, t - 1 + e^{-t}], [., t - 2(1 - e^{-t}) + (1 - e^{-2t})/2]]
    t = T_GRID
    ie = interval_excitation(t, gpebo_regressor(t), C_d=0.1)
    a = t[-1] - 1 + np.exp(-t[-1])
    b = t[-1] - 2 * (1 - np.exp(-t[-1])) + (1 - np.exp(-2 * t[-1])) / 2
    exact = np.linalg.eigvalsh([[t[-1], a], [a, b]])[0]
    assert ie.excited and ie.level == pytest.approx(exact, rel=1e-3)  # trapezoid, dt = 0.01: O(dt²) on a small eigenvalue
    assert 0 < ie.t_excited < t[-1]
    pe = persistent_excitation(t, gpebo_regressor(t), 1.0)
    assert not pe.excited and pe.level < 1e-8  # ψ tends to a constant direction: excitation fades


def test_pe_of_a_sinusoid():
    # ∫_t^{t+2π} [1, sin]ᵀ[1, sin] = diag(2π, π) for every t: α = π
    t = np.linspace(0, 20, 4001)
    pe = persistent_excitation(t, np.column_stack([np.ones_like(t), np.sin(t)]), 2 * np.pi)
    assert pe.excited and pe.level == pytest.approx(np.pi, rel=1e-4)


def test_identifiability_rank():
    t = T_GRID
    ok = identifiability_rank(t, gpebo_regressor(t))
    assert ok.identifiable and ok.times.size == 2
    bad = identifiability_rank(t, np.column_stack([np.sin(t), 2 * np.sin(t)]))
    assert bad.rank == 1 and not bad.identifiable
    np.testing.assert_allclose(np.abs(bad.unidentifiable_directions), [[2 / np.sqrt(5), 1 / np.sqrt(5)]], atol=1e-12)


def test_regular_persistence_and_local_regularity():
    t = T_GRID
    sa = bilinear_sa()
    assert regular_persistence(sa, t, 1.0, u=np.ones_like(t), stride=20).uniform
    assert not regular_persistence(sa, t, 1.0, u=np.exp(-t), stride=20).uniform
    # u = 1: W(t, t+T) = [[T, T²/2], [T²/2, T³/3]], so α(t, T) = λ_min([[1, 1/2], [1/2, 1/3]]) for all t, T
    lr = local_regularity(sa, t, [0.1, 0.3, 0.5], u=np.ones_like(t), stride=50)
    assert lr.regular
    np.testing.assert_allclose(lr.alpha, 2 / 3 - np.sqrt(4 / 9 - 1 / 12), rtol=1e-8)
    assert not local_regularity(sa, t, [0.1, 0.5], u=np.exp(-t), stride=50).regular


def test_bad_regressors():
    t = T_GRID
    with pytest.raises(ShapeError, match="one row per grid time"):
        interval_excitation(t, np.ones((10, 2)))
    with pytest.raises(DataError, match="not finite at t = 0"):
        persistent_excitation(t, np.full((t.size, 2), np.nan), 1.0)
    with pytest.raises(DataError, match="longer than the data"):
        persistent_excitation(t, gpebo_regressor(t), 50.0)
    with pytest.raises(DataError, match="C_d"):
        interval_excitation(t, gpebo_regressor(t), C_d=-1)
    with pytest.raises(ShapeError, match="has 3 samples"):
        regular_persistence(bilinear_sa(), t, 1.0, u=[1, 2, 3])
