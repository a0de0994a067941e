"""State bounds (levels >= 0) for the EKF, the UKF and MHE, and the Cascaded Tanks benchmark model.

Cascaded tanks (Schoukens, Mattsson, Wigren & Noël 2016): two tanks, outflow through a hole
proportional to sqrt(level) (Torricelli), the upper tank overflowing into the lower one at
x1 = 10, the level sensor saturating at 10. The overflow switch is written as a steep smooth step
(width 0.05) here: with a hard sign() switch the window NLP of MHE is nonsmooth and its solvers stop
(see benchmarks/bench_mhe.py); the sqrt outflows are kept exact, so a negative level is NaN.
"""

import numpy as np
import pytest

import nlobs
from nlobs.design import design_ekf, design_mhe, design_ukf
from nlobs.errors import PreconditionError, ShapeError

K = dict(k1=0.08, k2=0.07, k3=0.08, k4=0.04, k5=0.5, xmax=10.0, ymax=10.0, w=0.05)
NET = "(k4*u - k1*sqrt(x1))"
OVER = f"((1 + tanh((x1 - xmax)/w))/2*({NET} + sqrt({NET}**2 + 1e-6))/2)"
TANKS = nlobs.System(states=["x1", "x2"], inputs=["u"], outputs=["y"],
                     f=[f"{NET} - {OVER}", f"k2*sqrt(x1) - k3*sqrt(x2) + k5*{OVER}"],
                     h=["(x2 + ymax - sqrt((x2 - ymax)**2 + 1e-4))/2"], params=K, name="cascaded_tanks")
LEVELS = {"x1": (1e-4, None), "x2": (1e-4, None)}


@pytest.fixture(autouse=True)
def _virtual_machine(monkeypatch):
    monkeypatch.setenv("NLOBS_CC", "none")  # MHE's solver on the VM: no compile in this file


@pytest.fixture(scope="module")
def tank_data():
    # 1000 s sampled every 4 s (the benchmark's period), pump voltage swinging the upper level from 0.5 to 10
    # (overflow at the peaks); process noise on the plant, noise of std 0.05 on the measured lower level
    plant = nlobs.simulate(TANKS, None, t_final=1000.0, dt=0.5, x0=[4.0, 3.0], process_noise=nlobs.ProcessNoise(0.01), seed=3,
                           inputs={"u": "4.5 + 2.5*sin(2*pi*t/400) + 1.5*sin(2*pi*t/170)"})
    rng = np.random.default_rng(1)
    t, x, u = plant.t[::8], plant.x[::8], plant.u[::8]
    y = plant.y[::8] + 0.05 * rng.standard_normal((t.size, 1))
    return nlobs.Recording.from_arrays(TANKS, t, y, u=u, x=x)


TUNING = dict(Q=1e-3 * np.eye(2), R=[[0.05**2]], P0=np.diag([4.0, 0.1]))


def _x0(rec):
    return [1.0, float(rec.y[0, 0])]  # the hidden upper level is unknown: start far below the truth (about 4)


def test_ekf_update_is_projected_onto_the_bounds():
    # One measurement update of a scalar filter, computed by hand: K = P/(P + R), x+ = x + K(y - x),
    # P+ = (1 - K)²P + K²R (Joseph). With the bound x >= 0 the estimate is clipped to 0 and P+ is unchanged.
    sys1 = nlobs.System(states=["x"], f=["-x"], outputs=["y"], h=["x"], name="decay")
    P, R, x, y = 1.0, 1e-2, 0.5, -1.0
    Kg = P / (P + R)
    x_plus, P_plus = x + Kg * (y - x), (1 - Kg) ** 2 * P + Kg**2 * R
    assert x_plus < 0
    for bounds, expect in ((None, x_plus), ({"x": (0, None)}, 0.0)):
        o = nlobs.Observer(design_ekf(sys1, Q=[[0.0]], R=[[R]], P0=[[P]], xhat0=[x], bounds=bounds))
        z = o.update(0.0, o.initial_state(), None, [y])
        assert z[0] == pytest.approx(expect, abs=1e-15)
        assert z[1] == pytest.approx(P_plus, rel=1e-12)


def test_ukf_needs_the_bounds_on_the_tanks(tank_data):
    # P0 = 4 on x1 = 1 puts sigma points at 1 - sqrt(2·4) < 0: sqrt of a negative level. Without bounds the UKF is NaN
    # from the first prediction on (estimate stops there, naming the samples, rather than returning NaN estimates);
    # with the bounds the model is evaluated inside them and the filter runs.
    with pytest.raises(nlobs.FiniteEscapeError, match=r"observer 'ukf' .* became non-finite in the step from the sample at t = 0 "):
        nlobs.estimate(design_ukf(TANKS, **TUNING, xhat0=_x0(tank_data)), tank_data, max_step=0.5)
    boxed = nlobs.estimate(design_ukf(TANKS, **TUNING, xhat0=_x0(tank_data), bounds=LEVELS), tank_data, max_step=0.5)
    xh = boxed.observers["ukf"].xhat
    assert np.isfinite(xh).all() and xh.min() >= 1e-4


