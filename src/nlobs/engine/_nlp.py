"""NLP solvers whose functions are compiled C (cached on disk), not run on CasADi's virtual machine.

:func:`compiled_nlpsol` generates the functions a plugin needs (objective, constraints and their
derivatives) with :meth:`casadi.Function.generate_dependencies`, compiles them with the system C
compiler through the engine's cache (:func:`nlobs.engine.compile_c`'s builder), and loads the
plugin on the shared object. Without a compiler the VM is used.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import casadi as ca

from ._codegen import _build, find_compiler

__all__ = ["compiled_nlpsol"]


def compiled_nlpsol(name: str, plugin: str, nlp: Mapping[str, Any], opts: Mapping[str, Any]) -> tuple[ca.Function, bool]:
    """``casadi.nlpsol(name, plugin, nlp, opts)`` with its functions compiled; returns (solver, compiled)."""
    solver = ca.nlpsol(name, plugin, dict(nlp), dict(opts))
    if find_compiler() is None:
        return solver, False
    with tempfile.TemporaryDirectory(prefix="nlobs-nlp-") as tmp:
        cwd = os.getcwd()
        os.chdir(tmp)  # generate_dependencies writes into the working directory
        try:
            solver.generate_dependencies(f"{name}_nlp.c", {"with_header": False})
        finally:
            os.chdir(cwd)
        code = (Path(tmp) / f"{name}_nlp.c").read_text()
    so = _build(code, f"{name}_nlp")
    return ca.nlpsol(name, plugin, str(so), dict(opts)), True
