"""Conformance suite over the parameter-estimation based designs (STYLE habit 14).

Every design must: return the declared shapes; be deterministic; leave its inputs unmutated;
converge on a simple plant it is made for; reject unknown keywords; document every parameter.
"""

from __future__ import annotations

import copy
import inspect
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import pytest

from nlobs import (GD, Gradient, LinearRegression, StateAffine, System, WindowedNLS, design_gpebo_2gd, design_drem, design_gd,
                   design_gpebo, design_gradient, design_iandi, design_kkl, design_kkl_learned, design_kkl_pebo,
                   design_kkl_pebo_cascade, design_least_squares, design_pebo, simulate)
from nlobs.design import DESIGNS, ObserverDesign, design_from_config
from nlobs.errors import ModelError

REG = LinearRegression(["psi1", "psi2"], signals=["psi1", "psi2"])
REG_IN = {"psi1": "sin(t)", "psi2": "cos(2*t)"}
OSC_SA = StateAffine([[0, 1], [-1, 0]], [0, "u"], [[1], [0]], inputs=["u"], name="oscillator")
OSC = System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1"], name="oscillator")
PEB = System(states=["x1", "x2"], f=["x2", "-x1 + u"], outputs=["y"], h=["x1"], inputs=["u"], name="pebo_plant")
MIX = System(states=["x1", "x2", "x3"], f=["-x1 + x2 + x3", "-x2 + x1", "u"], outputs=["y"], h=["x1"], inputs=["u"])
DAMPED = System(states=["x1", "x2"], f=["x2", "-x1 - x2 + u"], outputs=["y"], h=["x1"], inputs=["u"])
CASC = System(states=["y1s", "a", "b", "c"], f=["-y1s + a + b + (1 + 0.5*cos(u))*c", "-2*a + sin(y1s)", "-b + a*y1s + u", "-y1s"],
              outputs=["y"], h=["y1s"], inputs=["u"])


@dataclass
class Case:
    name: str
    fn: Callable[..., ObserverDesign]
    system: Any
    kwargs: dict[str, Any]
    x0: tuple[float, ...]
    inputs: dict[str, Any] = field(default_factory=dict)
    t_final: float = 20.0
    tol: float = 1e-4


CASES = [
    Case("gradient", design_gradient, REG, dict(gamma=np.array([2.0, 2.0])), (1.5, -0.7), REG_IN),
    Case("least_squares", design_least_squares, REG, dict(P0=np.eye(2) * 10, forgetting=0.5), (1.5, -0.7), REG_IN, 30.0),
    Case("drem", design_drem, REG, dict(gamma=10.0, lambdas=[2.0]), (1.5, -0.7), REG_IN),
    Case("gd", design_gd, REG, dict(gamma_g=5.0, gamma=50.0), (1.5, -0.7), REG_IN),
    Case("gpebo", design_gpebo, OSC_SA, dict(estimator=Gradient(1.0)), (1.0, -0.5), {"u": "sin(0.5*t)"}, 30.0),
    Case("gpebo_2gd", design_gpebo_2gd, OSC_SA, dict(gamma_g=1.0, gamma=10.0, xhat0=np.array([0.1, 0.1])), (1.0, -0.5),
         {"u": "sin(0.5*t)"}, 30.0),
    Case("kkl", design_kkl, OSC, dict(phi=["(x1 - x2)/2", "(2*x1 - x2)/5"], left_inverse=["5*xi2 - 2*xi1", "5*xi2 - 4*xi1"],
                                      B=["y", "y"], Lambda=np.array([-1.0, -2.0])), (1.0, 0.5)),
    Case("pebo", design_pebo, PEB, dict(phi=["x2"], left_inverse=["y", "xi1"], B=["-y + u"], estimator=Gradient(5.0),
                                        alpha=2.0), (0.3, -0.8), {"u": "sin(t)"}),
    Case("kkl_pebo", design_kkl_pebo, MIX, dict(phi=["x2", "x3"], left_inverse=["y", "xi1", "xi2"], B=["y", "u"],
                                                Lambda=[-1, 0], estimator=GD(5.0, 50.0)), (0.2, 1.0, -0.5), {"u": "cos(t)"}),
    Case("kkl_pebo_nls", design_kkl_pebo, MIX, dict(phi=["x2", "x3"], left_inverse=["y", "xi1", "xi2"], B=["y", "u"],
                                                    Lambda=[-1, 0], estimator=WindowedNLS(window=1.0, samples=11)),
         (0.2, 1.0, -0.5), {"u": "cos(t)"}),
    Case("kkl_pebo_cascade", design_kkl_pebo_cascade, CASC, dict(x2=["a"], x3=["b"], x4=["c"], k="y1s", alpha=2.0,
                                                               estimator=Gradient(20.0)),
         (0.3, 1.0, -1.0, 0.5), {"u": "sin(t)"}),
    Case("iandi", design_iandi, DAMPED, dict(beta=["chi1 + 3*y"], phi=["x2"], left_inverse=["y", "xi1"],
                                             chi0=np.array([0.0])), (0.4, -1.0), {"u": "sin(t)"}, 10.0),
    Case("kkl_learned", design_kkl_learned, OSC, dict(region=np.array([[-1.0, 1.0], [-1.0, 1.0]]), eigenvalues=[-2, -3, -4],
                                                      degree=1, n_trajectories=8, t_final=12.0, dt=0.02),
         (1.0, 0.5), {}, 20.0),
]
IDS = [c.name for c in CASES]


