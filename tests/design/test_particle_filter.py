"""The particle filter kind (issue 22, item 3): against an exact Kalman filter on a linear-Gaussian model.

The reference is a NumPy Kalman filter written here for the PF's own discrete model: the transition of one
RK4 step of a linear flow, A_d = I + hA + (hA)²/2 + (hA)³/6 + (hA)⁴/24, process noise h·Q per step, the
update at t0 first. The PF's estimate differs from it by Monte Carlo error only, whose size is computed from
the KF's covariance and the PF's reported effective sample size.
"""

import numpy as np
import pytest
from scipy import stats

import nlobs
from nlobs.design.kalman._pf import design_pf
from nlobs.errors import FiniteEscapeError, PreconditionError
from nlobs.observer._particles import ParticleRunner

A = np.array([[0.0, 1.0], [-2.0, -0.5]])
LTI = nlobs.System.lti(A, None, [[1.0, 0.0]])
Q, R, P0, X0 = 0.2 * np.eye(2), np.array([[0.04]]), np.diag([0.5, 0.3]), np.array([0.3, -0.2])
H = 0.05
T = np.arange(150) * H


def _data(seed=3):
    rng = np.random.default_rng(seed)
    x = np.array([1.0, 0.0])
    Ad = _rk4_matrix(A, H)
    ys = []
    for _ in T:
        ys.append(x[0] + 0.2 * rng.standard_normal())
        x = Ad @ x + np.sqrt(H) * np.linalg.cholesky(Q) @ rng.standard_normal(2)
    return np.array(ys)[:, None]


def _rk4_matrix(A, h):
    M = h * A
    return np.eye(2) + M + M @ M / 2 + M @ M @ M / 6 + M @ M @ M @ M / 24


def _kalman(y):
    Ad, C = _rk4_matrix(A, H), np.array([[1.0, 0.0]])
    x, P = X0.copy(), P0.copy()
    xs, Ps, ll = [], [], 0.0
    for k in range(len(T)):
        if k:
            x, P = Ad @ x, Ad @ P @ Ad.T + H * Q
        S = C @ P @ C.T + R
        e = y[k] - C @ x
        ll += float(stats.multivariate_normal(np.zeros(1), S).logpdf(e))
        K = P @ C.T @ np.linalg.inv(S)
        x, P = x + K @ e, (np.eye(2) - K @ C) @ P
        xs.append(x), Ps.append(P)
    return np.array(xs), np.array(Ps), ll


@pytest.fixture(scope="module")
def data():
    y = _data()
    return y, _kalman(y)


def _run(scheme="bootstrap", particles=4000, seed=1, **kw):
    d = design_pf(LTI, Q=Q, R=R, P0=P0, xhat0=X0, particles=particles, scheme=scheme, seed=seed, **kw)
    return ParticleRunner(d)


@pytest.mark.parametrize("scheme", ["bootstrap", "auxiliary"])
def test_pf_matches_the_exact_kalman_filter_within_monte_carlo_error(data, scheme):
    y, (xk, Pk, llk) = data
    runner = _run(scheme, particles=2000)
    runs = [runner.run(T, y=y, seed=s) for s in range(1, 17)]
    xs = np.array([r.xhat for r in runs])                        # (seeds, N, n)
    # the Monte Carlo error, measured: the spread of independent runs (resampling makes it larger than
    # the posterior variance / ESS); the mean of 16 runs must sit on the KF within it (bias O(1/N) is far smaller).
    # z² is a squared t statistic (15 d.o.f., mean 1.15), correlated in time: its mean over the run is noisy
    sd = xs.std(axis=0, ddof=1)
    z2 = (xs.mean(axis=0) - xk) ** 2 / (sd ** 2 / len(runs))
    assert z2.mean() < 2.5, z2.mean()
    # each run within 0.8 posterior standard deviations of the KF everywhere (the largest over 96 runs of three seed
    # blocks, measured: 0.57, at the third sample, before the cloud has settled); an absolute 0.2 held for seeds 1-16 only
    post = np.sqrt(np.diagonal(Pk, axis1=1, axis2=2))
    assert (np.abs(xs - xk) / post).max() < 0.8 and np.abs(xs - xk).mean() < 0.02
    # the particle covariance is the posterior covariance, and the log-likelihood estimate the KF's
    out = runs[0]
    sd = np.sqrt(np.diagonal(Pk, axis1=1, axis2=2))
    rel = np.abs(out.P - Pk) / (sd[:, :, None] * sd[:, None, :])
    assert rel.mean() < 0.1 and rel.max() < 0.8, (rel.mean(), rel.max())
    lls = np.array([r.loglik.sum() for r in runs])
    assert abs(lls.mean() - llk) < 4 * lls.std(ddof=1) / np.sqrt(len(runs)) + 0.05, (lls, llk)


