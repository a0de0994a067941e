"""The observer-kind registry (design/_kind.py) is the single source of truth: every list of kinds reads it."""

from __future__ import annotations

import ast
import inspect
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

import nlobs
from nlobs.design import KINDS, Tuning, kind, register_design
from nlobs.design._kind import TIME_BASES
from nlobs.references import REFERENCES, work

SRC = Path(nlobs.__file__).parent


def test_every_kind_is_one_public_function_named_after_it():
    for name, k in KINDS.items():
        fn = k.design
        assert getattr(nlobs, fn.__name__) is fn and getattr(nlobs.design, fn.__name__) is fn, name
        assert fn.__name__ == f"design_{name}", f"{name}: design function {fn.__name__} is not design_{name}"
        assert next(iter(inspect.signature(fn).parameters)) == "system", name
        assert k.time_base in TIME_BASES and k.summary and all(key in REFERENCES for key, _ in k.references), name


def test_no_list_of_kinds_is_written_twice():
    """Outside the design modules (where each kind is declared, and a module may dispatch among its own kinds) and
    the examples (which run a paper's set of observers), no module spells out the kinds a second time: a dict or list
    literal naming three or more kinds by string."""
    names = set(KINDS)
    bad = []
    for path in SRC.rglob("*.py"):
        if path.relative_to(SRC).parts[0] in ("design", "examples"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            keys = node.keys if isinstance(node, ast.Dict) else node.elts if isinstance(node, (ast.List, ast.Tuple, ast.Set)) else []
            hits = {k.value for k in keys if isinstance(k, ast.Constant) and k.value in names}
            if len(hits) >= 3:
                bad.append(f"{path.relative_to(SRC)}:{node.lineno}: {sorted(hits)[:4]}")
    assert not bad, "read the kinds from nlobs.design.KINDS instead of listing them:\n" + "\n".join(bad)


def test_kinds_cli_and_docs_page_come_from_the_registry(capsys, tmp_path, monkeypatch):
    from nlobs.cli import main

    assert main(["kinds", "--json"]) == 0
    listed = [i["kind"] for i in json.loads(capsys.readouterr().out)["kinds"]]
    assert sorted(listed) == sorted(KINDS)
    import sys
    sys.path.insert(0, str(SRC.parents[1] / "docs" / "_ext"))
    import nlobs_docs

    monkeypatch.setattr(nlobs_docs, "HERE", tmp_path)
    nlobs_docs.write_kinds_page()
    page = (tmp_path / "kinds.rst").read_text()
    assert all(f"``{k}``" in page for k in KINDS)


def test_a_kind_registered_by_the_user_is_designed_from_a_file_and_listed(capsys):
    def design_mine(system, *, gain: float = 1.0, xhat0=None):
        """My observer: the EKF with Q = gain·I."""
        return nlobs.design_ekf(system, Q=gain * np.eye(system.n_states), R=[[1.0]], xhat0=xhat0)

    register_design("mine", design_mine)
    try:
        sys_ = nlobs.System(states=["x1", "x2"], f=["x2", "-x1"], outputs=["y"], h=["x1"])
        d = nlobs.design.design_from_config(sys_, "mine", {"gain": 0.5})
        assert d.method == "ekf" and KINDS["mine"].summary.startswith("My observer")
        with pytest.raises(TypeError, match="the model must be"):
            KINDS["mine"].design("not a model")
    finally:
        del KINDS["mine"]


def test_a_kind_declared_twice_or_with_a_bad_time_base_is_refused():
    with pytest.raises(ValueError, match="declared twice"):
        kind("ekf", summary="again")(lambda system: None)
    with pytest.raises(ValueError, match="time_base must be one of continuous, discrete, both"):
        kind("x", summary="s", time_base="hybrid")
    with pytest.raises(ValueError, match=r"\(key, place\) pairs"):
        kind("x", summary="s", references=work("004"))   # a pair, not a tuple of pairs
    with pytest.raises(KeyError, match="no reference 'nope'"):
        work("nope")


def test_tuning_statuses():
    assert Tuning.fails("why", a=1) == Tuning("fails", {"a": 1}, "why")
    assert Tuning.needs("P").why == "needs input: P"
    t = Tuning.tuned({"Q": 1}, "because", choice="note", choice_reason="reason", choice_rank=2)
    assert t.status == "tuned" and t.choice_rank == 2
    assert Tuning.tuned({}, "x").choice_rank == 0                     # no choice, no rank


def test_renamed_function_warns_with_the_new_name():
    with pytest.warns(DeprecationWarning, match="design_2gd is renamed design_gpebo_2gd"):
        old = nlobs.design_2gd
    assert old is nlobs.design_gpebo_2gd
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(AttributeError):
            nlobs.design_nothing  # noqa: B018
