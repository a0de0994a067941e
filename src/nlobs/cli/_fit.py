"""``nlobs fit``: unknown parameters of a model file from a recording, by simulation-error least squares or by the
innovations likelihood of an EKF/UKF."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from ._common import HELP_HOLD, clean, parse_assignments, parse_columns, parse_vector, positive_float


def add_parser(sub: Any) -> None:
    f = sub.add_parser("fit", help="fit unknown parameters to a recording (simulation-error least squares, or an EKF/UKF likelihood)",
                       description="Fit unknown parameters (and initial states) of a model file to a recording: the model "
                                   "is simulated over the whole recording, driven by its input, and the unknowns minimise "
                                   "the output error (a batch alternative to estimating them with an observer). Prints the "
                                   "estimates with standard errors from the Jacobian at the optimum.")
    f.add_argument("model", help="model file (TOML)")
    f.add_argument("data", help="CSV whose header names t, the outputs and the inputs")
    f.add_argument("--param", action="append", metavar="NAME", required=True,
                   help="an unknown parameter (repeatable, or comma-separated); its value in the file is the initial guess")
    f.add_argument("--fit-x0", action="append", metavar="STATE", help="a state whose initial value is unknown too (repeatable)")
    f.add_argument("--x0", metavar="VALUES",
                   help="the state at the recording's first time, '1,0' or 'x1=1,x2=0' (default: the file's [simulation] x0)")
    f.add_argument("--initial", action="append", metavar="NAME=VALUE", help="initial guess of an unknown (repeatable)")
    f.add_argument("--bound", action="append", metavar="NAME=LO:HI",
                   help="bounds of an unknown, e.g. 'k=0:' (k ≥ 0) or 'c=0.1:10' (repeatable)")
    f.add_argument("--output-std", action="append", metavar="OUTPUT=STD",
                   help="measurement noise std of an output, to weight it (default: each output scaled by its spread)")
    f.add_argument("--column", action="append", metavar="CSV=MODEL", help="map a CSV column to a model name (repeatable)")
    f.add_argument("--max-step", type=positive_float, metavar="SECONDS",
                   help="largest integration step (default: one RK4 step per sample interval; the report says how much "
                        "halving it changes the outputs)")
    f.add_argument("--hold", choices=("zoh", "linear"), default="zoh", help=HELP_HOLD)
    f.add_argument("--output", metavar="CSV", help="write t, the recorded and the fitted outputs to this CSV (with --method "
                                                  "likelihood: the filter's one-step predictions and their std)")
    f.add_argument("--method", choices=("simulation", "likelihood"), default="simulation",
                   help="'simulation' (default): simulation-error least squares; 'likelihood': maximise the innovations "
                        "likelihood of an EKF or UKF configured in the file (accounts for process noise; can learn Q and R)")
    f.add_argument("--observer", metavar="NAME",
                   help="with --method likelihood: the ekf or ukf observer of the file whose Q, R, P0, xhat0 are used "
                        "(its name, or its kind when the file configures one of that kind)")
    f.add_argument("--learn-noise", action="store_true",
                   help="with --method likelihood: also estimate scalings of Q and R (Q = exp(ρ_Q) Q, R = exp(ρ_R) R), "
                        "named log_Q_scale, log_R_scale in --initial and --bound")
    f.add_argument("--start", choices=("initial", "simulation"), default="initial",
                   help="with --method likelihood: start from the initial guesses (default) or from the simulation-error "
                        "fit (its initial states: --fit-x0, default all); a start that does not converge is followed by "
                        "the simulation-error fit, then perturbed starts (--starts)")
    f.add_argument("--starts", type=int, default=4, metavar="N",
                   help="with --method likelihood: most starts (default 4)")
    f.add_argument("--max-iter", type=int, default=None, metavar="N",
                   help="with --method likelihood: most trust-region iterations per start, over its phases (default 1000, "
                        "nlobs.learning's MAX_ITER)")
    f.add_argument("--smoothing", type=float, default=1.0, metavar="FACTOR",
                   help="with --method likelihood: factor on the widths over which abs/sign/min/max are smoothed for the "
                        "filter (default 1: 1 %% of the range each argument spans on the filter's run at the initial guess; 0: "
                        "exact, and the likelihood jumps where the filter crosses a switch)")
    f.add_argument("--no-censor", action="store_true",
                   help="with --method likelihood: do not read an output saturating at a known limit (min(x, 10)) as "
                        "censored where the recording sits at the limit")
    f.add_argument("--skip-missing", action="store_true",
                   help="with --method likelihood: leave empty/NaN output samples out of the likelihood")
    f.add_argument("--plot", metavar="FILE",
                   help="save the recorded outputs against the fitted model's (--method simulation) or the fitted "
                        "filter's one-step predictions with their ± 2σ band (--method likelihood) to FILE (png/pdf/svg)")
    f.add_argument("--json", action="store_true", help="print one JSON object")
    f.set_defaults(run=run)


def _names(items: list[str] | None) -> list[str]:
    return [p.strip() for item in items or () for p in item.split(",") if p.strip()]


def _bounds(items: list[str] | None) -> dict[str, tuple[float | None, float | None]]:
    out: dict[str, tuple[float | None, float | None]] = {}
    for item in items or ():
        if "=" not in item or ":" not in item.split("=", 1)[1]:
            raise ValueError(f"--bound: expected NAME=LO:HI (either side may be empty), got {item!r}")
        name, rng = (s.strip() for s in item.split("=", 1))
        lo, hi = (s.strip() for s in rng.split(":", 1))
        try:
            out[name] = (float(lo) if lo else None, float(hi) if hi else None)
        except ValueError:
            raise ValueError(f"--bound {name}: {rng!r} is not LO:HI with numbers") from None
    return out


def run(args: argparse.Namespace) -> int:
    from ..model import load_model
    from ..learning import fit_parameters
    from ..estimation import Recording
    from ..simulate._results import write_csv

    mf = load_model(args.model)
    system = mf.system
    rec = Recording.from_csv(args.data, system, columns=parse_columns(args.column))
    if args.method == "likelihood":
        return _likelihood(args, mf, rec)
    for flag, given in (("--observer", args.observer), ("--learn-noise", args.learn_noise),
                        ("--skip-missing", args.skip_missing), ("--start simulation", args.start != "initial"),
                        ("--starts", args.starts != 4), ("--max-iter", args.max_iter is not None), ("--smoothing", args.smoothing != 1.0),
                        ("--no-censor", args.no_censor)):
        if given:
            raise ValueError(f"{flag} is an option of --method likelihood (the simulation-error fit does not use it)")
    params, fit_x0 = _names(args.param), _names(args.fit_x0)
    unknown_names = params + [f"{s}(t0)" for s in fit_x0]
    x0 = None
    if args.x0 is not None:
        x0 = parse_vector(args.x0, system.states, "--x0", mf.simulation.x0)
    elif rec.x is None and mf.simulation.x0 is not None:
        x0 = mf.simulation.x0
    output_std = parse_assignments(args.output_std or [], system.outputs, "--output-std")
    initial = parse_assignments(args.initial or [], unknown_names, "--initial")
    res = fit_parameters(system, rec, params, x0=x0, fit_x0=fit_x0, initial=initial, bounds=_bounds(args.bound),
                         output_std=output_std or None, max_step=args.max_step, hold=args.hold)
    if args.output:
        header = ["t", *(f"{o}" for o in res.output_names), *(f"{o}.fit" for o in res.output_names)]
        write_csv(args.output, header, np.column_stack([res.t, res.y, res.y_fit]))
    if args.plot:
        from ..simulate._plot import plot_outputs

        plot_outputs(res.t, res.y, res.y_fit, list(res.output_names), args.plot, label="simulated, fitted",
                     title=f"{system.name}: simulation-error fit on {Path(args.data).name}")
    if args.json:
        print(json.dumps(clean({"model": system.name, "data": args.data, **res.to_dict()})))
    else:
        print(res.summary())
        if args.output:
            print(f"fitted outputs: {args.output}")
        if args.plot:
            print(f"plot: {args.plot}")
    return 0 if res.success else 1


def _likelihood(args: argparse.Namespace, mf: Any, rec: Any) -> int:
    """``nlobs fit --method likelihood``: the innovations likelihood of a configured EKF/UKF."""
    from ..design import design_from_config
    from ..learning import fit_likelihood
    from ..learning._likelihood import LIKELIHOOD_KINDS

    unused = [flag for flag, given in (("--x0", args.x0), ("--output-std", args.output_std),
                                       ("--fit-x0", args.fit_x0 and args.start != "simulation")) if given] + \
        (["--hold linear"] if args.hold != "zoh" else [])
    if unused:
        raise ValueError(f"{', '.join(unused)}: not used by --method likelihood (the observer's xhat0 and P0 give the "
                         "initial state, its R the measurement noise; inputs are held between samples; --fit-x0 only "
                         "with --start simulation)")
    configured = mf.observers
    usable = {n: c for n, c in configured.items() if c.kind in LIKELIHOOD_KINDS}
    if not args.observer:
        raise ValueError(f"--method likelihood needs --observer: one of the file's {'/'.join(LIKELIHOOD_KINDS)} observers "
                         f"({', '.join(usable) or 'none configured'})")
    name = args.observer
    if name not in configured:
        same = [n for n, c in usable.items() if c.kind == name]
        if len(same) != 1:
            raise ValueError(f"--observer {name!r}: {mf.path} configures no observer of that name"
                             + (f" and {len(same)} of that kind" if name in LIKELIHOOD_KINDS else "")
                             + f"; its {'/'.join(LIKELIHOOD_KINDS)} observers: {', '.join(usable) or 'none'}")
        name = same[0]
    config = configured[name]
    if config.kind not in LIKELIHOOD_KINDS:
        raise ValueError(f"--observer {name!r} is of kind {config.kind!r}; the likelihood needs the continuous-discrete "
                         f"kinds {', '.join(LIKELIHOOD_KINDS)}")
    design = design_from_config(mf.system, config.kind, config.options, where=f"{mf.path}: observers.{name}")
    params = _names(args.param)
    unknowns = params + (["log_Q_scale", "log_R_scale"] if args.learn_noise else [])
    initial = parse_assignments(args.initial or [], unknowns, "--initial")
    bounds = _bounds(args.bound)
    bad = [k for k in bounds if k not in unknowns]
    if bad:
        raise ValueError(f"--bound {bad[0]}: not an unknown of this fit ({', '.join(unknowns)})")
    res = fit_likelihood(design, rec, params, learn_noise=args.learn_noise, initial=initial, bounds=bounds,
                         start=args.start, starts=args.starts, fit_x0=_names(args.fit_x0) or None,
                         smoothing=args.smoothing, censor=not args.no_censor, max_step=args.max_step,
                         on_missing="skip" if args.skip_missing else "error",
                         **({} if args.max_iter is None else {"max_iter": args.max_iter}))
    if args.output:
        from ..simulate._results import write_csv

        outs = mf.system.outputs
        header = ["t", *outs, *(f"{o}.predicted" for o in outs), *(f"{o}.predicted_std" for o in outs)]
        write_csv(args.output, header, np.column_stack([rec.t, rec.y, *res.one_step]))
    if args.plot:
        from ..simulate._plot import plot_outputs

        pred, std = res.one_step
        plot_outputs(rec.t, rec.y, pred, list(mf.system.outputs), args.plot, std=std, label="one-step ŷ⁻",
                     title=f"{mf.system.name}: likelihood fit on {Path(args.data).name}"
                           + ("" if res.success else " (NOT converged)"))
    if args.json:
        print(json.dumps(clean({"model": mf.system.name, "data": args.data, **res.to_dict()})))
    else:
        print(res.summary())
        if args.output:
            print(f"one-step predictions of the fitted filter: {args.output}")
        if args.plot:
            print(f"plot: {args.plot}")
    return 0 if res.success else 1
