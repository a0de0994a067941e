"""Every public function documents every parameter (as python-control's docstrings_test does)."""

from __future__ import annotations

import inspect
import re

import pytest

import nlobs
import nlobs.analysis
import nlobs.design
import nlobs.estimation
import nlobs.model
import nlobs.learning
import nlobs.simulate

import sys

# `nlobs.simulate` is the function of that name once the package is loaded: the subpackage is read from sys.modules
NAMESPACES = (nlobs, nlobs.design, nlobs.analysis, nlobs.model, sys.modules["nlobs.simulate"], nlobs.estimation,
              nlobs.learning)


def _public_callables():
    seen = {}
    for ns in NAMESPACES:
        for name in dir(ns):
            if name.startswith("_"):
                continue
            obj = getattr(ns, name)
            if inspect.isfunction(obj) and obj.__module__.startswith("nlobs"):
                seen[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return sorted(seen.items())


@pytest.mark.parametrize("qualname, fn", _public_callables(), ids=lambda v: v if isinstance(v, str) else "")
def test_every_parameter_is_documented(qualname, fn):
    doc = inspect.getdoc(fn) or ""
    assert doc.strip(), f"{qualname} has no docstring"
    params = [p for p in inspect.signature(fn).parameters.values()
              if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD) and p.name not in ("self", "cls")]
    if len(params) <= 1 and "Parameters" not in doc:
        return  # a one-argument helper whose summary line says it all
    missing = [p.name for p in params if not re.search(rf"(^|[\s,`(]){re.escape(p.name)}\b", doc)]
    assert not missing, f"{qualname}: undocumented parameter(s) {missing}"
