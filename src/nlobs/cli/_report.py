"""``nlobs report``: the HTML report of a model — verdicts, every observer kind, the runs side by side."""

from __future__ import annotations

import argparse
import json
from typing import Any


def add_parser(sub: Any) -> None:
    r = sub.add_parser("report", help="HTML report of a model: observability, observer kinds (applies / why), runs and plots",
                       description="Runs `nlobs design --run` on the model (on its [simulation], or on DATA.csv) and writes a "
                                   "self-contained HTML report: observability verdicts, the table of observer kinds, the "
                                   "candidates' runs side by side with plots, and the parameter estimates.")
    r.add_argument("model", help="model file (TOML) or a bundled model name (nlobs models)")
    r.add_argument("data", nargs="?", help="a recording (CSV with t, the outputs and the inputs) to run on instead of the simulation")
    r.add_argument("--out", default="nlobs-report", metavar="DIR", help="output folder (default: nlobs-report)")
    r.add_argument("--kind", action="append", metavar="KIND", help="only this observer kind (repeatable)")
    r.add_argument("--params", default=None, metavar="NAMES", help="comma-separated parameters to estimate with the states")
    r.add_argument("--no-run", action="store_true", help="verdicts and candidates only, no comparison run")
    r.add_argument("--sensors", action="store_true",
                   help="add the section 'What to measure' (nlobs sensors) with the default pool of candidates; it is "
                        "added without this flag when the file has [sensors.NAME] tables")
    r.add_argument("--json", action="store_true", help="print one JSON object (the report's path and the ranking)")
    r.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..advise import advise
    from ..model import load_model
    from ..report import write_model_report
    from ..estimation import Recording

    mf = load_model(args.model)
    unknown = [p.strip() for p in args.params.split(",") if p.strip()] if args.params is not None else None
    recording = None
    if args.data:
        system = mf.system.augmented(unknown) if unknown else mf.system
        recording = Recording.from_csv(args.data, system)
    from ..advise._advice import WHAT_TO_TRY

    adv = advise(mf, unknown_params=unknown, recording=recording, kinds=args.kind, run=not args.no_run,
                 progress=not args.json)
    sensors = None
    if args.sensors or mf.sensors:
        from ..analysis import select_sensors

        sensors = select_sensors(mf, unknown_params=unknown)
    path = write_model_report(adv, args.out, source=mf.path + (f" with {args.data}" if args.data else ""), sensors=sensors)
    if args.json:
        best = adv.best
        out = {"report": str(path.resolve()), "ranking": list(adv.ranking or ()), "best": None if best is None else best.kind,
               "applies": [c.kind for c in adv.applicable]}
        if best is None and adv.ranking:
            out["none_converged"] = "no observer converged on the run: none is recommended; " + WHAT_TO_TRY
        print(json.dumps(out))
    else:
        best = adv.best
        print(f"{len(adv.applicable)} of {len(adv.candidates)} observer kinds apply"
              + (f"; best on the run: {best.kind}" if best is not None else
                 "; on the run NONE converged (none is recommended): try " + WHAT_TO_TRY if adv.ranking else ""))
        print(f"report: {path.resolve()}")
    return 0
