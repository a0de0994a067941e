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

from ._codegen import _build, built_path, find_compiler, signature_of

__all__ = ["compiled_nlpsol", "nlp_signature", "nlp_built"]


def nlp_signature(nlp: Mapping[str, Any]) -> str:
    """A hash of the NLP's definition (its objective and constraints as one CasADi function)."""
    keys = [k for k in ("x", "p") if k in nlp]
    return signature_of(ca.Function("nlp", [nlp[k] for k in keys], [nlp[k] for k in ("f", "g") if k in nlp]))


def nlp_built(name: str, sig: str, plugin: str) -> bool:
    """Whether the compiled functions of the NLP of signature `sig` are in the cache."""
    path = built_path(f"{name}_nlp", sig, plugin)
    return path is not None and path.exists()


def compiled_nlpsol(name: str, plugin: str, nlp: Mapping[str, Any], opts: Mapping[str, Any], *,
                    sig: str | None = None) -> tuple[ca.Function, bool]:
    """``casadi.nlpsol(name, plugin, nlp, opts)`` with its functions compiled; returns (solver, compiled). With `sig`
    (:func:`nlp_signature`) the build is found in the cache by it, without generating the code."""
    solver = ca.nlpsol(name, plugin, dict(nlp), dict(opts))
    if find_compiler() is None:
        return solver, False
    if sig is not None:
        so = built_path(f"{name}_nlp", sig, plugin)
        if so is not None and so.exists():
            return ca.nlpsol(name, plugin, str(so), dict(opts)), True
    with tempfile.TemporaryDirectory(prefix="nlobs-nlp-") as tmp:
        cwd = os.getcwd()
        os.chdir(tmp)  # generate_dependencies writes into the working directory
        try:
            solver.generate_dependencies(f"{name}_nlp.c", {"with_header": False})
        finally:
            os.chdir(cwd)
        code = (Path(tmp) / f"{name}_nlp.c").read_text()
    so = _build(code, f"{name}_nlp", built_path(f"{name}_nlp", sig, plugin) if sig is not None else None)
    return ca.nlpsol(name, plugin, str(so), dict(opts)), True
