"""``nlobs analyze``: structural observability and identifiability of a model file."""

from __future__ import annotations

import argparse
import json
from typing import Any

from ..references import cite
from ._common import clean


def add_parser(sub: Any) -> None:
    a = sub.add_parser("analyze", help=f"structural observability of a model file (generic rank, {cite('002')})")
    a.add_argument("model", help="model file (TOML)")
    a.add_argument("--params", default="", metavar="NAMES",
                   help="comma-separated parameters to treat as unknown constants (identifiability), or 'all'")
    a.add_argument("--inputs", default="generic", metavar="CLASS",
                   help=f"'generic' (default: the observation space of {cite('002')}), 'constant', or a polynomial degree")
    a.add_argument("--function", action="append", default=[], metavar="EXPR",
                   help="a function of the states to test for observability (repeatable), e.g. 'x1**2 + x2**2'")
    a.add_argument("--global", dest="global_check", action="store_true",
                   help=f"also decide global observability/identifiability ({cite('hong2019')}): globally, locally only "
                        "(with the number of solutions) or not")
    a.add_argument("--identifiable-functions", action="store_true",
                   help="also list generators of the identifiable (observable) functions, simplest first")
    a.add_argument("--experiments", type=int, default=None, metavar="N",
                   help="also analyse N experiments sharing the parameters (own initial states and inputs) and "
                        "count how many experiments are needed")
    a.add_argument("--engine", default="auto", choices=["auto", "msolve", "singular", "sympy"],
                   help="Gröbner engine of the global parts (default: msolve, else Singular)")
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
    report = analyze(mf.system, unknown_params=unknown, inputs=inputs, functions=args.function, seed=args.seed,
                     global_check=args.global_check, identifiable_functions=args.identifiable_functions,
                     experiments=args.experiments, engine=args.engine)
    print(json.dumps(clean(report.to_dict())) if args.json else report)
    return 0
