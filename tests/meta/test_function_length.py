"""No function in nlobs is longer than 150 lines, docstring included (issue 19: a newcomer reads one screenful of
logic at a time; the long ones were split into named steps)."""

from __future__ import annotations

import ast
from pathlib import Path

import nlobs

LIMIT = 150


def test_no_function_over_150_lines():
    root = Path(nlobs.__file__).parent
    long = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
                size = node.end_lineno - first + 1
                if size > LIMIT:
                    long.append(f"{path.relative_to(root)}:{node.lineno} {node.name}: {size} lines")
    assert not long, "split these into named steps:\n" + "\n".join(long)
