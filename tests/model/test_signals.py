"""Input signals: expressions, callables, sampled (ZOH / linear), piecewise."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import DataError, ModelError, ShapeError, System
from nlobs.model import Sampled, as_signal, input_signals

T = np.array([0.0, 0.25, 0.5, 1.0, 2.0])


def test_expression_and_number():
    assert np.allclose(as_signal("0.5*sin(t) + 1", name="u")(T), 0.5 * np.sin(T) + 1)
    assert np.allclose(as_signal(3, name="u")(T), 3.0)


def test_callable_vectorised_and_scalar_only():
    assert np.allclose(as_signal(np.cos, name="u")(T), np.cos(T))
    calls = []

    def step(t):  # scalar-only: `if` on an array raises, so nlobs falls back to a loop
        calls.append(t)
        return 1.0 if t >= 0.5 else 0.0

    assert np.array_equal(as_signal(step, name="u")(T), [0, 0, 1, 1, 1])


def test_sampled_zoh_linear_and_piecewise():
    s = Sampled([0, 1, 2], [0, 10, 20])
    assert np.array_equal(s(np.array([-1, 0, 0.5, 1, 1.5, 3])), [0, 0, 0, 10, 10, 20]) and s.held
    lin = Sampled([0, 1, 2], [0, 10, 20], hold="linear")
    assert np.allclose(lin(np.array([0.5, 1.5])), [5, 15]) and not lin.held
    pw = Sampled.piecewise([0, 0.2, 0.4], [1, 2, 3])
    assert np.array_equal(pw(np.array([0.1, 0.2, 0.39, 0.5])), [1, 2, 2, 3])


def test_sampled_rejects_bad_data():
    with pytest.raises(DataError, match="strictly increasing"):
        Sampled([0, 1, 1], [0, 1, 2])
    with pytest.raises(DataError, match="at row 1"):
        Sampled([0, 1, 2], [0, np.nan, 2])
    with pytest.raises(ShapeError, match="must match"):
        Sampled([0, 1], [0, 1, 2])


def test_input_signals_by_name_and_errors():
    sys = System(states=["x"], f=["-x + u + v"], inputs=["u", "v"], outputs=["y"], h=["x"])
    u, v = input_signals(sys, {"u": "t"})
    assert np.allclose(u(T), T) and np.allclose(v(T), 0)
    with pytest.raises(ModelError, match="'w', which is not an input"):
        input_signals(sys, {"w": 1})
    with pytest.raises(ModelError, match="pass `inputs` as a mapping"):
        input_signals(sys, "t")
    with pytest.raises(ModelError, match="unknown name `x`"):
        input_signals(sys, {"u": "x"})  # an input cannot depend on the state
