"""``nlobs demo``: the papers' examples, an HTML report and a summary table."""

from __future__ import annotations

import argparse
from typing import Any


def add_parser(sub: Any) -> None:
    d = sub.add_parser("demo", help="reproduce the papers' examples; write an HTML report and print a summary table",
                       description="Run the examples of the papers nlobs implements, check their claims with numbers, "
                                   "write a self-contained HTML report (plots, maths, the references) and print a summary.")
    d.add_argument("--out", default="nlobs-report", metavar="DIR", help="report folder (default: nlobs-report)")
    d.add_argument("--only", action="append", metavar="KEY", help="run only this example (repeatable); keys from --list")
    d.add_argument("--list", action="store_true", help="list the examples' keys and titles, and exit")
    d.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    d.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..examples import EXAMPLES
    from ..report import plain, run_demo

    if args.list:
        examples = sorted(EXAMPLES.values(), key=lambda e: e.order)
        width = max(len(e.key) for e in examples)
        for ex in examples:
            print(f"{ex.key:<{width}}  {plain(ex.title)}")
        return 0
    return run_demo(args.out, only=args.only, progress=not args.quiet).exit_code
