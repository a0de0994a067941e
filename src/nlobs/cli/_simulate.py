"""``nlobs simulate``: a model file's plant with its observers, on its ``[simulation]`` table."""

from __future__ import annotations

import argparse
import json
from typing import Any

from ._common import clean, designs_of


def add_parser(sub: Any) -> None:
    s = sub.add_parser("simulate", help="simulate a model file's plant with its observers")
    s.add_argument("model", help="model file (TOML)")
    s.add_argument("--observer", action="append", metavar="NAME", help="observer configured in the file (repeatable; default: all)")
    s.add_argument("--t-final", type=float, help="horizon (default: the file's [simulation] t_final)")
    s.add_argument("--dt", type=float, help="integration step (default: the file's, else 1e-3)")
    s.add_argument("--seed", type=int, help="noise seed (default: the file's)")
    s.add_argument("--engine", choices=("auto", "vm", "c"), default="auto", help="numeric backend")
    s.add_argument("--tol", type=float, help="convergence tolerance (default: 2%% of the initial error)")
    s.add_argument("--plot", metavar="FILE", help="save states vs estimates and error norms to FILE (png/pdf/svg)")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..model import load_model
    from ..simulate import simulate

    mf = load_model(args.model)
    # the file's [simulation] defaults, plant (true_parameters) and observers; unknown parameters are
    # checked for identifiability (also with the file's inputs) before anything runs
    run_ = simulate(mf, designs_of(mf, args.observer), t_final=args.t_final, dt=args.dt, seed=args.seed,
                    engine=args.engine, progress=not args.json)
    if args.plot:
        run_.plot(args.plot)
    if args.json:
        print(json.dumps(clean(run_.summary_dict(tol=args.tol))))
    else:
        print(run_.summary(tol=args.tol))
        if args.plot:
            print(f"plot: {args.plot}")
    return 0
