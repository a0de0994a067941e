"""``nlobs export``: an observer's sample-to-sample step as dependency-free C."""

from __future__ import annotations

import argparse
from typing import Any

from ._common import designs_of, parse_assignments, positive_float, positive_int


def add_parser(sub: Any) -> None:
    x = sub.add_parser("export", help="write an observer's sample-to-sample step as dependency-free C",
                       description="Write NAME.c and NAME.h (the observer's step from one sample to the next, C99, only "
                                   "<math.h>, no allocation) and an example main.c that reads t,u...,y... lines from stdin. "
                                   "With measurement delays (the model file's [simulation] delay, or --delay) the C also "
                                   "holds a fusion filter for rows stamped at arrival, and main.c runs it.")
    x.add_argument("model", help="model file (TOML)")
    x.add_argument("--observer", required=True, metavar="NAME", help="observer configured in the file")
    x.add_argument("--c", required=True, metavar="DIR", dest="c_dir", help="folder for NAME.c, NAME.h and an example main.c")
    x.add_argument("--name", help="C prefix and file name (default: MODEL_KIND)")
    x.add_argument("--max-step", type=float, help="largest RK4 step between samples (default: one step per interval)")
    x.add_argument("--delay", action="append", metavar="OUTPUT=SECONDS",
                   help="known measurement delay of an output (repeatable, or comma-separated): the rows are stamped at "
                        "arrival and a delayed value was taken SECONDS earlier. Default: the model file's [simulation] "
                        "delay (--delay replaces it; outputs not named have none). Writes the fusion filter "
                        "NAME_fusion_step")
    x.add_argument("--no-delay", action="store_true", help="ignore the model file's [simulation] delay (no fusion filter)")
    x.add_argument("--min-interval", type=positive_float, metavar="SECONDS",
                   help="with delays: the smallest spacing of the rows the program will read, which sizes the delay "
                        "history (default: the model file's [simulation] dt)")
    x.add_argument("--history", type=positive_int, metavar="KNOTS",
                   help="with delays: the number of knots the delay history holds, instead of --min-interval")
    x.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..model import load_model
    from ..observer import export_c

    mf = load_model(args.model)
    design = designs_of(mf, [args.observer])[args.observer]
    outputs = list(design.system.outputs)
    if args.delay and args.no_delay:
        raise ValueError("--delay and --no-delay: give one of them")
    if args.delay:
        delays = {o: 0.0 for o in outputs} | parse_assignments(args.delay, outputs, "--delay")
        bad = [k for k, v in delays.items() if v < 0]
        if bad:
            raise ValueError(f"--delay {bad[0]}: a delay must be >= 0 seconds, got {delays[bad[0]]:g}")
    elif mf.simulation.delay and not args.no_delay:
        delays = {o: float(mf.simulation.delay.get(o, 0.0)) for o in outputs}
    else:
        delays = None
    min_interval, history = args.min_interval, args.history
    if delays is None:
        if min_interval is not None or history is not None:
            raise ValueError("--min-interval and --history size the delay history; give them with --delay (or a model "
                             "file with a [simulation] delay)")
    elif min_interval is None and history is None and any(v > 0 for v in delays.values()):
        min_interval = mf.simulation.dt
        if min_interval is None:
            raise ValueError(f"{args.model}: with measurement delays, give --min-interval SECONDS (the smallest spacing of "
                             "the rows the program will read) or --history KNOTS; the file's [simulation] has no dt to "
                             "take it from")
    print(export_c(design, args.c_dir, name=args.name, max_step=args.max_step, delays=delays, min_interval=min_interval,
                   history=history))
    return 0