def _plant(case: Case) -> System:
    return case.system.to_system() if hasattr(case.system, "to_system") else case.system


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_declared_shapes(case):
    d = case.fn(case.system, **case.kwargs)
    s = d.system
    assert len(d.z_names) == d.n_z == len(set(d.z_names))
    z = np.linspace(-0.3, 0.4, d.n_z)
    u, y = np.full(s.n_inputs, 0.2), np.full(s.n_outputs, 0.1)
    assert np.asarray(d.flow(0.5, z, u, y)).shape == (d.n_z, 1)
    assert np.asarray(d.output(0.5, z, u, y)).shape == (s.n_states, 1)
    assert np.asarray(d.initial(np.zeros(s.n_states))).shape == (d.n_z, 1)
    if d.update is not None:
        assert np.asarray(d.update(0.5, z, u, y, np.ones(s.n_outputs))).shape == (d.n_z, 1)
    assert d.xhat0.shape == (s.n_states,)


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_deterministic(case):
    a, b = case.fn(case.system, **case.kwargs), case.fn(case.system, **case.kwargs)
    s = a.system
    z = np.linspace(-0.3, 0.4, a.n_z)
    args = (0.5, z, np.full(s.n_inputs, 0.2), np.full(s.n_outputs, 0.1))
    assert a.z_names == b.z_names
    assert np.array_equal(np.asarray(a.flow(*args)), np.asarray(b.flow(*args)))
    assert np.array_equal(np.asarray(a.output(*args)), np.asarray(b.output(*args)))


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_inputs_unmutated(case):
    before = copy.deepcopy(case.kwargs)
    system_before = _plant(case)
    case.fn(case.system, **case.kwargs)
    for k, v in before.items():
        got = case.kwargs[k]
        if isinstance(v, np.ndarray):
            assert np.array_equal(v, got) and got.flags.writeable, k
        else:
            assert v == got, k
    assert _plant(case) == system_before


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_converges_on_a_simple_plant(case):
    d = case.fn(case.system, **case.kwargs)
    run = simulate(_plant(case), {"o": d}, t_final=case.t_final, dt=1e-3, x0=case.x0, inputs=case.inputs)
    e = run.error_norm("o")
    assert e[0] > 10 * case.tol and e[-1] < case.tol


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_unknown_keywords_are_rejected(case):
    with pytest.raises(TypeError):
        case.fn(case.system, **case.kwargs, not_an_option=1)


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_every_parameter_is_documented(case):
    doc = inspect.getdoc(case.fn) or ""
    for name in inspect.signature(case.fn).parameters:
        assert name in doc, f"{case.fn.__name__} does not document `{name}`"


def test_every_design_is_registered_for_model_files():
    for case in CASES:
        assert DESIGNS[case.fn.__name__.removeprefix("design_")] is case.fn
    with pytest.raises(ModelError, match="unknown option `bogus`"):
        design_from_config(PEB, "pebo", {"phi": ["x2"], "left_inverse": ["y", "xi1"], "B": ["-y + u"], "bogus": 1})


def test_model_file_tables_configure_the_estimator():
    d = design_from_config(OSC_SA.to_system(), "gpebo", {"estimator": {"kind": "gd", "gamma_g": 2.0, "gamma": 3.0}})
    assert d.certificate.values["gd.gamma_g"] == 2.0 and d.method == "gpebo_2gd"
    with pytest.raises(ValueError, match="estimator.kind"):
        design_from_config(OSC_SA.to_system(), "gpebo", {"estimator": {"kind": "kalman"}})
    with pytest.raises(ValueError, match="unknown option `gain`"):
        design_from_config(OSC_SA.to_system(), "gpebo", {"estimator": {"kind": "gd", "gain": 1}})
