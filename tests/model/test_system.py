"""System: construction, validation with clear errors, immutability, parameters."""

from __future__ import annotations

import pytest
import sympy as sp

from nlobs import ModelError, System
from nlobs.model import symbol


def vdp(**kw):
    return System(states=["x1", "x2"], f=["x2", "mu*(1 - x1**2)*x2 - x1 + u"], outputs=["y"], h=["x1"],
                  inputs=["u"], params={"mu": 1.0}, name="vdp", **kw)


def test_fields_and_symbols():
    s = vdp()
    assert s.states == ("x1", "x2") and s.inputs == ("u",) and s.outputs == ("y",)
    assert s.n_states == 2 and s.n_params == 1 and dict(s.params) == {"mu": 1.0}
    x1, x2, u, mu = (symbol(n) for n in ("x1", "x2", "u", "mu"))
    assert sp.expand(s.f[1] - (mu * (1 - x1**2) * x2 - x1 + u)) == 0
    assert s.h == (x1,)
    assert not s.is_time_varying


def test_mapping_form_and_sympy_expressions_with_other_assumptions():
    a, b = sp.symbols("a b")  # plain symbols (no real=True) are matched by name
    s = System(states=["a", "b"], f={"b": -a, "a": b}, outputs=["y"], h={"y": a + sp.sin(b)})
    assert s.f == (symbol("b"), -symbol("a"))
    assert s.h[0] == symbol("a") + sp.sin(symbol("b"))


def test_time_varying_detected():
    s = System(states=["x"], f=["-x + sin(t)"], outputs=["y"], h=["x"])
    assert s.is_time_varying


def test_with_params_returns_new_system_and_rejects_unknown():
    s = vdp()
    s2 = s.with_params(mu=2.5)
    assert s.params["mu"] == 1.0 and s2.params["mu"] == 2.5
    assert s.key == s2.key  # same structure
    with pytest.raises(ModelError, match="`nu` is not a parameter of 'vdp'; its parameters are: mu"):
        s.with_params(nu=1.0)


def test_immutable():
    s = vdp()
    with pytest.raises(AttributeError, match="immutable"):
        s.name = "other"  # type: ignore[misc]
    with pytest.raises(TypeError):
        s.params["mu"] = 3.0  # type: ignore[index]


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(states=["x", "x"], f=["1", "2"], outputs=["y"], h=["x"]), "declared twice"),
        (dict(states=["x"], f=["1"], outputs=["x"], h=["x"]), "declared twice \\(as state and as output\\)"),
        (dict(states=["x"], f=["z"], outputs=["y"], h=["x"]), "unknown name `z`"),
        (dict(states=["x"], f=["x", "x"], outputs=["y"], h=["x"]), "`f` has 2 equation\\(s\\) but there are 1 states"),
        (dict(states=["x", "v"], f={"x": "v"}, outputs=["y"], h=["x"]), "no equation for the state\\(s\\) 'v'"),
        (dict(states=["x"], f={"x": "1", "q": "2"}, outputs=["y"], h=["x"]), "'q', which is not a declared state"),
        (dict(states=["t"], f=["1"], outputs=["y"], h=["t"]), "reserved"),
        (dict(states=["sin"], f=["1"], outputs=["y"], h=["1"]), "reserved"),
        (dict(states=["1x"], f=["1"], outputs=["y"], h=["1"]), "not valid"),
        (dict(states="x", f=["1"], outputs=["y"], h=["x"]), "must be a list of names"),
        (dict(states=["x"], f=[sp.Function("g")(sp.Symbol("x"))], outputs=["y"], h=["x"]), "not supported"),
        (dict(states=["x"], f=[sp.Symbol("w")], outputs=["y"], h=["x"]), "unknown symbol `w`"),
        (dict(states=["x"], f=["1"], outputs=["y"], h=["x"], params={"k": float("nan")}), "must be finite"),
        (dict(states=["x"], f=["1"], outputs=["y"], h=["x"], params={"k": "abc"}), "must be a number"),
        (dict(states=[], f=[], outputs=["y"], h=["1"]), "at least one state"),
    ],
)
def test_invalid_models_are_rejected_with_the_reason(kwargs, message):
    with pytest.raises(ModelError, match=message):
        System(**kwargs)


def test_str_shows_equations():
    text = str(vdp())
    assert "System 'vdp': 2 states (x1, x2)" in text
    assert "x1' = x2" in text and "y = x1" in text and "mu=1" in text


def test_equality_and_hash():
    assert vdp() == vdp() and hash(vdp()) == hash(vdp())
    assert vdp() != vdp().with_params(mu=3.0)


def test_substituted_uses_exact_rationals():
    s = System(states=["x"], f=["-k*x"], outputs=["y"], h=["x"], params={"k": 0.1})
    f, _ = s.substituted()
    assert f[0] == -sp.Rational(1, 10) * symbol("x")


def test_pickle_round_trip():
    import pickle

    s = vdp()
    back = pickle.loads(pickle.dumps(s))
    assert back == s and back.f == s.f and dict(back.params) == dict(s.params)


def test_augmented_appends_parameters_as_constant_states():
    import pickle

    s = System(states=["x"], f=["-k*x + c*u"], inputs=["u"], outputs=["y"], h=["x"], params={"k": 0.3, "c": 2.0})
    a = s.augmented(["k"])
    assert a.states == ("x", "k") and a.estimated_params == ("k",) and dict(a.params) == {"c": 2.0}
    assert str(a.f[0]) == str(s.f[0]) and a.f[1] == 0
    assert pickle.loads(pickle.dumps(a)) == a and a != s.augmented(["c"])
    assert a.with_params(c=1.0).estimated_params == ("k",)
    with pytest.raises(ModelError, match="`z` is not a parameter"):
        s.augmented(["z"])
    with pytest.raises(ModelError, match="must be constant"):
        System(states=["x"], f=["-x"], outputs=["y"], h=["x"], estimated_params=["x"])
