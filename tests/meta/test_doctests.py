"""Docstring examples check their own answers (STYLE §11): run them as tests."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import nlobs

MODULES = sorted(m.name for m in pkgutil.walk_packages(nlobs.__path__, "nlobs.") if not m.name.endswith("__main__"))


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert result.failed == 0, f"{result.failed} docstring example(s) failed in {name}"
