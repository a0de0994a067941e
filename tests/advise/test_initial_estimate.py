"""x̂(0) and P(0) of states that do not move on the run (a sensor bias, a constant; issue 36 part 4).

The run's box of a constant is a single point: clipping x̂(0) into it started the estimate at the true value, and
bias estimation looked solved when it was never tested. The reference values below come from the rule's definition
computed by hand (σ_w·√t_final, |x(0)|/2, and for x(0) = 0 the offset the outputs resolve: for y = x1 + noise σ with
x1' = b + u, ∂y(t)/∂x(0) = (1, t), so with x1(0) unknown too the offset is √12·σ/T; see the test).
"""

import numpy as np
import pytest

import nlobs
from nlobs.advise import advise
from nlobs.advise._context import build_context
from nlobs.cli._common import _auto_designs
from nlobs.errors import ModelError, ModelFileError

BIAS = """
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
t_final = {T}
dt = 0.01
x0 = [0.5, {b0}]
inputs = {{ u = "sin(t)" }}
noise = {{ y = 0.05 }}
sample_period = 0.05
seed = 3
{extra}
"""


def _file(tmp_path, b0=0.2, T=20.0, extra=""):
    path = tmp_path / "drift.toml"
    path.write_text(BIAS.format(b0=b0, T=T, extra=extra))
    return nlobs.load_model(path)


def _ctx(mf):
    return build_context(mf.system, model_file=mf, unknown_params=mf.unknown_params,
                         true_parameters=dict(mf.simulation.true_parameters))


def test_a_constant_state_is_offset_by_half_its_value_and_p0_matches(tmp_path):
    ctx = _ctx(_file(tmp_path, b0=0.2))
    assert ctx.xhat0[1] != 0.2
    assert abs(ctx.xhat0[1] - 0.2) == pytest.approx(0.1, rel=1e-12)          # |x(0)|/2
    assert ctx.xhat0[1] * 0.2 > 0                                              # keeps its sign
    assert np.sqrt(ctx.P0[1, 1]) == pytest.approx(0.1, rel=1e-12)            # P(0) = σ₀²: a one-σ offset
    assert any("constant on the run (b)" in n for n in ctx.notes)


def test_initial_std_sets_the_offset_and_p0_of_every_state_it_names(tmp_path):
    ctx = _ctx(_file(tmp_path, b0=0.2, extra="initial_std = { b = 0.03, x1 = 0.4 }"))
    assert abs(ctx.xhat0[1] - 0.2) == pytest.approx(0.03, rel=1e-12)
    assert np.sqrt(ctx.P0[1, 1]) == pytest.approx(0.03, rel=1e-12)
    # a moving state named too: offset and P(0) from it, not from its range on the run
    assert abs(ctx.xhat0[0] - 0.5) == pytest.approx(0.4, rel=1e-12)
    assert np.sqrt(ctx.P0[0, 0]) == pytest.approx(0.4, rel=1e-12)


def test_process_noise_sets_the_offset_of_a_constant(tmp_path):
    ctx = _ctx(_file(tmp_path, b0=0.2, T=16.0, extra="process_noise = { b = 0.05 }"))
    assert abs(ctx.xhat0[1] - 0.2) == pytest.approx(0.05 * 4.0, rel=1e-12)    # σ_w·√t_final
    assert np.sqrt(ctx.P0[1, 1]) == pytest.approx(0.2, rel=1e-12)


def test_a_constant_at_zero_is_offset_by_what_the_outputs_resolve(tmp_path):
    T = 20.0
    ctx = _ctx(_file(tmp_path, b0=0.0, T=T))
    # x1(0) and b unknown together (issue 42): sensitivities (1, t), information per sample M = [[1, T/2], [T/2, T²/3]]/σ²,
    # (M⁻¹)_bb = 12σ²/T², so the offset is √12·σ/T (b alone: √3·σ/T)
    expected = np.sqrt(12.0) * 0.05 / T
    assert abs(ctx.xhat0[1]) == pytest.approx(expected, rel=5e-3)
    assert abs(ctx.xhat0[1]) > 1e-6
    assert np.sqrt(ctx.P0[1, 1]) == pytest.approx(abs(ctx.xhat0[1]), rel=1e-12)


