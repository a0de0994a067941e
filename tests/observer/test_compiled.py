"""The prepared observer on sampled data: sub-steps chosen per interval, gaps, stiffness, failures, caching."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

import nlobs
from nlobs import DataError, FiniteEscapeError, Observer, Recording, System, design_custom, design_ekf, estimate
from nlobs.engine import find_compiler
from nlobs.observer import CompiledObserver, compiled_observer

VDP = System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], params={"mu": 1.0}, name="vdp")
ENGINES = ["vm"] + (["c"] if find_compiler() is not None else [])


@pytest.fixture(scope="module")
def vdp_rec() -> Recording:
    run = nlobs.simulate(VDP, t_final=20.0, dt=1e-3, x0=[2.0, 0.0], noise=nlobs.Noise.gaussian(0.1),
                         sampling=nlobs.Sampling(0.01), seed=0)
    return Recording.from_run(run, every=10)


def _ekf():
    return design_ekf(VDP, Q=np.diag([1e-4, 1e-3]), R=[[0.01]], P0=np.eye(2))


def test_one_step_per_sample_when_the_flow_is_slow_and_a_handle_is_built_once(vdp_rec, monkeypatch):
    d = _ekf()
    res = estimate(d, vdp_rec)
    info = res.info["integration"]["ekf"]
    # rate·dt is about 0.1 here: one RK4 step per 0.01 s sample, as before, and nothing more
    assert info["substeps"] == vdp_rec.t.size - 1 and info["max_substeps"] == 1 and 1 < info["fastest_rate"] < 20
    assert res.metrics().rms_error < 0.1
    builds = []
    monkeypatch.setattr(CompiledObserver, "_build", lambda self: builds.append(1))
    again = estimate(d, vdp_rec)  # the cached handle: nothing is rebuilt
    assert builds == [] and np.array_equal(again.observers["ekf"].xhat, res.observers["ekf"].xhat)
    handle = Observer(d).compiled()
    assert handle is compiled_observer(d) and builds == []
    traj = handle.run(vdp_rec.t, y=vdp_rec.y, u=vdp_rec.u)
    assert np.array_equal(traj.xhat, res.observers["ekf"].xhat) and np.array_equal(traj.z, res.observers["ekf"].z)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_long_gap_is_sub_stepped_and_the_estimate_stays_finite(vdp_rec, engine):
    """A 10⁴ s gap: integrated in steps of the observer's time scale, not one RK4 step (which gave 7e22
    after 10⁶ s); the covariance stays positive definite and the filter re-converges after the gap."""
    t = vdp_rec.t.copy()
    t[1000:] += 1e4
    gap = Recording.from_arrays(VDP, t, vdp_rec.y, vdp_rec.u, vdp_rec.x)
    res = estimate(_ekf(), gap, engine=engine)
    z, info = res.observers["ekf"].z, res.info["integration"]["ekf"]
    assert np.all(np.isfinite(z))
    # h·ρ ≤ 1 over the gap: at least 10⁴ · (rate at the start, ≥ 2) steps, at most a few times that
    assert 2e4 < info["max_substeps"] < 1e6
    for k in (999, 1000, z.shape[0] - 1):
        assert np.linalg.eigvalsh(z[k, 2:].reshape(2, 2)).min() > 0
    assert np.abs(z[1000, :2]).max() < 4  # on (near) the limit cycle, not 7e22
    assert res.error_norm()[-1] < 0.3  # the filter re-converged on the data after the gap


def test_c_and_vm_take_the_same_steps(vdp_rec):
    if find_compiler() is None:
        pytest.skip("needs a C compiler")
    t = vdp_rec.t.copy()
    t[700:] += 300.0
    gap = Recording.from_arrays(VDP, t, vdp_rec.y, vdp_rec.u)
    a, b = (estimate(_ekf(), gap, engine=e) for e in ("c", "vm"))
    assert a.info["integration"]["ekf"]["substeps"] == b.info["integration"]["ekf"]["substeps"]
    assert np.allclose(a.observers["ekf"].z, b.observers["ekf"].z, rtol=1e-9, atol=1e-9)


def _discrete_kf(F, Q, H, R, P0, dt, n):
    """The exact continuous-discrete Kalman covariance of a linear model: prediction by the matrix
    exponential (Van Loan 1978), Joseph-form update; an independent reference for the RK4 path."""
    m = F.shape[0]
    M = sla.expm(np.block([[-F, Q], [np.zeros((m, m)), F.T]]) * dt)
    Phi = M[m:, m:].T
    Qd = Phi @ M[:m, m:]
    P = P0.copy()
    for _ in range(n):
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        IKH = np.eye(m) - K @ H
        P = IKH @ P @ IKH.T + K @ R @ K.T
        P = Phi @ P @ Phi.T + Qd
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    IKH = np.eye(m) - K @ H
    return IKH @ P @ IKH.T + K @ R @ K.T


@pytest.mark.parametrize("engine", ENGINES)
def test_a_stiff_covariance_equation_does_not_inflate_between_samples(engine):
    """dP/dt has the rate 2·1000 here; one RK4 step per 0.01 s sample has h·ρ = 20 (unstable: P grows by
    ~|R(-20)|² per step). The steps are chosen from the measured rate and P matches the exact filter."""
    sys_ = System(states=["x1", "x2"], f=["-1000*x1 + x2", "-x2"], outputs=["y"], h=["x2"], name="stiff")
    Q, R, P0 = np.eye(2), np.array([[0.01]]), np.eye(2)
    t = np.arange(0, 2.0, 0.01)
    rec = Recording.from_arrays(sys_, t, np.exp(-t)[:, None], None)
    res = estimate(design_ekf(sys_, Q=Q, R=R, P0=P0), rec, engine=engine)
    info = res.info["integration"]["ekf"]
    assert info["max_substeps"] >= 20 and info["fastest_rate"] > 1500
    P = res.observers["ekf"].z[-1, 2:].reshape(2, 2)
    ref = _discrete_kf(np.array([[-1000.0, 1.0], [0.0, -1.0]]), Q, np.array([[0.0, 1.0]]), R, P0, 0.01, t.size - 1)
    assert np.allclose(P, ref, rtol=2e-3, atol=1e-9)


def test_a_gap_needing_too_many_steps_is_refused_with_its_time_and_size(vdp_rec):
    t = vdp_rec.t.copy()
    t[1000:] += 1e6
    gap = Recording.from_arrays(VDP, t, vdp_rec.y, vdp_rec.u)
    with pytest.raises(DataError, match=r"from t = 9\.99 to 1\.00001e\+06 \(length 1e\+06\).*Split the recording"):
        estimate(_ekf(), gap, max_step=1e-3)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_non_finite_estimate_raises_with_the_interval(engine):
    sys_ = System(states=["x"], f=["-x"], outputs=["y"], h=["x"], name="decay")
    # the flow takes log(xh): NaN once xh < 0, which the update makes happen after t = 0.5
    obs = design_custom(sys_, states=["xh"], flow=["log(xh) - 5*(xh - y)"], xhat0=[1.0])
    t = np.arange(0, 2.0, 0.1)
    y = np.where(t < 0.5, 1.0, -3.0)
    with pytest.raises(FiniteEscapeError, match=r"observer .custom.*from the sample at t = 0\.[45]"):
        estimate(obs, Recording.from_arrays(sys_, t, y[:, None], None), engine=engine)


def test_the_vm_does_not_finish_a_long_gap_it_will_redo(vdp_rec, monkeypatch):
    """A long gap whose first prediction proves too coarse (the rate grows inside it) is redone with more
    sub-steps. The VM stops the rejected attempt where the rate is exceeded, as the C loop does, instead of
    running it to the gap's end: the rows evaluated stay close to the sub-steps kept."""
    from nlobs.engine._intervals import IntervalRunner

    rows: list[int] = []
    real = IntervalRunner._rows_fn

    def counting(self, K, jumps=True):
        rows.append(K)
        return real(self, K, jumps)

    monkeypatch.setattr(IntervalRunner, "_rows_fn", counting)
    t = vdp_rec.t.copy()
    t[1000:] += 1e4
    gap = Recording.from_arrays(VDP, t, vdp_rec.y, vdp_rec.u, vdp_rec.x)
    res = estimate(_ekf(), gap, engine="vm")
    info = res.info["integration"]["ekf"]
    # here the gap is first tried with 26,980 sub-steps and redone with 54,151 (56,150 in all): running the
    # rejected attempt to its end would evaluate about 83,000 rows; stopped early, the rows (padded to whole
    # VM calls) stay within 15 % of the sub-steps kept
    assert info["max_substeps"] > 5e4 and sum(rows) < 1.15 * info["substeps"]
    assert np.all(np.isfinite(res.observers["ekf"].z))


