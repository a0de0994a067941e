"""``nlobs analyze``: structural observability and identifiability of a model file."""

from __future__ import annotations

import argparse
import json
from typing import Any

from ..references import cite
from ._common import clean


def add_parser(sub: Any) -> None:
    a = sub.add_parser("analyze", help="is the model observable? (generic rank of the observation space)",
                       description="Structural observability and identifiability of a model file: the generic rank of the "
                                   f"Jacobian of the output and its time derivatives ({cite('002')}), computed by truncated "
                                   f"power series modulo a prime ({cite('sedoglavic2002')}); unobservable directions, "
                                   "sign symmetries, and functions of the states you ask about.")
    a.add_argument("model", help="model file (TOML)")
    a.add_argument("--params", default="", metavar="NAMES",
                   help="comma-separated parameters to treat as unknown constants (identifiability), or 'all'")
    a.add_argument("--inputs", default="generic", metavar="CLASS",
                   help="the inputs the verdict covers: 'generic' (default: any smooth input), 'constant', or N "
                        "(polynomials of degree N)")
    a.add_argument("--function", action="append", default=[], metavar="EXPR",
                   help="a function of the states to test for observability (repeatable), e.g. 'x1**2 + x2**2'")
    a.add_argument("--seed", type=int, default=0, help="seed of the random point and prime (default 0)")
    a.add_argument("--json", action="store_true", help="print one JSON object")
    a.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..analysis import analyze
    from ..model import load_model

    mf = load_model(args.model)
    params = args.params.strip()
    unknown: Any = "all" if params == "all" else [p.strip() for p in params.split(",") if p.strip()]
    inputs: Any = int(args.inputs) if args.inputs.strip().isdigit() else args.inputs.strip()
    report = analyze(mf.system, unknown_params=unknown, inputs=inputs, functions=args.function, seed=args.seed)
    print(json.dumps(clean(report.to_dict())) if args.json else report)
    return 0
