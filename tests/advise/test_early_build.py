"""design --run builds each candidate's code early, beside the designs, where the run is compile-bound
(advise._early.EarlyBuild): the comparison must load exactly what was built (nothing compiled twice) and rank as
without it."""

from __future__ import annotations

import importlib
import threading

import pytest

import nlobs
from nlobs.engine import _codegen, find_compiler

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")


@pytest.fixture
def builds(monkeypatch, tmp_path):
    """(thread name, tag, the first compiler command's output file) of every compiler run, in a fresh cache."""
    monkeypatch.setenv("NLOBS_CACHE_DIR", str(tmp_path))
    seen: list[tuple[str, str]] = []
    orig = _codegen._run_compilers

    def counted(cc, commands, tag, left):
        seen.append((threading.current_thread().name, tag))
        return orig(cc, commands, tag, left)

    monkeypatch.setattr(_codegen, "_run_compilers", counted)
    return seen


def _ranking(adv):
    return [(s.kind, s.status, round(s.rms_error, 12) if s.rms_error is not None else None) for s in adv.scores]


def test_the_comparison_loads_the_code_built_early_and_ranks_the_same(builds, monkeypatch):
    adv = nlobs.advise("cart_pole", kinds=["ekf", "ukf"], run=True, tune=False, engine="c")
    early = [b for b in builds if b[0].startswith("nlobs-early-build")]
    assert early, builds   # the ekf (designed first) was built beside the next design
    # one build per candidate on the compiled engine: the comparison loaded the early build (code of its own for the
    # same candidate would be a third build)
    assert len(builds) == 2, builds
    advise_module = importlib.import_module("nlobs.advise._advise")   # the module (nlobs.advise is the function)
    monkeypatch.setattr(advise_module.EarlyBuild, "add", lambda self, c: None)
    again = nlobs.advise("cart_pole", kinds=["ekf", "ukf"], run=True, tune=False, engine="c")
    assert _ranking(adv) == _ranking(again)


def test_nothing_is_built_early_where_the_advisor_tunes_the_designs(builds):
    nlobs.advise("van_der_pol", kinds=["ekf"], run=True)   # 2 states: tuned before ranking, a new design
    assert not [b for b in builds if b[0].startswith("nlobs-early-build")], builds
