"""simulate._results.lean_traces and the standard deviations of a trace: inside it a trace keeps x̂ and its standard
deviations but not the internal state; the deviations are the square roots of the diagonal of the design's covariance,
evaluated here independently (the full matrix at each sample, its diagonal read by NumPy)."""

from __future__ import annotations

import numpy as np

import nlobs
from nlobs.design import design_srukf, design_ukf
from nlobs.simulate._results import lean_traces

PEND = nlobs.System(states=["th", "w"], f=["w", "-9.81*sin(th) - 0.2*w"], outputs=["y"], h=["th"], name="pend")


def _designs():
    kw = dict(Q=np.diag([1e-4, 1e-3]), R=[[1e-3]], P0=np.eye(2) * 0.1, xhat0=[0.5, 0.0])
    return {"ukf": design_ukf(PEND, **kw), "srukf": design_srukf(PEND, **kw)}


def _run():
    return nlobs.simulate(PEND, _designs(), t_final=3.0, dt=0.01, x0=[0.8, 0.0], noise=nlobs.Noise.gaussian(0.03),
                          sampling=nlobs.Sampling(0.05), seed=3)


def test_std_is_the_root_of_the_covariance_diagonal():
    run = _run()
    for name, tr in run.observers.items():
        P = np.array([np.asarray(tr.covariance(z), dtype=float) for z in tr.z[::25]])
        want = np.sqrt(np.diagonal(P, axis1=1, axis2=2))
        np.testing.assert_allclose(tr.std[::25], want, rtol=1e-12, atol=0, err_msg=name)


def test_a_lean_trace_keeps_the_estimate_and_its_deviations_but_not_the_internal_state():
    full = _run()
    with lean_traces():
        lean = _run()
    for name in full.observers:
        a, b = full.observers[name], lean.observers[name]
        assert a.z.shape[1] > 0 and b.z.shape == (a.z.shape[0], 0) and b.z_names == ()
        np.testing.assert_array_equal(a.xhat, b.xhat)
        np.testing.assert_array_equal(a.std, b.std)
    assert _run().observers["ukf"].z.shape[1] > 0   # outside it again: full traces


def test_the_advisors_ranking_run_is_lean(tmp_path):
    path = tmp_path / "pend.toml"
    path.write_text("""
name = "pend"
states = ["th", "w"]
outputs = ["y"]
[dynamics]
th = "w"
w = "-9.81*sin(th) - 0.2*w"
[output]
y = "th"
[simulation]
t_final = 3.0
dt = 0.01
x0 = [0.8, 0.0]
noise = { y = 0.03 }
sample_period = 0.05
""")
    adv = nlobs.advise(nlobs.load_model(path), kinds=["ukf"], run=True)
    tr = adv.run.observers["ukf"]
    assert tr.z.shape[1] == 0 and tr.std is not None and np.isfinite(tr.std).all()
