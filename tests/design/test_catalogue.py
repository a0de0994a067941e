"""Conformance suite over the classical catalogue (issue 3): every design returns the declared shapes, is
deterministic, leaves its inputs unmutated, converges on a trivially observable plant, rejects unknown
keywords, and documents every keyword."""

from __future__ import annotations

import copy
import inspect

import numpy as np
import pytest

import nlobs
from nlobs.design import (
    DESIGNS,
    design_augmented,
    design_banks,
    design_from_config,
    design_high_gain,
    design_high_gain_derivatives,
    design_high_gain_kalman,
    design_kalman_bucy,
    design_kalman_like,
    design_lipschitz,
    design_mhe,
    design_ukf,
)
from nlobs.errors import ModelError

#: x1' = x2, x2' = -x1 - x2, y = x1: observable, stable, and in every form the catalogue needs.
PLANT = nlobs.System(states=["x1", "x2"], f=["x2", "-x1 - x2"], outputs=["y"], h=["x1"], name="oscillator")

CASES = {
    "high_gain": (design_high_gain, {"theta": 5.0}),
    "high_gain_derivatives": (design_high_gain_derivatives,
                              {"r": 0.1, "xhat": {"x1": "y", "x2": "D1_y"}, "nominal": {"y": "-D0_y - D1_y"}}),
    "lipschitz": (design_lipschitz, {"gamma": 0.0}),
    "kalman_bucy": (design_kalman_bucy, {"Q": np.eye(2), "R": np.array([[0.1]])}),
    "kalman_like": (design_kalman_like, {"delta": 4.0, "W": np.array([[0.1]])}),
    "high_gain_kalman": (design_high_gain_kalman, {"lam": 2.0, "delta": 3.0}),
    "banks": (design_banks, {"P": np.array([[-2.0], [0.0]])}),
    "augmented": (design_augmented, {"T": ["x1", "x2"], "A": [[0, 1], [-1, -1]], "C": [[1, 0]],
                                     "left_inverse": ["w1", "w2"], "poles": [-1.0, -2.0]}),
    "ukf": (design_ukf, {"Q": 1e-2 * np.eye(2), "R": np.array([[1e-2]])}),
    "mhe": (design_mhe, {"horizon": 8, "R": np.array([[1e-2]])}),
}
XHAT0 = np.array([0.5, -0.5])


def build(kind, **extra):
    fn, kw = CASES[kind]
    return fn(PLANT, **kw, **extra)


@pytest.mark.parametrize("kind", CASES)
def test_registered(kind):
    assert DESIGNS[kind] is CASES[kind][0]


@pytest.mark.parametrize("kind", CASES)
def test_declared_shapes(kind):
    d = build(kind, xhat0=XHAT0)
    assert d.method == kind
    assert len(d.z_names) == d.n_z
    z0 = np.asarray(d.initial(XHAT0)).ravel()
    assert z0.size == d.n_z
    args = (0.1, z0, np.zeros(PLANT.n_inputs), np.array([0.3]))
    assert np.asarray(d.flow(*args)).size == d.n_z
    assert np.asarray(d.output(*args)).size == PLANT.n_states
    if d.sampled:
        assert np.asarray(d.update(*args, np.ones(1))).size == d.n_z
    assert str(d.certificate)  # readable evidence


@pytest.mark.parametrize("kind", CASES)
def test_deterministic(kind):
    a, b = build(kind), build(kind)
    rng = np.random.default_rng(7)
    for _ in range(3):
        z = np.asarray(a.initial(rng.normal(size=2))).ravel() + 0.01 * rng.normal(size=a.n_z)
        args = (0.2, z, np.zeros(0), rng.normal(size=1))
        np.testing.assert_array_equal(np.asarray(a.flow(*args)), np.asarray(b.flow(*args)))
        if a.sampled:
            np.testing.assert_array_equal(np.asarray(a.update(*args, np.ones(1))), np.asarray(b.update(*args, np.ones(1))))
    assert str(a.certificate) == str(b.certificate)


@pytest.mark.parametrize("kind", CASES)
def test_inputs_unmutated(kind):
    fn, kw = CASES[kind]
    kw_copy = copy.deepcopy(kw)
    x0 = XHAT0.copy()
    fn(PLANT, **kw, xhat0=x0)
    np.testing.assert_array_equal(x0, XHAT0)
    for k, v in kw.items():
        if isinstance(v, np.ndarray):
            np.testing.assert_array_equal(v, kw_copy[k])
        else:
            assert v == kw_copy[k]


@pytest.mark.parametrize("kind", CASES)
def test_converges_on_a_trivially_observable_plant(kind):
    d = build(kind, xhat0=XHAT0)
    sampling = nlobs.Sampling(0.05) if d.sampled else None
    run = nlobs.simulate(PLANT, d, t_final=10.0, dt=1e-2, x0=[1.0, 1.0], sampling=sampling, engine="vm")
    e = run.error_norm()
    assert e[-1] < 1e-3 * e[0], f"{kind}: error {e[0]:.3g} -> {e[-1]:.3g}"


@pytest.mark.parametrize("kind", CASES)
def test_unknown_keywords_are_rejected(kind):
    fn, kw = CASES[kind]
    with pytest.raises(TypeError):
        fn(PLANT, **kw, not_an_option=1)
    with pytest.raises(ModelError, match="unknown option `not_an_option`"):
        design_from_config(PLANT, kind, {**kw, "not_an_option": 1})


@pytest.mark.parametrize("kind", CASES)
def test_every_keyword_is_documented(kind):
    fn = CASES[kind][0]
    doc = inspect.getdoc(fn)
    for name, p in inspect.signature(fn).parameters.items():
        if p.kind is inspect.Parameter.KEYWORD_ONLY:
            assert name in doc, f"{fn.__name__}: `{name}` is not documented"