def test_the_run_shows_the_bias_converge_from_its_offset(tmp_path):
    adv = advise(_file(tmp_path, b0=0.2), kinds=["ekf"], run=True)
    tr = adv.run.observers["ekf"]
    start = abs(tr.xhat[0, 1] - 0.2)
    assert start == pytest.approx(0.1, rel=1e-12)
    tail = adv.run.t >= 0.8 * adv.run.t[-1]
    steady = float(np.sqrt(np.mean((tr.xhat[tail, 1] - 0.2) ** 2)))
    assert steady < 0.1 * start                       # visible: the offset is more than ten steady-state errors


def test_simulate_with_an_auto_designed_observer_gets_the_same_offset(tmp_path):
    mf = _file(tmp_path, b0=0.2)
    d = _auto_designs(mf, ["ekf"])["ekf"]
    np.testing.assert_array_equal(d.xhat0, _ctx(mf).xhat0)
    assert d.xhat0[1] != 0.2


@pytest.mark.parametrize("extra, key, says", [
    ("initial_std = { c = 0.1 }", "simulation.initial_std.c", "not a state or an unknown parameter"),
    ("initial_std = { b = 0.0 }", "simulation.initial_std.b", "must be positive"),
    ("initial_std = { b = -1.0 }", "simulation.initial_std.b", "must be positive"),
    ("initial_std = { b = inf }", "simulation.initial_std.b", "finite"),
    ("initial_std = { b = \"big\" }", "simulation.initial_std.b", "finite number"),
    ("initial_std = 0.1", "simulation.initial_std", "must be a table"),
])
def test_initial_std_errors_name_the_key(tmp_path, extra, key, says):
    with pytest.raises(ModelFileError) as e:
        _file(tmp_path, extra=extra)
    assert key in str(e.value) and says in str(e.value)


