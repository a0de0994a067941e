"""Data flows one way: a lower layer never imports a higher one (DEVELOPERS guide, STYLE §2)."""

from __future__ import annotations

import ast
from pathlib import Path

import nlobs

ORDER = [
    "model", "engine", "algebra", "analysis", "design", "observer", "simulate", "estimation", "learning", "advise", "report",
]
TOP = {"examples": 10, "interop": 11, "cli": 12}  # examples beside report; interop above; the CLI on top of everything
ROOT = Path(nlobs.__file__).parent


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if node.level:  # relative: resolve against the package
                base = path.relative_to(ROOT).parts[:-1][: len(path.relative_to(ROOT).parts) - node.level]
                parts = list(base) + (mod.split(".") if mod else [])
                out.add(parts[0] if parts else "")
                if not mod:
                    out.update(a.name for a in node.names)
            elif mod.startswith("nlobs."):
                out.add(mod.split(".")[1])
        elif isinstance(node, ast.Import):
            out.update(a.name.split(".")[1] for a in node.names if a.name.startswith("nlobs."))
    return out


def test_no_layer_imports_a_higher_one():
    rank = {name: i for i, name in enumerate(ORDER)} | TOP
    problems = []
    for path in ROOT.rglob("*.py"):
        rel = path.relative_to(ROOT).parts
        layer = rel[0] if len(rel) > 1 else None
        if layer not in rank:
            continue
        for imported in _imports(path):
            if imported in rank and rank[imported] > rank[layer]:
                problems.append(f"{'/'.join(rel)} imports {imported}")
    assert not problems, problems


def test_model_files_are_never_evaluated():
    """No eval/exec/sympify/parse_expr anywhere in the package source."""
    bad = []
    for path in ROOT.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call):
                fn = node.func
                name = fn.id if isinstance(fn, ast.Name) else fn.attr if isinstance(fn, ast.Attribute) else ""
                if name in {"eval", "exec", "sympify", "parse_expr", "lambdify"}:
                    bad.append(f"{path.relative_to(ROOT)}:{node.lineno} {name}")
    assert not bad, bad