def test_same_seed_same_estimates_and_another_seed_differs(data):
    y = data[0]
    r = _run(particles=500)
    a, b, c = r.run(T, y=y), r.run(T, y=y), r.run(T, y=y, seed=2)
    np.testing.assert_array_equal(a.xhat, b.xhat)
    np.testing.assert_array_equal(a.ess, b.ess)
    np.testing.assert_array_equal(_run(particles=500).run(T, y=y).xhat, a.xhat)  # a new design with the same seed too
    assert np.abs(a.xhat - c.xhat).max() > 1e-4


def test_ess_is_reported_and_drives_resampling(data):
    y = data[0]
    out = _run(particles=1000, threshold=0.5).run(T, y=y)
    assert np.all((out.ess >= 1) & (out.ess <= 1000 + 1e-9))
    np.testing.assert_array_equal(out.resampled, out.ess < 500)
    assert 0 < out.resampled.sum() < len(T)
    assert not _run(particles=1000, threshold=0.0).run(T, y=y).resampled.any()
    assert _run(particles=1000, threshold=1.0).run(T, y=y).resampled.all()


def test_the_generator_draws_standard_normals():
    x = _run(particles=10).normals(200_000, seed=7)
    assert stats.kstest(x, "norm").pvalue > 1e-3
    assert abs(x.mean()) < 0.01 and abs(x.var() - 1) < 0.01 and abs(stats.kurtosis(x)) < 0.05


def test_degeneracy_shows_in_the_ess_and_a_collapse_is_reported():
    # a measurement far from every particle: the weights stay finite (log domain), one particle carries them
    out = _run(particles=50).run(T, y=np.full((len(T), 1), 1e6))
    assert np.all(np.isfinite(out.xhat)) and out.ess.max() < 1.01
    # an output not finite at any particle (log of a negative state): the run stops naming the sample
    LOG = nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["log(x1)"])
    d = design_pf(LOG, Q=0.01 * np.eye(2), R=[[0.01]], P0=1e-4 * np.eye(2), xhat0=[-5.0, 0.0], particles=20)
    with pytest.raises(FiniteEscapeError, match="every particle's likelihood vanished"):
        ParticleRunner(d).run(T, y=np.zeros((len(T), 1)))


def test_options_are_checked():
    with pytest.raises(PreconditionError, match="particles"):
        design_pf(LTI, Q=Q, R=R, particles=1)
    with pytest.raises(PreconditionError, match="scheme"):
        design_pf(LTI, Q=Q, R=R, scheme="optimal")
    with pytest.raises(PreconditionError, match="threshold"):
        design_pf(LTI, Q=Q, R=R, threshold=1.5)
    with pytest.raises(PreconditionError, match="seed"):
        design_pf(LTI, Q=Q, R=R, seed=-1)


def test_substeps_between_samples_move_the_particles_like_the_discretised_model():
    # max_step = h/4: four RK4 steps per interval, noise h/4·Q after each; the exact KF of that model has
    # A_d = A4⁴ and Q_d = Σ_j A4^j (h/4·Q) A4^jᵀ (j = 0..3)
    y = _data()
    A4 = _rk4_matrix(A, H / 4)
    Ad, Qd = np.linalg.matrix_power(A4, 4), sum(np.linalg.matrix_power(A4, j) @ (H / 4 * Q) @ np.linalg.matrix_power(A4, j).T
                                                 for j in range(4))
    C = np.array([[1.0, 0.0]])
    x, P, xk = X0.copy(), P0.copy(), []
    for k in range(len(T)):
        if k:
            x, P = Ad @ x, Ad @ P @ Ad.T + Qd
        K = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
        x, P = x + K @ (y[k] - C @ x), (np.eye(2) - K @ C) @ P
        xk.append(x)
    xk = np.array(xk)
    runner = _run(particles=1000, max_step=H / 4)
    xs = np.array([runner.run(T, y=y, seed=s).xhat for s in range(1, 17)])
    z2 = (xs.mean(axis=0) - xk) ** 2 / (xs.std(axis=0, ddof=1) ** 2 / len(xs))
    assert z2.mean() < 2.5, z2.mean()