def test_initial_std_of_a_known_parameter_says_to_declare_it_unknown(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(BIAS.format(b0=0.2, T=5.0, extra="initial_std = { k = 0.1 }").replace(
        '[dynamics]', '[parameters]\nk = 2.0\n[dynamics]'))
    with pytest.raises(ModelFileError, match="known parameter.*unknown = true"):
        nlobs.load_model(path)


def test_initial_std_of_an_unknown_parameter_sets_its_p0_not_its_guess(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(BIAS.format(b0=0.2, T=5.0, extra="initial_std = { k = 0.7 }\ntrue_parameters = { k = 1.5 }").replace(
        '[dynamics]', '[parameters]\nk = { value = 1.0, unknown = true }\n[dynamics]').replace('"b + u"', '"b + k*u"'))
    ctx = _ctx(nlobs.load_model(path))
    i = ctx.system.states.index("k")
    assert ctx.xhat0[i] == 1.0                                 # the file's guess
    assert np.sqrt(ctx.P0[i, i]) == pytest.approx(0.7, rel=1e-12)


def test_a_simulation_given_in_python_is_checked_too(tmp_path):
    mf = _file(tmp_path)
    from dataclasses import replace
    sim = replace(mf.simulation, initial_std={"nope": 0.1})
    with pytest.raises(ModelError, match="initial_std names 'nope'.*states and unknown parameters: x1, b"):
        build_context(mf.system, model_file=mf, simulation=sim)
    sim = replace(mf.simulation, initial_std={"b": float("nan")})
    with pytest.raises(ModelError, match="initial_std.b must be a positive finite number"):
        build_context(mf.system, model_file=mf, simulation=sim)


def test_a_bias_the_run_cannot_settle_is_named_in_the_ranking(tmp_path):
    # b enters only through x1' = 0.01·b·sin(0.3t) + u: over 3 s an offset of 0.1 moves y by about 1e-4, far below the
    # noise (0.05)
    path = tmp_path / "weak.toml"
    path.write_text(BIAS.format(b0=0.2, T=3.0, extra="").replace('"b + u"', '"0.01*b*sin(0.3*t) + u"'))
    adv = advise(nlobs.load_model(path), kinds=["ekf"], run=True)
    (s,) = adv.scores
    assert "not converged within the run: b (" in s.detail
    adv = advise(_file(tmp_path, b0=0.2), kinds=["ekf"], run=True)      # x1' = b + u: b settles
    assert "not converged" not in adv.scores[0].detail


@pytest.mark.parametrize("extra, k0, c0", [
    ("", 1.0 * 1.3, 2.0 * 0.7),                                   # 30 % off, the first up, the second down
    ("initial_std = { k = 0.2, c = 0.5 }", 1.0 + 0.2, 2.0 - 0.5),   # by σ₀ where initial_std names it
])
def test_an_unknown_parameter_whose_guess_is_its_truth_starts_off_it(tmp_path, extra, k0, c0):
    """Without true_parameters the file's value is both the plant's and the guess: an estimate started there tests
    nothing (issue 36's rule 'no default may start an estimate at the true value', found on a 12-tank model where
    a and b 'converged' from their true values)."""
    path = tmp_path / "p.toml"
    path.write_text(BIAS.format(b0=0.2, T=5.0, extra=extra).replace(
        '[dynamics]', '[parameters]\nk = { value = 1.0, unknown = true }\nc = { value = 2.0, unknown = true }\n[dynamics]')
        .replace('"b + u"', '"b + k*u - c*x1"'))
    ctx = _ctx(nlobs.load_model(path))
    i, j = ctx.system.states.index("k"), ctx.system.states.index("c")
    assert (ctx.truth["k"], ctx.truth["c"]) == (1.0, 2.0)                   # the plant runs the file's values
    assert ctx.xhat0[i] == pytest.approx(k0, rel=1e-12)
    assert ctx.xhat0[j] == pytest.approx(c0, rel=1e-12)
    assert any("tests nothing" in n for n in ctx.notes)
    # P(0) covers the offset (a one-σ error)
    assert np.sqrt(ctx.P0[i, i]) >= abs(ctx.xhat0[i] - 1.0) * (1 - 1e-12)


def test_a_parameter_with_a_true_value_of_its_own_starts_at_the_guess(tmp_path):
    path = tmp_path / "p.toml"
    path.write_text(BIAS.format(b0=0.2, T=5.0, extra="true_parameters = { k = 1.5 }").replace(
        '[dynamics]', '[parameters]\nk = { value = 1.0, unknown = true }\n[dynamics]').replace('"b + u"', '"b + k*u"'))
    ctx = _ctx(nlobs.load_model(path))
    assert ctx.xhat0[ctx.system.states.index("k")] == 1.0
    assert not any("tests nothing" in n for n in ctx.notes)


def test_on_a_recording_the_parameters_start_at_the_guess(tmp_path):
    """On recorded data the plant is the real one: the file's value is only a guess, and there is no truth to avoid."""
    path = tmp_path / "p.toml"
    path.write_text(BIAS.format(b0=0.2, T=5.0, extra="").replace(
        '[dynamics]', '[parameters]\nk = { value = 1.0, unknown = true }\n[dynamics]').replace('"b + u"', '"b + k*u"'))
    mf = nlobs.load_model(path)
    t = np.linspace(0, 5, 101)
    rec = nlobs.Recording.from_arrays(mf.system, t, (0.5 + 0.2 * t - np.cos(t) + 1)[:, None], np.sin(t)[:, None])
    ctx = build_context(mf.system, model_file=mf, unknown_params=mf.unknown_params, recording=rec)
    assert ctx.xhat0[ctx.system.states.index("k")] == 1.0
    assert not any("tests nothing" in n for n in ctx.notes)
