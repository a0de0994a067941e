"""One conformance suite over every registered observer design (STYLE §14).

Every kind in the registry ``nlobs.design.KINDS`` must have a case here: a small plant the design
applies to, with tuning. Each design then must: return the declared shapes, be deterministic,
leave its inputs unmutated, converge on its plant, reject unknown options (from Python and
from model files), and run on simulated and recorded data alike.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from nlobs import ModelError, Observer, Recording, StateAffine, System, estimate, simulate
from nlobs.design import KINDS, ParticleDesign, design_from_config
from nlobs.observer import particle_runner

OSC = System(states=["x1", "x2"], f=["x2", "-x1 - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"], name="osc")
PEND = System(states=["x1", "x2"], f=["x2", "-2*sin(x1) - 0.5*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"], name="pend")
WEAK = System(states=["x1", "x2"], f=["x2", "-x1 - 0.5*x2 - 0.1*sin(x1) + u"], inputs=["u"], outputs=["y"], h=["x1"], name="weak")
TOY = System(states=["x1", "x2"], f=["x2**2", "c"], outputs=["y"], h=["x1"], params={"c": 0.5}, name="toy")
SA = StateAffine([[0, 1], [-1, -0.5]], [0, "u"], [[1], [0]], inputs=["u"], outputs=["y"], name="sa")

# kind -> (plant, tuning, x0, xhat0, simulation horizon, final-error tolerance)
CASES = {
    "luenberger": (OSC, dict(poles=[-2, -3]), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-5),
    "output_injection": (PEND, dict(poles=[-2, -3]), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-5),
    "ekf": (PEND, dict(Q=np.eye(2) * 1e-3, R=[[1e-4]]), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-4),
    "augmented": (TOY, dict(T=["x1", "x2", "x2**2"], A=[[0, 0, 1], [0, 0, 0], [0, "2*c", 0]], b=[0, "c", 0], C=[[1, 0, 0]],
                            left_inverse=["w1", "w2"], poles=[-1, -2, -3]), [2.0, -2.0], [0.0, 0.0], 12.0, 1e-4),
    "custom": (OSC, dict(states=["a", "b"], params={"k1": 4.5, "k2": 5.0},
                         flow=["b + k1*(y - a)", "-a - 0.5*b + u + k2*(y - a)"]), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-4),
    "high_gain": (PEND, dict(theta=4.0), [1.0, 0.0], [0.0, 0.0], 6.0, 1e-4),
    "high_gain_derivatives": (OSC, dict(psi=["D0_y", "D1_y"], r=0.1, nominal={"y": "-D0_y - 0.5*D1_y + u"}),
                              [1.0, 0.0], [0.0, 0.0], 8.0, 1e-4),
    "lipschitz": (WEAK, dict(region={"x1": [-3, 3], "x2": [-3, 3], "u": [-1, 1]}), [1.0, 0.0], [0.0, 0.0], 15.0, 1e-3),
    "kalman_bucy": (OSC, dict(Q=np.eye(2) * 0.1, R=[[0.01]]), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-4),
    "kalman_like": (SA, dict(delta=4.0, Q=np.eye(2) * 0.1), [1.0, 0.0], [0.0, 0.0], 10.0, 1e-4),
    "high_gain_kalman": (OSC, dict(lam=3.0, delta=3.0), [1.0, 0.0], [0.0, 0.0], 10.0, 1e-3),
    "banks": (OSC, dict(L=[[-2.0], [-1.0]]), [1.0, 0.0], [0.0, 0.0], 15.0, 1e-3),
    "ukf": (PEND, dict(Q=np.eye(2) * 1e-3, R=[[1e-4]]), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-4),
    # sampled every dt = 1e-3 here (continuous measurements): a short window of many samples, IPOPT at each
    "mhe": (OSC, dict(horizon=5, R=[[1e-4]], P0=np.eye(2) * 1e-3), [1.0, 0.0], [0.0, 0.0], 2.0, 1e-3),
    "srukf": (PEND, dict(Q=np.eye(2) * 1e-3, R=[[1e-4]]), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-4),
    "srekf": (PEND, dict(Q=np.eye(2) * 1e-3, R=[[1e-4]]), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-4),
    "iekf": (PEND, dict(Q=np.eye(2) * 1e-3, R=[[1e-4]], iterations=3), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-4),
    # a particle cloud: Monte Carlo error ~ σ/√ESS (σ = 0.01 from R), not 1e-4
    "pf": (PEND, dict(Q=np.eye(2) * 1e-3, R=[[1e-4]], P0=np.eye(2) * 0.5, particles=500), [1.0, 0.0], [0.0, 0.0], 8.0, 2e-2),
}

# Parameter-estimation based designs (issue 4; 000 and 004). Regression plant: θ' = 0, Y = ψ(t)ᵀθ with a regressor
# of time (estimate() holds inputs by zero-order hold while it interpolates y, so ψ built from an input would not
# satisfy the regression between samples of a recording)
REG = System(states=["th1", "th2"], f=["0", "0"], outputs=["y"], h=["sin(t)*th1 + cos(t)*th2"], name="regression")
PEB = System(states=["x1", "x2"], f=["x2", "-x1 + u"], outputs=["y"], h=["x1"], inputs=["u"], name="pebo_plant")
MIX = System(states=["x1", "x2", "x3"], f=["-x1 + x2 + x3", "-x2 + x1", "u"], outputs=["y"], h=["x1"], inputs=["u"], name="mix")
CASC = System(states=["y1s", "a", "b", "c"], f=["-y1s + a + b + (1 + 0.5*cos(u))*c", "-2*a + sin(y1s)", "-b + a*y1s + u", "-y1s"],
              outputs=["y"], h=["y1s"], inputs=["u"], name="cascade")
DAMPED = System(states=["x1", "x2"], f=["x2", "-x1 - 0.5*x2"], outputs=["y"], h=["x1"], name="damped")
# KKL for OSC with Λ = diag(-1, -2): rows t_i = C(A - λ_i I)⁻¹ = (1/3, -2/3), (3/8, -1/4); B_i = y + t_i b u
OSC_KKL = dict(phi=["x1/3 - 2*x2/3", "3*x1/8 - x2/4"], left_inverse=["-1.5*xi1 + 4*xi2", "-2.25*xi1 + 2*xi2"],
               B=["y - 2*u/3", "y - u/4"], Lambda=[-1, -2])
CASES.update({
    "gradient": (REG, dict(gamma=1.0), [1.5, -0.7], [0.0, 0.0], 25.0, 1e-4),
    "least_squares": (REG, dict(P0=10.0, forgetting=1.0), [1.5, -0.7], [0.0, 0.0], 20.0, 1e-4),
    "drem": (REG, dict(gamma=10.0, lambdas=[2.0]), [1.5, -0.7], [0.0, 0.0], 20.0, 1e-4),
    "gd": (REG, dict(gamma_g=5.0, gamma=50.0), [1.5, -0.7], [0.0, 0.0], 20.0, 1e-4),
    # ψ = Φ_Aᵀ C decays with the stable A of SA (interval, not persistent, excitation): G+D, not a gradient
    "gpebo": (SA, dict(estimator={"kind": "gd", "gamma_g": 2.0, "gamma": 20.0}), [1.0, 0.0], [0.0, 0.0], 20.0, 1e-4),
    "gpebo_2gd": (SA, dict(gamma_g=1.0, gamma=10.0), [1.0, 0.0], [0.0, 0.0], 20.0, 1e-4),
    "kkl": (OSC, OSC_KKL, [1.0, 0.0], [0.0, 0.0], 12.0, 1e-4),
    "pebo": (PEB, dict(phi=["x2"], left_inverse=["y", "xi1"], B=["-y + u"], alpha=2.0,
                       estimator={"kind": "gradient", "gamma": 5.0}), [0.3, -0.8], [0.0, 0.0], 15.0, 1e-4),
    "kkl_pebo": (MIX, dict(phi=["x2", "x3"], left_inverse=["y", "xi1", "xi2"], B=["y", "u"], Lambda=[-1, 0],
                           estimator={"kind": "gd", "gamma_g": 5.0, "gamma": 50.0}), [0.2, 1.0, -0.5], [0.0, 0.0, 0.0],
                 20.0, 1e-4),
    "kkl_pebo_cascade": (CASC, dict(x2=["a"], x3=["b"], x4=["c"], k="y1s", alpha=2.0,
                                    estimator={"kind": "gradient", "gamma": 20.0}), [0.3, 1.0, -1.0, 0.5], [0.0] * 4, 20.0, 1e-4),
    "iandi": (OSC, dict(beta=["chi1 + 3*y"], phi=["x2"], left_inverse=["y", "xi1"]), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-4),
    "kkl_learned": (DAMPED, dict(region=[[-1.0, 1.0], [-1.0, 1.0]], eigenvalues=[-2, -3, -4], degree=1, n_trajectories=8,
                                 t_final=12.0, dt=0.02), [1.0, 0.0], [0.0, 0.0], 10.0, 1e-4),
})


def _plant(model):
    return model.to_system() if isinstance(model, StateAffine) else model


def test_every_registered_design_has_a_conformance_case():
    assert set(KINDS) <= set(CASES), f"add a conformance case for: {sorted(set(KINDS) - set(CASES))}"


@pytest.fixture(params=sorted(CASES))
def case(request):
    kind = request.param
    if kind not in KINDS:
        pytest.fail(f"{kind} has a case but is not registered")
    return (kind, *CASES[kind])


def test_declared_shapes_and_determinism(case):
    kind, model, tuning, x0, xhat0, *_ = case
    d1 = KINDS[kind].design(model, **copy.deepcopy(tuning), xhat0=xhat0)
    d2 = KINDS[kind].design(model, **copy.deepcopy(tuning), xhat0=xhat0)
    plant = _plant(model)
    n, nu, ny = plant.n_states, plant.n_inputs, plant.n_outputs
    if isinstance(d1, ParticleDesign):  # no ODE (a particle cloud run over the samples): same seed, same run
        t = np.arange(50) * 0.01
        r1, r2 = particle_runner(d1).run(t, u=np.zeros((50, nu)), y=np.sin(t)), particle_runner(d2).run(t, u=np.zeros((50, nu)), y=np.sin(t))
        assert r1.z.shape == (50, d1.n_z) and r1.xhat.shape == (50, n) and np.array_equal(r1.z, r2.z)
        assert str(d1.certificate) and d1.certificate.reference
        return
    assert len(d1.z_names) == d1.n_z and d1.flow.size1_out(0) == d1.n_z and d1.output.size1_out(0) == n
    assert d1.flow.size1_in(2) == nu and d1.flow.size1_in(3) == ny
    if d1.update is not None:
        assert d1.update.size1_out(0) == d1.n_z
    obs1, obs2 = Observer(d1), Observer(d2)
    z0 = obs1.initial_state()
    assert z0.shape == (d1.n_z,) and np.all(np.isfinite(z0))
    args = (0.3, z0, np.full(nu, 0.2), np.full(ny, 0.7))
    assert np.array_equal(obs1.rhs(*args), obs2.rhs(*args))
    assert np.array_equal(obs1.estimate(*args), obs2.estimate(*args))
    assert str(d1.certificate) and d1.certificate.reference


def test_inputs_are_not_mutated(case):
    kind, model, tuning, _, xhat0, *_ = case
    given = copy.deepcopy(tuning)
    KINDS[kind].design(model, **given, xhat0=list(xhat0))
    for k, v in tuning.items():
        assert np.array_equal(np.asarray(given[k], dtype=object), np.asarray(v, dtype=object)) if not isinstance(v, dict) else given[k] == v


def test_converges_on_its_plant_and_on_recorded_data(case):
    kind, model, tuning, x0, xhat0, horizon, tol = case
    d = KINDS[kind].design(model, **copy.deepcopy(tuning), xhat0=xhat0)
    plant = _plant(model)
    inputs = {"u": "sin(t)"} if plant.n_inputs else None
    run = simulate(plant, {kind: d}, t_final=horizon, dt=1e-3, x0=x0, inputs=inputs)
    assert run.metrics(kind).final_error < tol
    rec = Recording.from_run(run, every=5)
    offline = estimate({kind: d}, rec, max_step=1e-3, hold="linear")
    assert offline.metrics(kind).final_error < max(tol, 1e-3) * 10


def test_unknown_options_are_rejected(case):
    kind, model, tuning, *_ = case
    with pytest.raises(TypeError):
        KINDS[kind].design(model, **copy.deepcopy(tuning), not_an_option=1)
    if isinstance(model, System):
        with pytest.raises(ModelError, match=f"unknown option `not_an_option` for kind '{kind}'"):
            design_from_config(model, kind, {**copy.deepcopy(tuning), "not_an_option": 1})


# -- discrete-time models (maps): every kind that runs on maps, on one map ---------------------------------------
# a damped pendulum discretised by hand (Euler, its own map: no integrator between steps), angle measured
T_MAP = 0.05
PEND_MAP = System(states=["x1", "x2"], f=[f"x1 + {T_MAP}*x2", f"x2 + {T_MAP}*(-2*sin(x1) - 0.5*x2 + u)"], inputs=["u"],
                  outputs=["y"], h=["x1"], time="discrete", sample_time=T_MAP, name="pend_map")
LIN_MAP = System(states=["x1", "x2"], f=["0.9*x1 + 0.2*x2", "-0.1*x1 + 0.95*x2 + u"], inputs=["u"], outputs=["y"], h=["x1"],
                 time="discrete", sample_time=0.1, name="lin_map")
_QM, _RM = np.eye(2) * 1e-6, [[1e-4]]
# kind -> (plant, tuning, x0, xhat0, t_final, final-error tolerance): noise-free runs from x̂(0) = 0
MAP_CASES = {
    "luenberger": (LIN_MAP, dict(poles=[0.5, 0.4]), [1.0, -1.0], [0.0, 0.0], 4.0, 1e-6),
    "ekf": (PEND_MAP, dict(Q=_QM, R=_RM), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-3),
    "ukf": (PEND_MAP, dict(Q=_QM, R=_RM), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-3),
    "srukf": (PEND_MAP, dict(Q=_QM, R=_RM), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-3),
    "srekf": (PEND_MAP, dict(Q=_QM, R=_RM), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-3),
    "iekf": (PEND_MAP, dict(Q=_QM, R=_RM, iterations=3), [1.0, 0.0], [0.0, 0.0], 8.0, 1e-3),
    "mhe": (PEND_MAP, dict(horizon=8, Q=_QM, R=_RM, P0=np.eye(2)), [1.0, 0.0], [0.0, 0.0], 4.0, 1e-3),
    # a particle cloud: Monte Carlo error ~ σ/√ESS (σ = 0.01 from R)
    "pf": (PEND_MAP, dict(Q=np.eye(2) * 1e-5, R=_RM, P0=np.eye(2) * 0.5, particles=2000), [1.0, 0.0], [0.0, 0.0], 8.0, 2e-2),
}


def test_every_kind_that_runs_on_maps_has_a_map_case_and_the_others_refuse_one():
    on_maps = {k for k, v in KINDS.items() if v.runs_on("discrete")}
    assert on_maps == set(MAP_CASES), f"map cases missing for {sorted(on_maps - set(MAP_CASES))}, extra {sorted(set(MAP_CASES) - on_maps)}"
    with pytest.raises(Exception, match="continuous-time only"):
        KINDS["high_gain"].design(PEND_MAP, theta=2.0)


@pytest.fixture(params=sorted(MAP_CASES))
def map_case(request):
    return (request.param, *MAP_CASES[request.param])


def test_map_designs_are_deterministic_and_leave_their_inputs_alone(map_case):
    kind, model, tuning, x0, xhat0, *_ = map_case
    given = copy.deepcopy(tuning)
    d1, d2 = KINDS[kind].design(model, **given, xhat0=list(xhat0)), KINDS[kind].design(model, **copy.deepcopy(tuning), xhat0=xhat0)
    for k, v in tuning.items():
        assert np.array_equal(np.asarray(given[k], dtype=object), np.asarray(v, dtype=object))
    t = np.arange(30) * model.sample_time
    u, y = np.sin(t)[:, None], np.cos(t)[:, None]
    if isinstance(d1, ParticleDesign):
        r1, r2 = particle_runner(d1).run(t, u=u, y=y), particle_runner(d2).run(t, u=u, y=y)
        assert r1.z.shape == (30, d1.n_z) and np.array_equal(r1.z, r2.z)
    else:
        assert d1.update is not None and d1.update.size1_out(0) == d1.n_z
        z1, z2 = Observer(d1).initial_state(), Observer(d2).initial_state()
        for k in range(5):   # the update of a map: predict from the previous step, correct with y
            z1 = np.asarray(d1.update(t[k], z1, u[k], y[k], [1.0]), dtype=float).ravel()
            z2 = np.asarray(d2.update(t[k], z2, u[k], y[k], [1.0]), dtype=float).ravel()
        assert np.array_equal(z1, z2) and np.all(np.isfinite(z1))
        assert "discrete time" in str(d1)
    assert d1.certificate.reference
    with pytest.raises(TypeError):
        KINDS[kind].design(model, **copy.deepcopy(tuning), not_an_option=1)


def test_map_designs_converge_on_their_plant_and_on_its_recording(map_case):
    kind, model, tuning, x0, xhat0, t_final, tol = map_case
    d = KINDS[kind].design(model, **copy.deepcopy(tuning), xhat0=xhat0)
    run = simulate(model, {kind: d}, t_final=t_final, x0=x0, inputs={"u": "sin(t)"})
    assert run.info["time"] == "discrete" and run.metrics(kind).final_error < tol
    offline = estimate({kind: d}, Recording.from_run(run))
    assert offline.metrics(kind).final_error < tol
    np.testing.assert_allclose(offline.observers[kind].xhat, run.observers[kind].xhat, rtol=0, atol=1e-12)
