"""``nlobs design``: which observers fit a model, why the others do not, and (``--run``) which works best."""

from __future__ import annotations

import argparse
import json
from typing import Any

from ._common import clean, positive_float


def add_parser(sub: Any) -> None:
    d = sub.add_parser("design", help="try every observer kind on a model: applies or why not, the tuning, and a ranking (--run)",
                       description="Runs the observability analysis and the form recognition, then tries every observer kind "
                                   "with an automatic tuning from the model's time scales, the region its [simulation] visits "
                                   "and the declared noise. Each kind: applies (with its design and certificate), fails (the "
                                   "failed condition with its numbers), or needs input you must supply.")
    d.add_argument("model", help="model file (TOML) or a bundled model name (nlobs models)")
    d.add_argument("--run", dest="compare", action="store_true", help="simulate every applicable design on the file's [simulation] and rank them")
    d.add_argument("--data", metavar="CSV", help="rank on this recording (t, outputs, inputs) instead of the simulation")
    d.add_argument("--kind", action="append", metavar="KIND", help="try only this kind (repeatable)")
    d.add_argument("--params", default=None, metavar="NAMES",
                   help="comma-separated parameters to estimate with the states (default: those marked unknown in the file)")
    d.add_argument("--xhat0", default=None, metavar="V1,V2,...", help="initial estimate shared by every candidate")
    d.add_argument("--engine", choices=("auto", "vm", "c"), default="auto", help="numeric backend of the run")
    d.add_argument("--budget", type=positive_float, default=None, metavar="SECONDS",
                   help="seconds each candidate may take in --run, compiling included (default 120); one that takes "
                        "longer is reported as 'did not finish' and the others keep their results")
    d.add_argument("--toml", action="store_true", help="print the applicable designs as [observers.NAME] tables to paste in the file")
    d.add_argument("--json", action="store_true", help="print one JSON object")
    d.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..advise import advise
    from ..model import load_model
    from ..simulate import Recording

    mf = load_model(args.model)
    unknown = None
    if args.params is not None:
        unknown = [p.strip() for p in args.params.split(",") if p.strip()]
    recording = None
    if args.data:
        system = mf.system.augmented(unknown) if unknown else mf.system
        recording = Recording.from_csv(args.data, system)
    xhat0 = None
    if args.xhat0:
        try:
            xhat0 = [float(v) for v in args.xhat0.split(",")]
        except ValueError:
            raise ValueError(f"--xhat0 must be comma-separated numbers, got {args.xhat0!r}") from None
    from ..advise._advise import BUDGET

    adv = advise(mf, unknown_params=unknown, recording=recording, kinds=args.kind, run=args.compare or bool(args.data),
                 xhat0=xhat0, progress=not args.json, engine=args.engine,
                 budget=args.budget if args.budget is not None else BUDGET)
    if args.json:
        print(json.dumps(clean(adv.to_dict())))
    elif args.toml:
        print(to_toml(adv))
    else:
        print(adv)
    return 0


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return json.dumps(str(v))


def to_toml(adv: Any) -> str:
    """The applicable candidates as ``[observers.KIND]`` tables (kind + the options the design was made with)."""
    from ..advise._advice import jsonable

    out = [f"# observers for {adv.model!r} found by `nlobs design` (paste into the model file)"]
    for c in adv.applicable:
        out.append(f"\n[observers.{c.kind}]\nkind = \"{c.kind}\"")
        for k, v in jsonable(c.options).items():
            out.append(f"{k} = {_toml_value(v)}")
    return "\n".join(out)
