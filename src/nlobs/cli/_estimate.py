"""``nlobs estimate``: observers of a model file on recorded data (CSV)."""

from __future__ import annotations

import argparse
import dataclasses
import json
from typing import Any

from ._common import (HELP_ENGINE, failed_status, HELP_HOLD, clean, designs_of, parse_columns, parse_matrix, parse_vector,
                      positive_float)


def add_parser(sub: Any) -> None:
    e = sub.add_parser("estimate", help="run an observer on recorded data (CSV with t, outputs, inputs)",
                       description="Run observers configured in a model file on a recording. Without true states in "
                                   "the file, the report shows what the data can tell: the innovations (each sample "
                                   "against the output predicted before it) and whether they are white.")
    e.add_argument("model", help="model file (TOML)")
    e.add_argument("data", help="CSV whose header names t, the outputs and the inputs (and optionally the states); "
                                "other columns are ignored")
    e.add_argument("--observer", action="append", metavar="NAME", required=True,
                   help="observer configured in the file (repeatable)")
    e.add_argument("--column", action="append", metavar="CSV=MODEL",
                   help="map a CSV column to a model name, e.g. 'time=t' or 'level_2=y' (repeatable, or comma-separated)")
    e.add_argument("--xhat0", metavar="VALUES",
                   help="initial estimate, '0.1,2' or 'x1=0.1,x2=2' (named: the others keep the observer's own)")
    e.add_argument("--P0", metavar="MATRIX",
                   help="initial covariance of covariance-carrying observers (ekf, ukf, kalman_bucy, ...): one number "
                        "(times the identity), one number per state (the diagonal) or a JSON matrix '[[..], [..]]'")
    e.add_argument("--smooth", action="store_true",
                   help="smooth the whole recording after filtering it (fixed-interval Rauch-Tung-Striebel smoother; "
                        "unscented for ukf and srukf): estimates use the samples after them too; the CSV holds the smoothed "
                        "values. For the continuous-discrete ekf and ukf, and on a discrete-time model for its ekf, srekf, iekf, "
                        "ukf and srukf")
    e.add_argument("--skip-missing", action="store_true", help="leave empty/NaN output samples out of the update")
    e.add_argument("--hold", choices=("zoh", "linear"), default="zoh", help=HELP_HOLD)
    e.add_argument("--max-step", type=positive_float, metavar="SECONDS",
                   help="largest integration step between samples (default: one step per sample interval)")
    e.add_argument("--engine", choices=("auto", "vm", "c"), default="auto", help=HELP_ENGINE)
    e.add_argument("--output", metavar="FILE",
                   help="write t, the inputs, the outputs, the states (when recorded) and each observer's estimate "
                        "(NAME.STATE) to this CSV")
    e.add_argument("--plot", metavar="FILE",
                   help="save the estimates (filtered and, with --smooth, smoothed; the true states when the recording "
                        "has them) to FILE (png/pdf/svg)")
    e.add_argument("--json", action="store_true", help="print one JSON object")
    e.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..model import load_model
    from ..estimation import Recording, estimate

    mf = load_model(args.model)
    system = mf.system
    estimated = mf.observer_system  # the states and the unknown parameters the observers estimate
    overrides = {} if args.P0 is None else {"P0": parse_matrix(args.P0, estimated.n_states, "--P0")}
    designs = designs_of(mf, args.observer, overrides=overrides)
    xhat0 = None
    if args.xhat0 is not None:
        xhat0 = {n: parse_vector(args.xhat0, estimated.states, "--xhat0", d.xhat0) for n, d in designs.items()}
    rec = Recording.from_csv(args.data, system, columns=parse_columns(args.column))
    if mf.unknown_params and rec.x is not None:   # a CSV that `simulate --output` wrote also has the parameters' truth
        with_params = Recording.from_csv(args.data, estimated, columns=parse_columns(args.column))
        rec = with_params if with_params.x is not None else rec
    run_ = estimate(designs, rec, xhat0=xhat0, on_missing="skip" if args.skip_missing else "error", hold=args.hold,
                    max_step=args.max_step, engine=args.engine, progress=not args.json, smooth=args.smooth,
                    delay=dict(mf.simulation.delay) or None)
    if mf.units:   # the file's [units] label the plot's axes, as simulate's
        run_ = dataclasses.replace(run_, info={**run_.info, "units": dict(mf.units)})
    if args.output:
        run_.to_csv(args.output)
    if args.plot:
        run_.plot(args.plot, title=f"{system.name} on {args.data}")
    if args.json:
        print(json.dumps(clean(run_.summary_dict())))
    else:
        print(run_.summary())
        for name, tr in run_.observers.items():
            if tr.smoothed:
                print(f"{name}: smoothed (fixed-interval RTS{', unscented' if tr.method in ('ukf', 'srukf') else ''}); "
                      "the estimates below and in the CSV are the smoothed ones")
            print(f"{name}: final estimate " + ", ".join(f"{s}={v:.6g}" for s, v in zip(run_.state_names, tr.xhat[-1])))
        if args.output:
            print(f"estimates: {args.output}")
        if args.plot:
            print(f"plot: {args.plot}")
    return failed_status(run_)
