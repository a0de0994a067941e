"""The command line: ``nlobs COMMAND ...``, one module per command.

Each command module defines ``add_parser(sub)`` (its sub-parser, with ``set_defaults(run=...)``)
and the function that runs it. Errors print one line (``nlobs: error: ...``) and exit non-zero;
with ``--json`` they print one JSON object ``{"error": {"type": ..., "message": ...}}`` on stderr;
``--debug`` shows the traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence

from . import _analyze, _demo, _design, _estimate, _export, _fit, _kinds, _models, _report, _simulate
from ._common import error_message

__all__ = ["main", "COMMANDS"]

#: The command modules, in the order `nlobs --help` lists them.
COMMANDS = [_demo, _models, _analyze, _design, _report, _simulate, _estimate, _fit, _export, _kinds]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="nlobs", description="Nonlinear observability analysis and state-observer design.")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in COMMANDS:
        module.add_parser(sub)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return args.run(args)
    except KeyboardInterrupt:
        print("nlobs: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - the CLI turns every error into one line
        if args.debug:
            raise
        message = error_message(e)
        if getattr(args, "json", False):
            print(json.dumps({"error": {"type": type(e).__name__, "message": message}}), file=sys.stderr)
        else:
            print(f"nlobs: error: {message}", file=sys.stderr)
        return 1
