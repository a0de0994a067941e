"""Acceptance, M8 #1: 001_1b4027b3a70d560f.txt §IV-C, eqs. (20)-(22)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from nlobs import PreconditionError, simulate
from nlobs.analysis import kalman_rank
from nlobs.examples import toy_augmented as ex


def test_augmented_pair_observable_iff_c_nonzero():
    # 001 §IV-C: O = [[1, 0, 0], [0, 0, 1], [0, 2c, 0]]
    for c in (0.5, -1.0, 3.0):
        A, _, C = ex.augmented_matrices(c)
        assert kalman_rank(A, C).observable
    A, _, C = ex.augmented_matrices(0.0)
    r = kalman_rank(A, C)
    assert r.rank == 2 and np.allclose(np.abs(r.unobservable_directions), [[0, 1, 0]])


def test_paper_gain_places_the_paper_eigenvalues():
    # 001 §IV-C: L = [1+√2, 1, 1+√2] -> eig(A - LC) = -1, -√2/2 ± j√2/2
    A, _, C = ex.augmented_matrices(0.5)
    eig = np.linalg.eigvals(A - ex.L_PAPER @ C)
    assert np.allclose(np.sort_complex(eig), np.sort_complex(ex.EIG_PAPER), atol=1e-12)
    d = ex.paper_observer(ex.toy_system(0.5))
    assert np.allclose(np.sort_complex(d.certificate.values["eigenvalues"]), np.sort_complex(ex.EIG_PAPER), atol=1e-12)


def test_augmented_error_follows_the_linear_law_and_decays_at_sqrt2_over_2():
    system = ex.toy_system(0.5)
    d = ex.paper_observer(system)
    run = simulate(system, {"o": d}, t_final=20.0, dt=1e-3, x0=ex.X0)
    A, _, C = ex.augmented_matrices(0.5)
    M = A - ex.L_PAPER @ C
    w = np.column_stack([run.x, run.x[:, 1] ** 2])  # T(x)
    e_w = run.observers["o"].z - w
    for k in (0, 2000, 7000, 20000):
        assert np.allclose(e_w[k], scipy.linalg.expm(M * run.t[k]) @ e_w[0], atol=1e-9)
    # the slowest mode: rate √2/2, measured over one period of the oscillation
    rate = ex.decay_rate(run.t, run.error_norm("o"), 10.0, 10.0 + 2 * np.pi / (np.sqrt(2) / 2))
    assert rate == pytest.approx(np.sqrt(2) / 2, rel=0.02)
    # (22): x̂ = [I2 0] ŵ
    assert np.allclose(run.observers["o"].xhat, run.observers["o"].z[:, :2])


def test_mimicking_is_checked():
    with pytest.raises(PreconditionError, match="does not mimic"):
        from nlobs import design_augmented

        design_augmented(ex.toy_system(0.5), T=["x1", "x2", "x2**2"], A=[[0, 0, 1], [0, 0, 0], [0, "c", 0]], b=[0, "c", 0],
                         C=[[1, 0, 0]], left_inverse=["w1", "w2"], L=ex.L_PAPER)


def test_example_claims_hold():
    result = ex.run()
    assert all(c.holds is True for c in result.claims), [str(c) for c in result.claims if c.holds is not True]
    assert len(result.table) == 2


def test_global_claims_without_an_engine_are_not_checked_never_failed(monkeypatch):
    """Without a Gröbner engine the global statements cannot be decided: they read "not checked" with
    what to install, are not counted as failures, and the demo's summary and report say so."""
    import io

    import nlobs.analysis.structural._global as G
    from nlobs.examples import ExampleResult
    from nlobs.examples._base import Claim
    from nlobs.report import example_section
    from nlobs.report._demo import _print_summary

    import nlobs.analysis.structural._analyze as A

    monkeypatch.setattr(G, "get_engine", lambda *a, **k: None)
    monkeypatch.setattr(A, "get_engine", lambda *a, **k: None)   # analyze() picks the engine (analysis/structural/_analyze.py)
    claims = ex.global_claims()
    assert [c.holds for c in claims] == [None, None]
    assert all(str(c).startswith("[not checked]") and "msolve" in c.detail for c in claims)
    res = ExampleResult("aug-toy", "t", "r", "s", "m", claims=(Claim("a checked claim", True), *claims))
    assert res.ok and res.tally == "claims 1/3 hold, 2 not checked"
    out = io.StringIO()
    _print_summary([res], [], out, __import__("pathlib").Path("report.html"), 1.0, 1.0)
    assert "claims 1/3 hold, 2 not checked" in out.getvalue() and "NOT CHECKED: c = 0.5" in out.getvalue()
    assert "FAILS" not in out.getvalue()
    html = example_section(res, plots=False)
    assert html.count("class='unchecked'>not checked<") == 2 and "FAILS" not in html
