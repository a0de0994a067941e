"""``nlobs estimate``: observers of a model file on recorded data (CSV)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from ._common import clean, designs_of


def add_parser(sub: Any) -> None:
    e = sub.add_parser("estimate", help="run an observer on recorded data (CSV with t, outputs, inputs)")
    e.add_argument("model", help="model file (TOML)")
    e.add_argument("data", help="CSV whose header names t, the outputs and the inputs (and optionally the states)")
    e.add_argument("--observer", action="append", metavar="NAME", required=True, help="observer configured in the file")
    e.add_argument("--skip-missing", action="store_true", help="leave empty/NaN output samples out of the update")
    e.add_argument("--hold", choices=("zoh", "linear"), default="zoh", help="measurement hold between samples")
    e.add_argument("--max-step", type=float, help="largest integration step between samples")
    e.add_argument("--engine", choices=("auto", "vm", "c"), default="auto", help="numeric backend")
    e.add_argument("--output", metavar="FILE", help="write t and the estimates to this CSV")
    e.add_argument("--json", action="store_true", help="print one JSON object")
    e.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..model import load_model
    from ..simulate import Recording, estimate

    mf = load_model(args.model)
    rec = Recording.from_csv(args.data, mf.system)
    run_ = estimate(designs_of(mf, args.observer), rec, on_missing="skip" if args.skip_missing else "error", hold=args.hold,
                    max_step=args.max_step, engine=args.engine)
    if args.output:
        import numpy as np

        cols = ["t"] + [f"{name}.{s}" for name in run_.observers for s in run_.state_names]
        data = np.column_stack([run_.t] + [tr.xhat for tr in run_.observers.values()])
        np.savetxt(args.output, data, delimiter=",", header=",".join(cols), comments="")
    if args.json:
        print(json.dumps(clean(run_.summary_dict())))
    else:
        print(run_.summary())
        for name, tr in run_.observers.items():
            print(f"{name}: final estimate " + ", ".join(f"{s}={v:.6g}" for s, v in zip(run_.state_names, tr.xhat[-1])))
    return 0
