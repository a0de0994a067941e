"""``nlobs simulate``: a model file's plant with its observers, on its ``[simulation]`` table."""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np

from ._common import failed_status, HELP_ENGINE, clean, designs_of, parse_assignments, parse_columns, parse_vector, positive_float


def add_parser(sub: Any) -> None:
    s = sub.add_parser("simulate", help="simulate a model file's plant with its observers",
                       description="Simulate the plant of a model file together with its observers. Defaults come from "
                                   "the file's [simulation] table; the options below replace them.")
    s.add_argument("model", help="model file (TOML)")
    s.add_argument("--observer", action="append", metavar="NAME",
                   help="observer configured in the file, or an observer kind (ekf, ukf, ...: designed with the automatic "
                        "tuning of `nlobs design`) (repeatable; default: every configured observer)")
    s.add_argument("--t-final", type=positive_float, metavar="T",
                   help="horizon in seconds (default: the last time of --input, else the file's [simulation] t_final)")
    s.add_argument("--dt", type=positive_float, help="integration step in seconds (default: the file's, else 1e-3; a "
                                                     "discrete-time model steps by its sample_time)")
    s.add_argument("--x0", metavar="VALUES", help="initial plant state, '1,0' or 'x1=1,x2=0' (default: the file's x0)")
    s.add_argument("--xhat0", metavar="VALUES", help="initial estimate of every observer, as --x0 (default: each observer's)")
    s.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="a plant parameter value (repeatable); the observers keep the file's values")
    s.add_argument("--input", metavar="CSV", dest="input_csv",
                   help="drive the plant with a recorded input: a CSV with t and the model's inputs (from t = 0); "
                        "when it also has the outputs, the simulated outputs are compared with them")
    s.add_argument("--column", action="append", metavar="CSV=MODEL", help="map a column of --input to a model name (repeatable)")
    s.add_argument("--hold", choices=("zoh", "linear"), default="zoh",
                   help="with --input, how the recorded input is held between its samples (default: zoh, the last value; "
                        "'linear' interpolates)")
    s.add_argument("--seed", type=int, help="noise seed (default: the file's)")
    s.add_argument("--engine", choices=("auto", "vm", "c"), default="auto", help=HELP_ENGINE)
    s.add_argument("--tol", type=positive_float,
                   help="absolute convergence tolerance on ‖x̂ − x‖ (default: each state judged in its own units, "
                        "its band max(2%% of its initial error, 2 × its steady-state error), at most 20%% of its initial "
                        "error unless that floor is zero-mean noise; the summary names the states that set the time)")
    s.add_argument("--output", metavar="CSV",
                   help="write t, inputs, outputs, true states and each observer's estimate (NAME.STATE) to a CSV that "
                        "`nlobs estimate` reads back; a sampled run writes its sample instants")
    s.add_argument("--plot", metavar="FILE", help="save states vs estimates and error norms to FILE (png/pdf/svg)")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..model import Sampled, load_model
    from ..estimation import Recording
    from ..simulate import Sampling, simulate

    mf = load_model(args.model)
    system, cfg = mf.system, mf.simulation
    params = parse_assignments(args.param or [], system.param_names, "--param")
    inputs: dict[str, Any] | None = None  # None: the file's (and the identifiability check runs on them)
    recorded = None
    if args.input_csv:
        recorded = Recording.from_csv(args.input_csv, system, columns=parse_columns(args.column), require_outputs=False)
        if recorded.t[0] != 0:
            raise ValueError(f"{args.input_csv}: the recording starts at t = {recorded.t[0]:g}; a simulation starts at t = 0: "
                             "shift its time column so that the first sample is at 0")
        recorded.check_finite("skip")
        inputs = {name: Sampled(recorded.t, recorded.u[:, j], args.hold, name=name) for j, name in enumerate(system.inputs)}
    elif args.column:
        raise ValueError("--column maps the columns of --input; give --input CSV")
    t_final = args.t_final
    if t_final is None:  # a recorded input sets its own horizon; else the file's
        t_final = float(recorded.t[-1]) if recorded is not None else cfg.t_final
    if t_final is None:
        raise ValueError(f"{mf.path}: no horizon: give --t-final or set [simulation] t_final")
    if system.is_discrete:   # a map steps by its sample_time
        if args.dt is not None:
            raise ValueError(f"{mf.path}: --dt does not apply to a discrete-time model (it steps by sample_time = "
                             f"{system.sample_time:g} s)")
        dt = None
    else:
        dt = args.dt if args.dt is not None else (cfg.dt if cfg.dt is not None else 1e-3)
    if args.x0 is not None:
        x0 = parse_vector(args.x0, system.states, "--x0", cfg.x0)
    elif cfg.x0 is None:
        raise ValueError(f"{mf.path}: no initial state: give --x0 or set [simulation] x0 = [...] ({system.n_states} numbers)")
    else:
        x0 = cfg.x0
    # observers estimate the states and the unknown parameters (their guesses are the default tail of x̂0)
    est = mf.observer_system.states
    xhat0 = None if args.xhat0 is None else parse_vector(
        args.xhat0, est, "--xhat0", [0.0] * system.n_states + list(mf.guesses.values()) if mf.unknown_params else None)
    # the file's plant (true_parameters), noise, sampling and seed; unknown parameters are checked for
    # identifiability (also with the file's inputs) before anything runs
    run_ = simulate(mf, designs_of(mf, args.observer), t_final=t_final, dt=dt, x0=x0, inputs=inputs, params=params or None,
                    xhat0=xhat0, seed=args.seed, engine=args.engine, progress=not args.json)
    validation = _validation(run_, recorded) if recorded is not None else None
    if args.output:
        every = Sampling(cfg.sample_period).every(dt) if cfg.sample_period and dt else 1
        run_.to_csv(args.output, every=every)
    if args.plot:
        run_.plot(args.plot)
    if args.json:
        out = run_.summary_dict(tol=args.tol)
        if validation is not None:
            out["validation"] = validation
        print(json.dumps(clean(out)))
    else:
        print(run_.summary(tol=args.tol))
        if not run_.observers and not run_.failures:
            print(f"no observers: {mf.path} configures none. `nlobs design {mf.path} --toml` proposes them (paste its "
                  f"[observers] tables into the file), or `nlobs simulate {mf.path} --observer ekf` runs one kind with its "
                  "automatic tuning")
        if validation:
            print("simulated vs recorded outputs (" + args.input_csv + "): " + "; ".join(
                f"{o}: RMSE {v['rmse']:.4g}, fit {v['fit_percent']:.1f} %" for o, v in validation.items()))
        for path, what in ((args.output, "trajectory"), (args.plot, "plot")):
            if path:
                print(f"{what}: {path}")
    return failed_status(run_)


def _validation(run_: Any, rec: Any) -> dict[str, dict[str, float]]:
    """Noise-free simulated outputs against the recorded ones at the recording's times within the run:
    RMSE and the fit 100·(1 − ‖y − ŷ‖/‖y − mean y‖) per output."""
    out = {}
    inside = rec.t <= run_.t[-1] + 1e-12
    for j, name in enumerate(rec.output_names):
        y = rec.y[inside, j]
        ok = np.isfinite(y)
        if not ok.any():
            continue
        y_sim = np.interp(rec.t[inside][ok], run_.t, run_.y_true[:, j])
        err = y[ok] - y_sim
        spread = np.linalg.norm(y[ok] - y[ok].mean())
        out[name] = {"rmse": float(np.sqrt(np.mean(err**2))), "samples": int(ok.sum()),
                     "fit_percent": float(100 * (1 - np.linalg.norm(err) / spread)) if spread > 0 else float("nan")}
    return out
