"""The command line: ``nlobs COMMAND ...``, one module per command.

Each command module defines ``add_parser(sub)`` (its sub-parser, with ``set_defaults(run=...)``)
and the function that runs it. Errors print one line (``nlobs: error: ...``) and exit non-zero;
with ``--json`` they print one JSON object ``{"error": {"type": ..., "message": ...}}`` on stderr;
``--debug`` shows the traceback. A reader that closes the pipe early (``nlobs analyze M | head``) ends the
command quietly with status 0.

Exit status: 0 success; 1 an error (one line); 2 a usage error; 3 (``simulate``, ``estimate``) some
observers failed — each is named on stderr with its reason, and the others' results are printed and written;
130 interrupted.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from typing import NoReturn

from . import _analyze, _demo, _design, _estimate, _export, _fit, _kinds, _models, _report, _sensors, _simulate, _tune
from ._common import error_message, positive_int

__all__ = ["main", "COMMANDS"]

#: The command modules, in the order `nlobs --help` lists them.
COMMANDS = [_demo, _models, _analyze, _sensors, _design, _report, _simulate, _estimate, _fit, _tune, _export, _kinds]


class _Parser(argparse.ArgumentParser):
    """Usage errors as one line that names the option (``nlobs simulate: error: argument --dt: expected a positive
    number ..., got '0'``) and where the usage is, instead of the whole usage block first."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="nlobs", description="Nonlinear observability analysis and state-observer design.")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    p.add_argument("--max-expression", type=positive_int, metavar="N",
                   help="longest expression a model file may hold, in characters (default 200000)")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in COMMANDS:
        module.add_parser(sub)
    return p


def _closed_pipe() -> int:
    """stdout was closed by the reader (``nlobs analyze ... | head``): stop quietly, as Unix tools do. Python
    would otherwise report the broken pipe again when it flushes stdout at exit, so stdout is pointed at devnull
    (the recipe of the Python documentation, "Note on SIGPIPE")."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    from ..model import set_max_expression

    limit = None if args.max_expression is None else set_max_expression(args.max_expression)
    try:
        status = args.run(args)
        sys.stdout.flush()   # a reader that went away shows here, inside the handler below
        return status
    except BrokenPipeError:
        return _closed_pipe()
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
    finally:
        if limit is not None:   # main() may run again in the same process (tests, notebooks)
            set_max_expression(limit)
