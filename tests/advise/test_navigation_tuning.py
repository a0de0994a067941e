"""The default tuning on models whose states do not all move on the run, the honest ranking, the file's own observers in
the ranking, and a random walk on an unknown parameter (issue 42, items 2-4).

Reference values come from independent computations in plain NumPy: the smallest offset of x_i(0) the run resolves
with all initial values unknown, δ_i = √((M⁻¹)_ii), M = mean_t Σ_k (∂y_k(t)/∂x(0))ᵀ(∂y_k(t)/∂x(0))/σ_k², is computed from
finite differences of an RK4 simulation written here (not from the linearised sensitivities of
nlobs.advise._context._resolvable), and the random walk's increments are checked against σ²·dt.
"""

import json

import numpy as np
import pytest

import nlobs
from nlobs.advise import advise
from nlobs.advise._advice import Score
from nlobs.advise._context import build_context
from nlobs.advise._rank import rank
from nlobs.cli import main
from nlobs.errors import ModelError, ModelFileError
from nlobs.report import write_model_report

# A cart on a flat road: p, v, pitch theta (0: flat), height h and vertical speed vh (moved only by a 1e-8 m/s²
# vibration: their range on the run is rounding), accelerometer bias b. Before issue 42 the vertical speed's range
# (~1e-8) made ‖D⁻¹ ∂f/∂x D‖ and so ω_p about 5000 s⁻¹: P(0) of 1e-7 on h and vh, Q of 1e-3 on b.
FLAT = """
name = "flat6"
states = ["p", "v", "theta", "h", "vh", "b"]
inputs = ["a", "az"]
outputs = ["gp", "gh"]
[dynamics]
p = "v"
v = "(a - b)*cos(theta)"
theta = "0"
h = "vh"
vh = "(a - b)*sin(theta) + az"
b = "0"
[output]
gp = "p"
gh = "h"
[simulation]
t_final = 20.0
dt = 0.01
x0 = [0.0, 5.0, 0.0, 100.0, 0.0, 0.1]
inputs = { a = "0.5*sin(0.3*t) + 0.1", az = "1e-8*sin(0.5*t)" }
noise = { gp = 0.5, gh = 1.0 }
sample_period = 0.2
seed = 3
"""
SIG = np.array([0.5, 1.0])
T, DT = 20.0, 0.01


def _f(x, t):
    p, v, th, h, vh, b = x
    a = 0.5 * np.sin(0.3 * t) + 0.1
    az = 1e-8 * np.sin(0.5 * t)
    return np.array([v, (a - b) * np.cos(th), 0.0, vh, (a - b) * np.sin(th) + az, 0.0])


def _outputs(x0):
    """RK4 in NumPy on the grid of the run; the outputs (p, h) at every step."""
    x = np.array(x0, dtype=float)
    ys = [x[[0, 3]].copy()]
    for k in range(int(round(T / DT))):
        t = k * DT
        k1 = _f(x, t)
        k2 = _f(x + 0.5 * DT * k1, t + 0.5 * DT)
        k3 = _f(x + 0.5 * DT * k2, t + 0.5 * DT)
        k4 = _f(x + DT * k3, t + DT)
        x = x + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        ys.append(x[[0, 3]].copy())
    return np.array(ys)


def _resolvable_by_finite_differences(x0):
    """δ_i = √((M⁻¹)_ii), M = mean_t Sᵀ Σ⁻¹ S with S = ∂y(t)/∂x(0) by central differences: the offsets the run resolves
    with every initial value unknown together."""
    cols = []
    for i in range(len(x0)):
        e = 1e-4 * max(1.0, abs(x0[i]))
        up, dn = np.array(x0, dtype=float), np.array(x0, dtype=float)
        up[i] += e
        dn[i] -= e
        cols.append((_outputs(up) - _outputs(dn)) / (2 * e) / SIG)   # ∂y(t)/∂x_i(0) / σ, shape (N, 2)
    S = np.stack(cols, axis=2)                                        # (N, 2, n)
    M = np.einsum("tki,tkj->ij", S, S) / S.shape[0]
    return np.sqrt(np.diag(np.linalg.inv(M)))


def _load(tmp_path, text, name="m.toml"):
    path = tmp_path / name
    path.write_text(text)
    return nlobs.load_model(path)


