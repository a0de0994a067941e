"""``nlobs tune``: the noise covariances Q, R (and P0) of a Kalman-family observer from a recording."""

from __future__ import annotations

import argparse
import json
from typing import Any

from ._common import HELP_ENGINE, clean, designs_of, parse_columns, positive_float, positive_int


def add_parser(sub: Any) -> None:
    t = sub.add_parser("tune", help="tune an observer's Q, R (and P0) on a recording (innovations likelihood)",
                       description="Estimate the diagonal process noise Q (one variance per state, unknown parameters "
                                   "included), the measurement noise R (one per output) and optionally P(0) of an ekf, ukf, "
                                   "srekf, srukf, iekf or pf by maximising the filter's innovations likelihood on the "
                                   "recording (Schweppe 1965), or with --truth by minimising its RMS state error. Prints "
                                   "each variance with its standard error, the NIS consistency check and the "
                                   "log-likelihood; --toml prints an [observers.NAME] table to paste into the model file.")
    t.add_argument("model", help="model file (TOML)")
    t.add_argument("data", help="CSV whose header names t, the outputs and the inputs")
    t.add_argument("--observer", required=True, metavar="NAME|KIND",
                   help="an observer configured in the file, or a kind (ekf, ukf, srekf, srukf, iekf, pf) designed with "
                        "the advisor's automatic tuning; its Q, R, P0 are the start and the reference scales")
    t.add_argument("--fix-r", action="store_true", help="keep the observer's R (tune Q only)")
    t.add_argument("--p0", action="store_true", help="also tune diag P(0)")
    t.add_argument("--truth", metavar="CSV",
                   help="reference trajectory (t and state columns, e.g. motion capture): minimise the filter's RMS state "
                        "error against it instead of maximising the likelihood")
    t.add_argument("--starts", type=positive_int, default=3, metavar="N", help="most starts (default 3)")
    t.add_argument("--max-iter", type=positive_int, default=200, metavar="N",
                   help="most L-BFGS-B iterations per start (default 200)")
    t.add_argument("--name", metavar="NAME", help="name of the [observers.NAME] table printed by --toml (default KIND_tuned)")
    t.add_argument("--column", action="append", metavar="CSV=MODEL", help="map a CSV column to a model name (repeatable)")
    t.add_argument("--skip-missing", action="store_true", help="leave empty/NaN output samples out of the likelihood")
    t.add_argument("--max-step", type=positive_float, metavar="SECONDS",
                   help="largest integration step between samples (default: the filter's own rule)")
    t.add_argument("--engine", choices=("auto", "vm", "c"), default="auto", help=HELP_ENGINE)
    t.add_argument("--json", action="store_true", help="print one JSON object")
    t.add_argument("--toml", action="store_true", help="print only the [observers.NAME] table with the tuned values")
    t.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..model import load_model
    from ..learning import tune
    from ..estimation import Recording

    if args.json and args.toml:
        raise ValueError("--json and --toml: choose one output")
    mf = load_model(args.model)
    design = designs_of(mf, [args.observer])[args.observer]
    rec = Recording.from_csv(args.data, mf.system, columns=parse_columns(args.column))
    res = tune(design, rec, fix_r=args.fix_r, tune_p0=args.p0, truth=args.truth, starts=args.starts,
               max_iter=args.max_iter, delay=dict(mf.simulation.delay) or None,
               on_missing="skip" if args.skip_missing else "error", max_step=args.max_step, engine=args.engine,
               progress=not (args.json or args.toml))
    if args.toml:
        print(res.toml(args.name), end="")
        if not res.converged:
            print(f"# NOT converged: {res.message}")
    elif args.json:
        print(json.dumps(clean({"model": mf.system.name, "data": args.data, "observer": args.observer, **res.to_dict()})))
    else:
        print(res.summary())
    return 0 if res.converged else 1
