"""Start-up (issue 38 §4): ``import nlobs`` and ``nlobs --help`` import none of the heavy libraries; they load where
they are first used (a model, a run, a plot). Timed in benchmarks/bench_startup.py, not here."""

from __future__ import annotations

import json
import subprocess
import sys

HEAVY = ("sympy", "casadi", "scipy", "matplotlib", "pandas", "mpmath", "flint")


def _imported_after(code: str) -> list[str]:
    probe = (f"{code}\nimport json, sys\n"
             f"print(json.dumps(sorted({{m.split('.')[0] for m in sys.modules}} & {set(HEAVY)!r})))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_import_nlobs_pulls_in_no_heavy_library():
    assert _imported_after("import nlobs") == []


def test_the_command_line_help_pulls_in_no_heavy_library():
    assert _imported_after("from nlobs.cli import _parser\n_parser().format_help()") == []


def test_the_public_names_still_load_on_first_use():
    import nlobs

    assert nlobs.simulate.__module__.startswith("nlobs.simulate") and callable(nlobs.advise)
    assert nlobs.design_ekf.__name__ == "design_ekf" and nlobs.System.__name__ == "System"
    import importlib

    importlib.import_module("nlobs.simulate._run")      # importing the subpackage keeps nlobs.simulate the function
    assert callable(nlobs.simulate) and not isinstance(nlobs.simulate, type(importlib))
    assert "design_ekf" in dir(nlobs) and "simulate" in dir(nlobs)