def test_states_that_do_not_move_get_p0_and_q_of_the_size_the_run_resolves(tmp_path):
    mf = _load(tmp_path, FLAT)
    ctx = build_context(mf.system, model_file=mf)
    x0 = np.array(mf.simulation.x0)
    delta = _resolvable_by_finite_differences(x0)
    names = list(ctx.system.states)
    sd0 = np.sqrt(np.diag(ctx.P0))
    # P(0) is never below what the sensors resolve (the old rule gave h and vh 1e-7)
    assert np.all(sd0 >= 0.97 * delta), dict(zip(names, sd0 / delta))
    # the quiet states (h, vh: their range is rounding) and the constant at 0 (theta) get P(0) = δ², not more
    for s in ("h", "vh", "theta"):
        i = names.index(s)
        assert sd0[i] == pytest.approx(delta[i], rel=0.03), s
    # the bias (x(0) = 0.1) starts off by |x(0)|/2 = 0.05 > δ_b: P(0) = 0.05²
    ib = names.index("b")
    assert delta[ib] < 0.05 and sd0[ib] == pytest.approx(0.05, rel=1e-9)
    # constants get a random walk the run cannot resolve: over t_final, a tenth of min(δ, σ₀)
    for s, sigma0 in (("b", 0.05), ("theta", delta[names.index("theta")])):
        i = names.index(s)
        assert ctx.Q[i, i] == pytest.approx((0.1 * min(delta[i], sigma0)) ** 2 / T, rel=0.06), s
    # the plant's rate is that of its moving states, not of the rounding in vh (it was ~5000 s⁻¹)
    assert ctx.omega_p < 1.0
    # the Cramér–Rao bound of x(0) from the run's 100 samples of each output: F = 100·M, so δ/10
    np.testing.assert_allclose(ctx.cramer_rao, delta / np.sqrt(T / 0.2), rtol=0.03)


class _Ctx:
    """What _unsettled reads of a context: one constant state."""

    def __init__(self, bound):
        self.model = nlobs.System(states=["c"], f=["0"], outputs=["y"], h=["c"], name="c")
        self.system = self.model
        self.constant = (0,)
        self.scenario = None
        self.cramer_rao = np.array([bound])


@pytest.mark.parametrize("bound, settled", [(0.05, False), (0.1, True), (0.2, False)])
def test_a_constant_within_three_cramer_rao_bounds_is_settled_where_the_run_can_show_it_halve(bound, settled):
    from nlobs.advise._rank import _unsettled

    err = np.full((10, 1), 0.25)          # 25 % of the initial error of 1 left at the end
    tail = np.arange(10) >= 8
    # 3·bound: 0.15 < 0.25 (not settled); 0.3 ≥ 0.25 and ≤ 0.5 (settled); 0.6 > 0.5: the run cannot show it halve
    assert (_unsettled(err, tail, _Ctx(bound), np.array([1.0])) == "") is settled