def test_inactive_bounds_change_nothing():
    vdp = nlobs.System(states=["x1", "x2"], f=["x2", "(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], name="vdp")
    run = nlobs.simulate(vdp, None, t_final=10.0, dt=0.05, x0=[2.0, 0.0], noise=nlobs.Noise.gaussian(0.1), seed=0)
    rec = nlobs.Recording.from_run(run)
    far = {"x1": (-50, 50), "x2": (None, 50)}
    for design in (design_ekf, design_ukf):
        a = nlobs.estimate(design(vdp, Q=0.01 * np.eye(2), R=[[0.01]]), rec).observers
        b = nlobs.estimate(design(vdp, Q=0.01 * np.eye(2), R=[[0.01]], bounds=far), rec).observers
        name = next(iter(a))
        np.testing.assert_allclose(a[name].xhat, b[name].xhat, rtol=0, atol=1e-12)


def test_mhe_ekf_and_ukf_estimate_the_hidden_upper_level(tank_data):
    x1 = tank_data.x[:, 0]
    designs = {"ekf": design_ekf(TANKS, **TUNING, xhat0=_x0(tank_data), bounds=LEVELS),
               "ukf": design_ukf(TANKS, **TUNING, xhat0=_x0(tank_data), bounds=LEVELS),
               "mhe": design_mhe(TANKS, horizon=10, **TUNING, xhat0=_x0(tank_data), bounds=LEVELS)}
    run = nlobs.estimate(designs, tank_data, max_step=0.5)
    assert abs(run.observers["mhe"].xhat[0, 0] - x1[0]) > 2.5  # a real initial error to recover from
    for name in designs:
        xh = run.observers[name].xhat[:, 0]
        rms = np.sqrt(np.mean((xh[50:] - x1[50:]) ** 2))  # after 200 s
        assert rms < 0.25, (name, rms)
        assert xh.min() >= 1e-4
    assert run.observers["mhe"].z[-1, -1] == 0  # no IPOPT fallback needed


def test_bounds_option_is_checked():
    with pytest.raises(ShapeError, match=r"`bounds` names 'x3', which is not a state of 'cascaded_tanks' \(states: x1, x2\)"):
        design_ekf(TANKS, **TUNING, bounds={"x3": (0, None)})
    with pytest.raises(ShapeError, match="must be a pair"):
        design_ukf(TANKS, **TUNING, bounds={"x1": 0})
    with pytest.raises(ShapeError, match="lower bound of `x1` must be a number or None"):
        design_ekf(TANKS, **TUNING, bounds={"x1": ("zero", None)})
    with pytest.raises(PreconditionError, match="initial estimate is outside the bounds: x1 = 0 not in"):
        design_ukf(TANKS, **TUNING, bounds=LEVELS)  # xhat0 defaults to zeros
    with pytest.raises(PreconditionError, match=r"Jacobian is not finite at the bound x1 = 0"):
        design_ekf(TANKS, **TUNING, xhat0=[1.0, 1.0], bounds={"x1": (0, None)})


def test_mhe_on_a_hard_overflow_switch_stops_with_the_window_named(tank_data):
    # the same tanks with the overflow written with sign(): the window NLP is nonsmooth where the level crosses 10;
    # the certificate says so before the run, and the run stops with a SolverError naming the window, not with NaN
    net = "(k4*u - k1*sqrt(x1))"
    over = f"((1 + sign(x1 - xmax))/2*({net} + abs({net}))/2)"
    hard = nlobs.System(states=["x1", "x2"], inputs=["u"], outputs=["y"], f=[f"{net} - {over}", f"k2*sqrt(x1) - k3*sqrt(x2) + k5*{over}"],
                        h=["(x2 + ymax - abs(x2 - ymax))/2"], params=K, name="cascaded_tanks_hard")
    d = design_mhe(hard, horizon=20, **TUNING, xhat0=_x0(tank_data), bounds=LEVELS)
    assert "[FAILED] the model is differentiable" in str(d.certificate) and "abs(), sign()" in str(d.certificate)
    rec = nlobs.Recording.from_arrays(hard, tank_data.t, tank_data.y, u=tank_data.u, x=tank_data.x)
    with pytest.raises(nlobs.SolverError, match=r"window t in \[[0-9.]+, [0-9.]+\].*IPOPT.*uses abs and sign.*smooth steps"):
        nlobs.estimate(d, rec, max_step=0.5)
