"""``nlobs design``: which observers fit a model, why the others do not, and (``--run``) which works best."""

from __future__ import annotations

import argparse
import json
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

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
    d.add_argument("--no-tune", dest="tune", action="store_false",
                   help="with --run: keep the default Q and R of the Kalman-family candidates (by default they are tuned "
                        "on the run's measurements by the innovations likelihood before the ranking, as `nlobs tune` does)")
    d.add_argument("--toml", action="store_true", help="print the applicable designs as [observers.NAME] tables to paste in the file")
    d.add_argument("--json", action="store_true", help="print one JSON object")
    d.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..advise import advise
    from ..model import load_model
    from ..estimation import Recording

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
                 budget=args.budget if args.budget is not None else BUDGET, tune=args.tune)
    if args.json:
        print(json.dumps(clean(adv.to_dict())))
    elif args.toml:
        print(to_toml(adv, existing=mf.observers))
    else:
        print(adv)
    return 0


#: A number is written exactly (Python's shortest repr, which reads back bit for bit), unless a number of at most 12
#: significant digits lies within :data:`ULPS` units in the last place of it: then it was that short number with the
#: rounding noise of a computation in its last bits (0.0025000000000000005, σ² of 0.05; 2.2499999999999996e-08), and
#: is written short (0.0025). Every other value keeps all its digits (0.3333333333333333, a learned map's region
#: 129.99324999999664): a sigma-point weight at exactly 0, a least-squares fit to simulated data read it back as the
#: same observer.
ULPS = 4

_BARE = set("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")


def _toml_key(k: Any) -> str:
    k = str(k)
    return k if k and set(k) <= _BARE else json.dumps(k, ensure_ascii=False)


def _toml_number(v: float) -> str:
    """A float as TOML (see :data:`ULPS`); TOML's own inf, -inf and nan for the non-finite."""
    if np.isnan(v):
        return "nan"
    if np.isinf(v):
        return "inf" if v > 0 else "-inf"
    text = repr(float(v))
    for digits in range(1, 13):
        short = float(f"{v:.{digits}g}")
        if abs(short - v) <= ULPS * np.spacing(abs(v)):
            text = repr(short)
            break
    return text if any(c in text for c in ".eEn") else text + ".0"


def _toml_value(v: Any, key: str = "") -> str:
    """One option's value as TOML. TOML has no null: a side of a bound without a limit (None) is written as TOML's
    -inf (lower) or inf (upper), which the designs read as "no bound"."""
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return _toml_number(float(v))
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, Mapping):
        if key == "bounds":   # {state: (lo, hi)}: None is no bound on that side
            v = {k: [-np.inf if pair[0] is None else pair[0], np.inf if pair[1] is None else pair[1]]
                 if isinstance(pair, (list, tuple)) and len(pair) == 2 else pair for k, pair in v.items()}
        items = [(k, x) for k, x in v.items() if x is not None]
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x, str(k))}" for k, x in items) + " }"
    if isinstance(v, (list, tuple)):
        if any(x is None for x in v):
            raise ValueError(f"option `{key}` has an empty entry (None), which TOML cannot write: {v!r}")
        return "[" + ", ".join(_toml_value(x, key) for x in v) + "]"
    if isinstance(v, complex):
        return _toml_value([v.real, v.imag], key)
    return json.dumps(str(v), ensure_ascii=False)


def to_toml(adv: Any, existing: Any = ()) -> str:
    """The applicable candidates as ``[observers.NAME]`` tables (kind + the options the design was made with), written so
    that the file they are pasted into loads and designs the same observers (numbers to :data:`DIGITS` significant
    digits; no bound on a side: ±inf).

    `existing` are the observer names the file already has: a table is named after its kind unless the file has that
    name (then ``KIND_design``), and a candidate designed from one of the file's own tables is not repeated."""
    taken = set(existing)
    out = [f"# observers for {adv.model!r} found by `nlobs design` (paste into the model file)"]
    for c in adv.applicable:
        own = re.match(r"designed from the file's \[observers\.([^\]]+)\]", c.why)   # advise._kinds._from_file
        if own:
            out.append(f"\n# {c.kind}: designed from the file's own [observers.{own.group(1)}], not repeated")
            continue
        name, k = c.kind, 1
        while name in taken:
            name = f"{c.kind}_design" + (str(k) if k > 1 else "")
            k += 1
        taken.add(name)
        out.append(f"\n[observers.{name}]\nkind = \"{c.kind}\"")
        for key, v in c.options.items():
            if v is None:     # an option left at its default
                continue
            out.append(f"{_toml_key(key)} = {_toml_value(v, key)}")
    return "\n".join(out)
