"""Acceptance, M8 #5 (first half): 002_613af42269ea26a7.txt robot arm with the error-linearisation observer."""

from __future__ import annotations

import numpy as np
import pytest

from nlobs import design_output_injection, simulate
from nlobs.examples import pendulum as ex
from nlobs.model import OutputInjectionForm


def test_the_pendulum_is_in_output_injection_form():
    s = ex.pendulum()
    form = OutputInjectionForm.from_system(s)
    a1, a2, b = (s.params[k] for k in ("a1", "a2", "b"))
    assert np.allclose(form.A, [[0, 1], [0, -a2]])
    y, u = s.y[0], s.u[0]
    assert float((form.B[1] - (-a1 * __import__("sympy").sin(y) + b * u)).subs({y: 0.7, u: -0.3})) == pytest.approx(0, abs=1e-12)


def test_error_is_linear_and_global():
    s = ex.pendulum()
    d = design_output_injection(s, poles=ex.POLES)
    for x0, xhat0 in (((1.0, 0.0), (0.0, 0.0)), ((3.0, -2.0), (-2.0, 4.0))):  # large errors too: global
        run = simulate(s, {"o": d}, t_final=8.0, dt=1e-3, x0=x0, inputs={"u": "sin(t)"}, xhat0=xhat0)
        form = OutputInjectionForm.from_system(s)
        M = form.A - d.certificate.values["K"] @ form.C
        assert ex.linear_error_deviation(run.t, run.error("o"), M) < 1e-8
        assert ex.decay_rate(run.t, run.error_norm("o"), 3.0, 7.0) == pytest.approx(2.0, rel=0.03)


def test_example_claims_hold():
    result = ex.run()
    assert all(c.holds is True for c in result.claims), [str(c) for c in result.claims if c.holds is not True]
