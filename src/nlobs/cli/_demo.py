"""``nlobs demo``: the papers' examples, an HTML report and a summary table."""

from __future__ import annotations

import argparse
from typing import Any


def add_parser(sub: Any) -> None:
    d = sub.add_parser("demo", help="reproduce the papers' examples; write an HTML report")
    d.add_argument("--out", default="nlobs-report", help="report folder (default: nlobs-report)")
    d.add_argument("--only", action="append", metavar="KEY", help="run only this example (repeatable); see --list")
    d.add_argument("--list", action="store_true", help="list the examples and exit")
    d.add_argument("--quiet", action="store_true", help="no progress lines")
    d.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..examples import EXAMPLES
    from ..report import run_demo

    if args.list:
        for ex in sorted(EXAMPLES.values(), key=lambda e: e.order):
            print(f"{ex.key:<16} {ex.title}")
        return 0
    return run_demo(args.out, only=args.only, progress=not args.quiet).exit_code
