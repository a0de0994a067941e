"""``nlobs sensors``: what should I measure? The minimal sets of candidate sensors that make the model observable (exact
generic rank), and the Cramér–Rao bounds each set allows on the file's ``[simulation]`` run, ranked under a budget.

The candidates are the file's ``[sensors.NAME]`` tables (expr, noise, optional cost), else every state and every
output. ``--run`` also runs a smoothed extended Kalman filter with each listed set on the run (simulate layer:
:func:`nlobs.estimation.sensor_errors`) and shows the error of its x̂(0) beside each bound.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from ..references import cite
from ._common import clean, positive_float, positive_int


def add_parser(sub: Any) -> None:
    a = sub.add_parser("sensors", help="what should I measure? minimal sensor sets and their Cramér–Rao bounds",
                       description="Sensor selection on a model file: every inclusion-minimal set of candidate sensors "
                                   "([sensors.NAME] tables with expr, noise and cost; default: every state and output) that "
                                   "makes the states and unknown parameters locally observable, by the exact generic rank "
                                   f"of `nlobs analyze` ({cite('sedoglavic2002')}), pruned by the sink components of the "
                                   f"influence graph ({cite('liu2013')}); then, on the file's [simulation] run, the "
                                   "Cramér–Rao bound of each initial value per set, the unobservability index "
                                   f"({cite('krener2009')}), the best set under --budget by log det of the Fisher "
                                   "information and the cost–quality Pareto front.")
    a.add_argument("model", help="model file (TOML) or a bundled model name (nlobs models)")
    a.add_argument("--target", default=None, metavar="NAMES",
                   help="comma-separated states and unknown parameters to observe (default: all of them)")
    a.add_argument("--budget", type=positive_float, default=None, metavar="COST",
                   help="most total cost of the best set (default: no limit)")
    a.add_argument("--params", default=None, metavar="NAMES",
                   help="comma-separated parameters to treat as unknown, or 'all' (default: the file's unknown = true)")
    a.add_argument("--inputs", default="generic", metavar="CLASS",
                   help="the inputs the structural verdict covers: 'generic' (default), 'constant', or N (polynomials of "
                        "degree N)")
    a.add_argument("--no-bounds", action="store_true", help="the structural part only (no run)")
    a.add_argument("--run", dest="filter_run", action="store_true",
                   help="also run a smoothed EKF with each listed set on the [simulation] run (noise draws with each "
                        "sensor's σ) and show the RMS error of its x̂(0) beside the bounds")
    a.add_argument("--draws", type=positive_int, default=20, metavar="N",
                   help="noise draws per set with --run (default 20; the RMS of N draws is uncertain by about 1/√(2N))")
    a.add_argument("--plot", default=None, metavar="FILE",
                   help="save the bounds per state and set as a picture (PNG, SVG or PDF by the extension)")
    a.add_argument("--engine", default="auto", choices=["auto", "vm", "c"],
                   help="where the run's sensitivities are computed (default: auto)")
    a.add_argument("--seed", type=int, default=0, help="seed of the random points and primes (default 0)")
    a.add_argument("--json", action="store_true", help="print one JSON object")
    a.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..analysis import select_sensors
    from ..model import load_model
    from ._analyze import unknown_params_of

    mf = load_model(args.model)
    inputs: Any = int(args.inputs) if args.inputs.strip().isdigit() else args.inputs.strip()
    sel = select_sensors(mf, targets=args.target, budget=args.budget, unknown_params=unknown_params_of(mf, args.params),
                         inputs=inputs, quality_part=not args.no_bounds, seed=args.seed, engine=args.engine)
    errors = None
    if args.filter_run:
        if sel.run is None:
            raise ValueError(f"--run: {mf.path} has no [simulation] x0 to run (or --no-bounds was given)")
        from ..estimation import sensor_errors

        errors = sensor_errors(mf, sel, seeds=args.draws, engine=args.engine)
    if args.plot:
        from ..report._sensors import sensors_figure

        sensors_figure(sel, errors=errors.rms if errors is not None else None).savefig(args.plot, dpi=150)
    if args.json:
        out = sel.to_dict()
        if errors is not None:
            out["filter"] = errors.to_dict()
        if args.plot:
            out["plot"] = args.plot
        print(json.dumps(clean(out)))
        return 0
    print(sel)
    if errors is not None:
        print(errors)
    if args.plot:
        print(f"plot: {args.plot}")
    return 0
