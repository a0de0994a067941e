"""python-control interop: plants in (StateSpace, NonlinearIOSystem + twin), observers out (nlsys), closed loops.

The closed-loop references are independent of the interop code: the matrix exponential of the
linear closed loop, SciPy's ``solve_ivp`` on the hand-written nonlinear loop, and a discrete
Kalman filter written out in NumPy with the exact (Van Loan) discretisation.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.integrate as si
import scipy.linalg as sl

import nlobs
from nlobs.errors import ModelError, PreconditionError, ShapeError

ct = pytest.importorskip("control", reason="python-control is the optional extra nlobs[interop]")

A = np.array([[0.0, 1.0], [2.0, -1.0]])  # unstable (eigenvalues 1, -2): the loop must be closed
B = np.array([[0.0], [1.0]])
C = np.array([[1.0, 0.0]])
TIGHT = {"rtol": 1e-10, "atol": 1e-12}


def _cart():
    return ct.ss(A, B, C, 0, states=["p", "v"], inputs=["F"], outputs=["pos"], name="cart")


def _lqr_controller(K, labels, u_name="F", dt=0):
    """u = r - K xhat as a static python-control system."""
    return ct.nlsys(None, lambda t, x, u, p: u[0] - K @ u[1:], inputs=["r", *labels], outputs=[u_name], name="ctrl", dt=dt)


# -- plants in ------------------------------------------------------------------------------

def test_state_space_becomes_the_same_lti_model():
    plant = ct.ss(A, B, C, [[0.5]], name="cart")  # default labels x[0], u[0], y[0]
    s = nlobs.from_control(plant)
    assert s.states == ("x0", "x1") and s.inputs == ("u0",) and s.outputs == ("y0",) and s.name == "cart"
    lti = nlobs.LTI.from_system(s)
    for mine, theirs in ((lti.A, A), (lti.B, B), (lti.C, C), (lti.D, [[0.5]])):
        np.testing.assert_array_equal(mine, theirs)
    named = nlobs.from_control(_cart(), name="c2")
    assert named.states == ("p", "v") and named.inputs == ("F",) and named.outputs == ("pos",) and named.name == "c2"
    # a StateSpace may bring a twin too; it is checked like any other
    twin = nlobs.System(states=["p", "v"], inputs=["F"], outputs=["pos"], f=["v", "2*p - v + F"], h=["p"], name="cart")
    assert nlobs.from_control(_cart(), twin=twin) is twin
    with pytest.raises(ModelError, match=r"d\(v\)/dt"):
        nlobs.from_control(_cart(), twin=nlobs.System(states=["p", "v"], inputs=["F"], outputs=["pos"],
                                                      f=["v", "2*p - v + 2*F"], h=["p"]))


def _pendulum_nlsys(a1=9.81, sign=1.0, labels=True):
    def upd(t, x, u, p):
        return [x[1], sign * p["a1"] * np.sin(x[0]) - p["a2"] * x[1] + p["b"] * u[0]]

    names = dict(states=["th", "om"], inputs=["tau"], outputs=["ang"]) if labels else dict(states=2, inputs=1, outputs=1)
    return ct.nlsys(upd, lambda t, x, u, p: [x[0]], params={"a1": a1, "a2": 0.5, "b": 1.0}, name="pend", **names)


def _pendulum_twin(a1=9.81):
    return nlobs.System(states=["th", "om"], inputs=["tau"], outputs=["ang"], f=["om", "a1*sin(th) - a2*om + b*tau"],
                        h=["th"], params={"a1": a1, "a2": 0.5, "b": 1.0}, name="pend")


def test_nonlinear_system_needs_a_twin_and_the_twin_is_checked():
    plant = _pendulum_nlsys()
    with pytest.raises(PreconditionError, match="opaque Python functions.*twin=nlobs.System"):
        nlobs.from_control(plant)
    assert nlobs.from_control(plant, twin=_pendulum_twin()) == _pendulum_twin()
    # a wrong parameter value in the twin: the message names the equation, the point and both values
    with pytest.raises(ModelError, match=r"twin's f does not match updfcn .*'pend': d\(om\)/dt at t = .* in the twin and "
                                         r".* in updfcn .*a1"):
        nlobs.from_control(plant, twin=_pendulum_twin(a1=9.8))
    wrong_h = nlobs.System(states=["th", "om"], inputs=["tau"], outputs=["ang"], f=["om", "a1*sin(th) - a2*om + b*tau"],
                           h=["sin(th)"], params={"a1": 9.81, "a2": 0.5, "b": 1.0})
    with pytest.raises(ModelError, match=r"twin's h does not match outfcn .*output ang"):
        nlobs.from_control(plant, twin=wrong_h)
    swapped = nlobs.System(states=["om", "th"], inputs=["tau"], outputs=["ang"], f=["a1*sin(th) - a2*om + b*tau", "om"],
                           h=["th"], params={"a1": 9.81, "a2": 0.5, "b": 1.0})
    with pytest.raises(ModelError, match="state 0 is 'om' in the twin but 'th' in 'pend'"):
        nlobs.from_control(plant, twin=swapped)
    # default python-control labels: only sizes and equations are compared
    assert nlobs.from_control(_pendulum_nlsys(labels=False), twin=_pendulum_twin()).states == ("th", "om")
    three = nlobs.System(states=["a", "b", "c"], f=["b", "c", "a"], outputs=["y"], h=["a"])
    with pytest.raises(ModelError, match="twin 'system' has 3 states"):
        nlobs.from_control(plant, twin=three)


def test_twin_check_reports_a_failing_user_function_and_accepts_points():
    plant = ct.nlsys(lambda t, x, u, p: [-np.sqrt(x[0]) if x[0] >= 0 else 1 / 0], lambda t, x, u, p: [x[0]],
                     states=["h"], outputs=["lvl"], inputs=0, name="tank")
    twin = nlobs.System(states=["h"], f=["-sqrt(h)"], outputs=["lvl"], h=["h"])
    with pytest.raises(ModelError, match=r"'tank'.updfcn raised at t = .*ZeroDivisionError.*Pass `points`"):
        nlobs.from_control(plant, twin=twin)
    pts = [(0.0, [v], []) for v in (0.1, 1.0, 4.0)]
    assert nlobs.from_control(plant, twin=twin, points=pts) == twin


def test_bad_plants_are_refused_with_the_fix():
    with pytest.raises(TypeError, match=r"transfer function.*control.ss\(sys\)"):
        nlobs.from_control(ct.tf([1], [1, 2, 3]))
    with pytest.raises(PreconditionError, match=r"unspecified sample period \(dt = True\)"):
        nlobs.from_control(ct.ss(A, B, C, 0, dt=True))
    with pytest.raises(TypeError, match="expected a control.StateSpace"):
        nlobs.from_control(np.eye(2))
    with pytest.raises(ShapeError, match="`states` must be a list of 2"):
        nlobs.from_control(_cart(), states=["only_one"])


# -- observers out --------------------------------------------------------------------------

def test_linear_closed_loop_lqr_on_estimates_matches_the_matrix_exponential():
    """Cart (unstable), Luenberger observer from nlobs, LQR from python-control, loop by interconnect."""
    plant = _cart()
    design = nlobs.design_luenberger(nlobs.from_control(plant), poles=[-4, -5])
    est = nlobs.to_control(design, plant=plant, name="est")
    assert est.input_labels == ["pos", "F"] and est.output_labels == ["xhat[0]", "xhat[1]"] and est.isctime()
    K, _, _ = ct.lqr(plant, np.diag([10.0, 1.0]), [[1.0]])
    loop = ct.interconnect([plant, est, _lqr_controller(K, est.output_labels)], inplist=["r"],
                           outlist=["pos", "xhat[0]", "xhat[1]"])
    T = np.linspace(0, 3, 61)
    x0, z0 = np.array([0.5, -0.2]), nlobs.Observer(design).initial_state([0.0, 0.0])
    resp = ct.input_output_response(loop, T, 0.0, [x0, z0], solve_ivp_kwargs=TIGHT)
    # independent: L by pole placement (unique for one output), the loop's matrix exponential
    L = ct.place(A.T, C.T, [-4, -5]).T
    Acl = np.block([[A, -B @ K], [L @ C, A - B @ K - L @ C]])
    ref = np.array([sl.expm(Acl * t) @ np.concatenate([x0, z0]) for t in T])
    assert np.abs(resp.states.T - ref).max() < 1e-8
    assert np.abs(resp.outputs[1:].T - ref[:, 2:]).max() < 1e-8
    assert np.abs(ref[-1]).max() < 0.05 < np.abs(ref[:, :2]).max()  # stabilised, from a visible start


def test_nonlinear_closed_loop_with_a_twin_matches_the_hand_written_loop():
    """Inverted pendulum (nlsys + twin), output-injection observer, LQR on the linearisation at the top."""
    plant = _pendulum_nlsys()
    model = nlobs.from_control(plant, twin=_pendulum_twin())
    design = nlobs.design_output_injection(model, poles=[-6, -7])
    est = nlobs.to_control(design, plant=plant, name="est")
    lin = plant.linearize([0, 0], [0])
    K, _, _ = ct.lqr(lin, np.diag([20.0, 1.0]), [[0.1]])
    loop = ct.interconnect([plant, est, _lqr_controller(K, est.output_labels, "tau")], inplist=["r"],
                           outlist=["ang", "xhat[0]", "xhat[1]"])
    T = np.linspace(0, 3, 61)
    x0, xhat0 = np.array([0.4, 0.0]), np.array([0.0, 0.5])
    resp = ct.input_output_response(loop, T, 0.0, [x0, nlobs.Observer(design).initial_state(xhat0)], solve_ivp_kwargs=TIGHT)

    # independent: the loop written out, observer x̂' = A0 x̂ + [0, a1 sin y + b u] - L (x̂1 - y) (002 error linearisation)
    A0 = np.array([[0.0, 1.0], [0.0, -0.5]])
    L = ct.place(A0.T, C.T, [-6, -7]).T.reshape(-1)

    def rhs(t, s):
        x, xh = s[:2], s[2:]
        u = -(K @ xh)[0]
        y = x[0]
        dx = [x[1], 9.81 * np.sin(x[0]) - 0.5 * x[1] + u]
        dxh = A0 @ xh + np.array([0.0, 9.81 * np.sin(y) + u]) - L * (xh[0] - y)
        return np.concatenate([dx, dxh])

    ref = si.solve_ivp(rhs, (0, 3), np.concatenate([x0, xhat0]), t_eval=T, method="DOP853", **TIGHT).y
    assert np.abs(resp.states - ref).max() < 1e-7
    assert np.abs(ref[:2, -1]).max() < 0.02 and np.abs(ref[:2]).max() > 0.3  # upright, from 0.4 rad


def _van_loan(Ac, Q, T):
    n = Ac.shape[0]
    M = sl.expm(np.block([[-Ac, Q], [np.zeros((n, n)), Ac.T]]) * T)
    Ad = M[n:, n:].T
    return Ad, Ad @ M[:n, n:]


def test_discrete_ekf_closes_a_sampled_loop_and_matches_a_numpy_kalman_filter():
    """Continuous-discrete EKF as a discrete-time nlsys (dt = T), plant c2d(zoh), dlqr, interconnect."""
    Tp, N = 0.05, 60
    plant = _cart()
    Q, R, P0 = np.diag([1e-3, 1e-2]), np.array([[1e-2]]), np.diag([0.5, 0.5])
    design = nlobs.design_ekf(nlobs.from_control(plant), Q=Q, R=R, P0=P0)
    with pytest.raises(PreconditionError, match="continuous-discrete.*pass dt=<sample period>"):
        nlobs.to_control(design, plant=plant)
    plant_d = ct.c2d(plant, Tp)
    est = nlobs.to_control(design, plant=plant_d, dt=Tp, max_step=Tp / 4, name="ekf")
    assert est.dt == Tp and est.state_labels[:2] == ["xhat_p", "xhat_v"]
    K, _, _ = ct.dlqr(plant_d, np.diag([10.0, 1.0]), [[1.0]])
    loop = ct.interconnect([plant_d, est, _lqr_controller(K, est.output_labels, dt=Tp)], inplist=["r"],
                           outlist=["pos", "xhat[0]", "xhat[1]", "F"])
    T = np.arange(N) * Tp
    x0, xhat0 = np.array([0.5, -0.2]), np.array([0.0, 0.0])
    resp = ct.input_output_response(loop, T, 0.0, [x0, nlobs.Observer(design).initial_state(xhat0)])

    # independent: the sampled loop with a linear Kalman filter, exact discretisation of x̂ and P
    Ad, Qd = _van_loan(A, Q, Tp)
    Bd = np.asarray(plant_d.B)
    x, xh, P = x0.copy(), xhat0.copy(), P0.copy()
    ref = []
    for k in range(N):
        y = C @ x
        G = P @ C.T @ np.linalg.inv(C @ P @ C.T + R)
        xh = xh + G @ (y - C @ xh)
        P = (np.eye(2) - G @ C) @ P @ (np.eye(2) - G @ C).T + G @ R @ G.T
        u = -(K @ xh)
        ref.append(np.concatenate([y, xh, u]))
        x = Ad @ x + Bd @ u
        xh, P = Ad @ xh + Bd @ u, Ad @ P @ Ad.T + Qd
    ref = np.array(ref)
    assert np.abs(resp.outputs.T - ref).max() < 1e-7  # RK4 (4 steps per period) vs exact: ~1e-9
    assert np.abs(ref[-1, :3]).max() < 0.05 and np.abs(ref[:, 0]).max() > 0.4


def test_discrete_form_is_the_online_observer_on_recorded_data():
    """Driven by recorded [y, u], the discrete nlsys reproduces nlobs.estimate (zero-order hold) exactly."""
    pend = nlobs.load_model(str(__import__("importlib.resources").resources.files("nlobs.models").joinpath("pendulum.toml")))
    run = nlobs.simulate(pend.system, t_final=2.0, dt=1e-3, x0=[1.0, 0.0], inputs={"u": "sin(t)"},
                         noise=nlobs.Noise.gaussian(0.01), seed=2)
    rec = nlobs.Recording.from_run(run, every=10)
    design = nlobs.design_ekf(pend.system, Q=np.diag([1e-3, 1e-2]), R=[[1e-4]], xhat0=[0.0, 0.0])
    est = nlobs.to_control(design, dt=0.01, max_step=2.5e-3)
    assert est.input_labels == ["y", "u"]
    T = np.arange(rec.t.size) * 0.01
    resp = ct.input_output_response(est, T, [rec.y[:, 0], rec.u[:, 0]], nlobs.Observer(design).initial_state())
    ref = nlobs.estimate(design, rec, max_step=2.5e-3, engine="vm")
    xhat = next(iter(ref.observers.values())).xhat
    assert np.abs(resp.outputs.T - xhat).max() < 1e-10
    assert np.abs(xhat[-1] - rec.x[-1]).max() < 0.05


def test_zero_input_plant_python_control_issue_1176():
    """An autonomous plant (no inputs): python-control 0.10.2 cannot linearize it or build a zero-input
    StateSpace (issue #1176), but interconnect with an nlsys plant and inplist=[] works."""
    osc = ct.nlsys(lambda t, x, u, p: [x[1], -x[0] - 0.1 * x[1] ** 3], lambda t, x, u, p: [x[0]], inputs=0,
                   states=["q", "w"], outputs=["q_meas"], name="osc")
    twin = nlobs.System(states=["q", "w"], f=["w", "-q - 0.1*w**3"], outputs=["q_meas"], h=["q"], name="osc")
    design = nlobs.design_ekf(nlobs.from_control(osc, twin=twin), Q=np.eye(2) * 1e-2, R=[[1e-2]], mode="continuous")
    est = nlobs.to_control(design, plant=osc)
    assert est.input_labels == ["q_meas"]
    loop = ct.interconnect([osc, est], inplist=[], outlist=["xhat[0]", "xhat[1]"])
    T = np.linspace(0, 2, 21)
    z0 = nlobs.Observer(design).initial_state([0.0, 0.0])
    resp = ct.input_output_response(loop, T, 0.0, [np.array([1.0, 0.0]), z0], solve_ivp_kwargs=TIGHT)

    def rhs(t, x):
        return [x[1], -x[0] - 0.1 * x[1] ** 3]

    truth = si.solve_ivp(rhs, (0, 2), [1.0, 0.0], t_eval=T, **TIGHT).y
    np.testing.assert_allclose(resp.states[:2], truth, atol=1e-8)
    assert np.abs(resp.outputs[:, -1] - truth[:, -1]).max() < np.abs(truth[:, 0]).max() / 4  # the estimate closed in


def test_to_control_refuses_what_it_cannot_do():
    design = nlobs.design_luenberger(nlobs.from_control(_cart()), poles=[-4, -5])
    with pytest.raises(PreconditionError, match="`max_step` applies to a discrete-time system"):
        nlobs.to_control(design, max_step=0.01)
    with pytest.raises(ShapeError, match="plant 'two' has 2 output"):
        nlobs.to_control(design, plant=ct.ss(A, B, np.eye(2), 0, name="two"))
    with pytest.raises(ValueError, match="`dt` must be a positive number"):
        nlobs.to_control(design, dt=0.0)
    with pytest.raises(ValueError, match=r"format with '\{i\}'"):
        nlobs.to_control(design, outputs="xhat")
    est = nlobs.to_control(design, outputs=["p_hat", "v_hat"], inputs="m[{i}]", name="obs")
    assert est.output_labels == ["p_hat", "v_hat"] and est.input_labels == ["m[0]", "m[1]"] and est.name == "obs"


def test_importing_nlobs_does_not_import_control():
    code = "import sys, nlobs; nlobs.interop; print('control' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_discrete_time_systems_both_ways():
    """A discrete StateSpace becomes a map (checked against python-control's own forced response), and a map's EKF
    becomes a discrete nlsys with the model's period that reproduces nlobs.estimate."""
    Ad, Bd, Cd = np.array([[1.0, 0.1], [-0.1, 0.98]]), np.array([[0.0], [0.1]]), np.array([[1.0, 0.0]])
    plant = ct.ss(Ad, Bd, Cd, 0, dt=0.1, states=["p", "v"], inputs=["F"], outputs=["pos"], name="dcart")
    m = nlobs.from_control(plant)
    assert m.is_discrete and m.sample_time == 0.1 and m.states == ("p", "v")
    k = np.arange(101)
    u = np.sin(0.3 * k)
    ref = ct.forced_response(plant, T=k * 0.1, U=u, X0=[1.0, 0.0])
    run = nlobs.simulate(m, None, t_final=10.0, x0=[1.0, 0.0], inputs={"F": (k * 0.1, u)})
    np.testing.assert_allclose(run.x, np.asarray(ref.states).T, rtol=0, atol=1e-12)
    # the map's EKF as python-control sees it: dt taken from the model, driven by [y, u]
    ekf = nlobs.design_ekf(m, Q=np.eye(2) * 1e-4, R=[[1e-2]], P0=np.eye(2), xhat0=[0.0, 0.0])
    est = nlobs.to_control(ekf, name="est")
    assert est.dt == 0.1
    y = np.asarray(ref.outputs).reshape(-1) + 0.05 * np.random.default_rng(0).standard_normal(k.size)
    resp = ct.input_output_response(est, T=k * 0.1, U=np.vstack([y, u]), X0=nlobs.Observer(ekf).initial_state())
    rec = nlobs.Recording.from_arrays(m, k * 0.1, y[:, None], u[:, None])
    np.testing.assert_allclose(np.asarray(resp.outputs).T, nlobs.estimate(ekf, rec).observers["ekf"].xhat, rtol=0,
                               atol=1e-12)
    with pytest.raises(PreconditionError, match="sample_time = 0.1; dt = 0.2 differs"):
        nlobs.to_control(ekf, dt=0.2)
    twin = nlobs.System(states=["p", "v"], inputs=["F"], outputs=["pos"], f=["p + 0.1*v", "-0.1*p + 0.98*v + 0.1*F"],
                        h=["p"], name="dcart")
    with pytest.raises(nlobs.ModelError, match="is discrete-time with dt = 0.1 but the twin 'dcart' is continuous-time"):
        nlobs.from_control(plant, twin=twin)