def test_a_run_where_no_candidate_converges_names_no_best(tmp_path, capsys):
    # b enters only through x1' = 0.01·b·sin(0.3t) + u: over 3 s its offset moves y far less than the noise, so no
    # filter settles it (the run ends with b unsettled for every candidate)
    text = """
name = "weak"
states = ["x1", "b"]
inputs = ["u"]
outputs = ["y"]
[dynamics]
x1 = "0.01*b*sin(0.3*t) + u"
b = "0"
[output]
y = "x1"
[simulation]
t_final = 3.0
dt = 0.01
x0 = [0.5, 0.2]
inputs = { u = "sin(t)" }
noise = { y = 0.05 }
sample_period = 0.05
seed = 3
"""
    mf = _load(tmp_path, text, "weak.toml")
    adv = advise(mf, kinds=["ekf", "ukf"], run=True)
    ok = [s for s in adv.scores if s.status == "ok"]
    assert ok and all(s.converged is False for s in ok)
    assert adv.best is None
    assert "NO BEST" in str(adv) and "nlobs tune" in str(adv)
    d = adv.to_dict()
    assert d["best"] is None and "none is recommended" in d["none_converged"]
    text = write_model_report(adv, tmp_path / "rep").read_text()
    assert "no observer converged on the run: none is recommended" in text and "best:" not in text
    assert main(["design", str(tmp_path / "weak.toml"), "--run", "--json", "--kind", "ekf"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["best"] is None and "nlobs tune" in out["none_converged"]


def test_a_run_that_ends_worse_than_it_started_is_ranked_after_those_that_converged():
    good = Score("slow", "ok", 1.0, None, 1.0, normalised_rms=0.5, converged=True)
    bad = Score("fast_but_wrong", "ok", 0.1, 1.0, 0.1, normalised_rms=0.01, converged=False)
    failed = Score("x", "diverged", detail="non-finite")
    assert [s.kind for s in rank([bad, failed, good])] == ["slow", "fast_but_wrong", "x"]
    assert not bad.eligible and good.eligible


MINE = """
name = "drift"
states = ["x1", "b"]
inputs = ["u"]
outputs = ["y"]
[dynamics]
x1 = "b + u"
b = "0"
[output]
y = "x1"
[simulation]
t_final = 5.0
dt = 0.01
x0 = [0.5, 0.2]
inputs = { u = "sin(t)" }
noise = { y = 0.05 }
sample_period = 0.05
seed = 3
[observers.mine]
kind = "ekf"
Q = [[1e-6, 0.0], [0.0, 1e-8]]
R = [[0.0025]]
P0 = [[0.01, 0.0], [0.0, 0.04]]
"""


def test_the_files_own_observer_is_ranked_beside_the_candidates(tmp_path):
    mf = _load(tmp_path, MINE, "mine.toml")
    adv = advise(mf, kinds=["ekf"], run=True)
    mine = [s for s in adv.scores if s.own == "mine"]
    assert len(mine) == 1 and mine[0].kind == "file:mine" and mine[0].status == "ok"
    assert "file:mine" in adv.ranking and "ekf" in adv.ranking
    assert "file:mine" in str(adv)
    assert any(r.get("observer") == "mine" and r.get("from_file") for r in adv.to_dict()["scores"])
    assert "file:mine (yours)" in write_model_report(adv, tmp_path / "rep").read_text()


DRIFT = """
name = "heat"
states = ["T"]
inputs = ["u"]
outputs = ["y"]
[parameters]
k = {{ value = 0.5, unknown = true }}
[dynamics]
T = "-k*T + u"
[output]
y = "T"
[simulation]
t_final = 20.0
dt = 0.01
x0 = [1.0]
inputs = {{ u = "1 + sin(t)" }}
noise = {{ y = 0.01 }}
sample_period = 0.1
process_noise = {{ {pn} }}
seed = 5
"""


def test_process_noise_on_an_unknown_parameter_is_its_random_walk_in_the_plant_and_the_filters_q(tmp_path):
    mf = _load(tmp_path, DRIFT.format(pn="k = 0.05"), "heat.toml")
    assert dict(mf.simulation.process_noise) == {"k": 0.05}
    ctx = build_context(mf.system, model_file=mf, unknown_params=mf.unknown_params)
    assert ctx.system.states == ("T", "k")
    assert ctx.Q[1, 1] == pytest.approx(0.05 ** 2, rel=1e-12)
    # the plant the candidates are compared on: the parameter wanders with increments of variance σ²·dt
    sc = ctx.scenario
    run = nlobs.simulate(ctx.system, None, t_final=sc.t_final, dt=sc.dt, x0=sc.x0, inputs=sc.inputs,
                         process_noise=sc.process_noise, seed=1)
    dk = np.diff(run.x[:, 1])
    assert np.var(dk) == pytest.approx(0.05 ** 2 * sc.dt, rel=0.1)
    assert np.all(np.diff(run.x[:, 0]) != 0)
    # nlobs.simulate on the file: the plant carries k as a state, and it wanders too
    run2 = nlobs.simulate(mf)
    assert run2.x.shape[1] == 2
    assert np.var(np.diff(run2.x[:, 1])) == pytest.approx(0.05 ** 2 * 0.01, rel=0.1)


def test_process_noise_naming_neither_a_state_nor_an_unknown_parameter_is_refused(tmp_path):
    with pytest.raises(ModelFileError, match="not one of"):
        _load(tmp_path, DRIFT.format(pn="q = 0.05"), "bad.toml")
    known = DRIFT.format(pn="g = 0.05").replace("[parameters]\n", "[parameters]\ng = 2.0\n")
    with pytest.raises(ModelFileError, match="known parameter"):
        _load(tmp_path, known, "known.toml")
    mf = _load(tmp_path, DRIFT.format(pn="k = 0.05"), "heat.toml")
    with pytest.raises(ModelError, match="does not estimate"):
        build_context(mf.system, model_file=mf, unknown_params=())
