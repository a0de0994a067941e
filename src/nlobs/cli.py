"""The command line: ``nlobs demo | analyze | simulate | estimate | export``.

Errors print one line (``nlobs: error: ...``) and exit non-zero; ``--debug`` shows the traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from typing import Any
from .references import cite

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="nlobs", description="Nonlinear observability analysis and state-observer design.")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    d = sub.add_parser("demo", help="reproduce the papers' examples; write an HTML report")
    d.add_argument("--out", default="nlobs-report", help="report folder (default: nlobs-report)")
    d.add_argument("--only", action="append", metavar="KEY", help="run only this example (repeatable); see --list")
    d.add_argument("--list", action="store_true", help="list the examples and exit")
    d.add_argument("--quiet", action="store_true", help="no progress lines")

    a = sub.add_parser("analyze", help=f"structural observability of a model file (generic rank, {cite('002')})")
    a.add_argument("model", help="model file (TOML)")
    a.add_argument("--params", default="", metavar="NAMES",
                   help="comma-separated parameters to treat as unknown constants (identifiability), or 'all'")
    a.add_argument("--inputs", default="generic", metavar="CLASS",
                   help=f"'generic' (default: the observation space of {cite('002')}), 'constant', or a polynomial degree")
    a.add_argument("--function", action="append", default=[], metavar="EXPR",
                   help="a function of the states to test for observability (repeatable), e.g. 'x1**2 + x2**2'")
    a.add_argument("--seed", type=int, default=0, help="seed of the random point and prime (default 0)")
    a.add_argument("--json", action="store_true", help="print one JSON object")

    s = sub.add_parser("simulate", help="simulate a model file's plant with its observers")
    s.add_argument("model", help="model file (TOML)")
    s.add_argument("--observer", action="append", metavar="NAME", help="observer configured in the file (repeatable; default: all)")
    s.add_argument("--t-final", type=float, help="horizon (default: the file's [simulation] t_final)")
    s.add_argument("--dt", type=float, help="integration step (default: the file's, else 1e-3)")
    s.add_argument("--seed", type=int, help="noise seed (default: the file's)")
    s.add_argument("--engine", choices=("auto", "vm", "c"), default="auto", help="numeric backend")
    s.add_argument("--tol", type=float, help="convergence tolerance (default: 2%% of the initial error)")
    s.add_argument("--plot", metavar="FILE", help="save states vs estimates and error norms to FILE (png/pdf/svg)")
    s.add_argument("--json", action="store_true", help="print one JSON object")

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

    x = sub.add_parser("export", help="write an observer's sample-to-sample step as dependency-free C")
    x.add_argument("model", help="model file (TOML)")
    x.add_argument("--observer", required=True, metavar="NAME", help="observer configured in the file")
    x.add_argument("--c", required=True, metavar="DIR", dest="c_dir", help="folder for NAME.c, NAME.h and an example main.c")
    x.add_argument("--name", help="C prefix and file name (default: MODEL_KIND)")
    x.add_argument("--max-step", type=float, help="largest RK4 step between samples (default: one step per interval)")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return {"demo": _demo, "analyze": _analyze, "simulate": _simulate, "estimate": _estimate,
                "export": _export}[args.command](args)
    except KeyboardInterrupt:
        print("nlobs: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # noqa: BLE001 - the CLI turns every error into one line
        if args.debug:
            raise
        print(f"nlobs: error: {e}".splitlines()[0] if not isinstance(e, KeyError) else f"nlobs: error: {e.args[0]}", file=sys.stderr)
        return 1


def _demo(args: argparse.Namespace) -> int:
    from .report import run_demo
    from .examples import EXAMPLES

    if args.list:
        for ex in sorted(EXAMPLES.values(), key=lambda e: e.order):
            print(f"{ex.key:<16} {ex.title}")
        return 0
    return run_demo(args.out, only=args.only, progress=not args.quiet).exit_code


def _analyze(args: argparse.Namespace) -> int:
    from .analysis import analyze
    from .model import load_model

    mf = load_model(args.model)
    params = args.params.strip()
    unknown: Any = "all" if params == "all" else [p.strip() for p in params.split(",") if p.strip()]
    inputs: Any = int(args.inputs) if args.inputs.strip().isdigit() else args.inputs.strip()
    report = analyze(mf.system, unknown_params=unknown, inputs=inputs, functions=args.function, seed=args.seed)
    print(json.dumps(_clean(report.to_dict())) if args.json else report)
    return 0


def _designs(model_file: Any, names: Sequence[str] | None) -> dict[str, Any]:
    from .design import design_from_config

    configured = model_file.observers
    if names:
        unknown = [n for n in names if n not in configured]
        if unknown:
            raise KeyError(f"{model_file.path}: no observer {unknown[0]!r}; configured: {', '.join(configured) or '(none)'}")
    chosen = names or list(configured)
    return {n: design_from_config(model_file.system, configured[n].kind, configured[n].options,
                                  where=f"{model_file.path}: observers.{n}") for n in chosen}


def _clean(value: Any) -> Any:
    """JSON-safe: NaN/inf become null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_clean(v) for v in value]
    return value


