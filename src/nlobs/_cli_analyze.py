"""``nlobs analyze MODEL.toml [--json]``: the structural observability report of a model file.

Kept apart from ``cli.py`` (which the core owns) so that the subcommand can be wired in with one
line: ``run_analyze(args.model, args.json, unknown_params=..., inputs=...)``. It imports only the
model and analysis layers, so it answers in well under a second once ``nlobs`` itself imports
lazily.
"""

from __future__ import annotations

import json as _json
import sys
from collections.abc import Sequence
from typing import Any, TextIO

__all__ = ["run_analyze", "add_analyze_arguments"]


def add_analyze_arguments(parser: Any) -> None:
    """Add the ``analyze`` options to an :class:`argparse.ArgumentParser` (sub)parser."""
    parser.add_argument("model", help="a TOML model file")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    parser.add_argument("--params", default="", help="comma-separated parameters to treat as unknown constants "
                        "(identifiability), or 'all'")
    parser.add_argument("--inputs", default="generic", help="'generic' (default), 'constant', or a polynomial degree")
    parser.add_argument("--function", action="append", default=[], help="a function of the states to test for observability "
                        "(repeatable), e.g. 'x1**2 + x2**2'")


def run_analyze(path: str, json: bool = False, *, params: str = "", inputs: str = "generic",
                functions: Sequence[str] = (), out: TextIO | None = None, err: TextIO | None = None) -> int:
    """Analyse the model file at `path` and print the report; return the exit code.

    Exit codes: 0 the model is locally observable (generic rank condition holds), 1 it is not,
    2 the file or an option is invalid (the message says what to change).
    """
    from .analysis import analyze
    from .errors import NlobsError
    from .model import load_model

    out = out or sys.stdout
    err = err or sys.stderr
    try:
        system = load_model(path).system
        unknown: Any = "all" if params.strip() == "all" else [p.strip() for p in params.split(",") if p.strip()]
        inp: Any = int(inputs) if inputs.strip().isdigit() else inputs.strip()
        report = analyze(system, unknown_params=unknown, inputs=inp, functions=list(functions))
    except NlobsError as e:
        print(f"nlobs analyze: {e}", file=err)
        return 2
    if json:
        print(_json.dumps(report.to_dict(), indent=2), file=out)
    else:
        print(report, file=out)
    return 0 if report.observable else 1