@pytest.mark.parametrize("engine", ENGINES)
def test_estimate_reports_progress_through_a_long_gap(vdp_rec, engine):
    """Progress is the fraction of the recording's time span covered, over all observers: it never goes
    back (a rejected attempt at the gap is redone from its start), reports inside the gap on the virtual
    machine, and ends at 1 only when the run succeeded."""
    t = vdp_rec.t.copy()
    t[1000:] += 1e4
    gap = Recording.from_arrays(VDP, t, vdp_rec.y, vdp_rec.u, vdp_rec.x)
    seen: list[float] = []
    estimate({"a": _ekf(), "b": _ekf()}, gap, engine=engine, progress=seen.append)
    assert seen[-1] == 1.0 and np.all(np.diff(seen) >= 0) and 0 < seen[0] <= 0.5
    if engine == "vm":  # several reports per observer, some inside the gap (t = 10 ... 10⁴ + 10 of 10⁴ + 20); the two
        assert sum(0.01 < f < 0.49 for f in seen) >= 5   # observers run side by side: the mean of their fractions
    seen.clear()
    bad = vdp_rec.y.copy()
    bad[1500] = 1e200  # the EKF's state becomes non-finite after this sample: no 100 %
    with pytest.raises(FiniteEscapeError):
        estimate(_ekf(), Recording.from_arrays(VDP, vdp_rec.t, bad, vdp_rec.u), engine=engine, progress=seen.append)
    assert not seen or seen[-1] < 1.0