def _simulate(args: argparse.Namespace) -> int:
    from .model import load_model
    from .simulate import Noise, ProcessNoise, Sampling, simulate

    mf = load_model(args.model)
    cfg = mf.simulation
    t_final = args.t_final or cfg.t_final
    if t_final is None:
        raise ValueError(f"{mf.path}: no horizon: give --t-final or set [simulation] t_final")
    dt = args.dt or cfg.dt or 1e-3
    if cfg.x0 is None:
        raise ValueError(f"{mf.path}: no initial state: set [simulation] x0 = [...] ({mf.system.n_states} numbers)")
    noise = Noise.per_output(dict(cfg.noise), dict(cfg.noise_bound)) if (cfg.noise or cfg.noise_bound) else None
    run = simulate(mf.system, _designs(mf, args.observer), t_final=t_final, dt=dt, x0=cfg.x0, inputs=dict(cfg.inputs),
                   noise=noise, process_noise=ProcessNoise(dict(cfg.process_noise)) if cfg.process_noise else None,
                   sampling=Sampling(cfg.sample_period) if cfg.sample_period else None,
                   seed=args.seed if args.seed is not None else cfg.seed, engine=args.engine, progress=not args.json)
    if args.plot:
        run.plot(args.plot)
    if args.json:
        print(json.dumps(_clean(run.summary_dict(tol=args.tol))))
    else:
        print(run.summary(tol=args.tol))
        if args.plot:
            print(f"plot: {args.plot}")
    return 0


def _estimate(args: argparse.Namespace) -> int:
    from .model import load_model
    from .simulate import Recording, estimate

    mf = load_model(args.model)
    rec = Recording.from_csv(args.data, mf.system)
    run = estimate(_designs(mf, args.observer), rec, on_missing="skip" if args.skip_missing else "error", hold=args.hold,
                   max_step=args.max_step, engine=args.engine)
    if args.output:
        import numpy as np

        cols = ["t"] + [f"{name}.{s}" for name in run.observers for s in run.state_names]
        data = np.column_stack([run.t] + [tr.xhat for tr in run.observers.values()])
        np.savetxt(args.output, data, delimiter=",", header=",".join(cols), comments="")
    if args.json:
        print(json.dumps(_clean(run.summary_dict())))
    else:
        print(run.summary())
        for name, tr in run.observers.items():
            print(f"{name}: final estimate " + ", ".join(f"{s}={v:.6g}" for s, v in zip(run.state_names, tr.xhat[-1])))
    return 0


def _export(args: argparse.Namespace) -> int:
    from .model import load_model
    from .observer import export_c

    mf = load_model(args.model)
    design = _designs(mf, [args.observer])[args.observer]
    print(export_c(design, args.c_dir, name=args.name, max_step=args.max_step))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
