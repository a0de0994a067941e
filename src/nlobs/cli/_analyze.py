"""``nlobs analyze``: structural observability and identifiability of a model file.

The file's unknown parameters (``k = { value = 0.3, unknown = true }``) are checked for
identifiability without ``--params``. A model with piecewise functions (abs, sign, min, max,
sat) is analysed on the regimes its ``[simulation]`` visits (``--regime auto``), on a point
(``--regime x1=1,x2=12``), or on the default branches (``--regime default``).
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from ..references import cite
from ._common import clean

MAX_REGIMES = 4  #: regimes analysed at most (the most visited ones)


def add_parser(sub: Any) -> None:
    a = sub.add_parser("analyze", help="is the model observable? (generic rank of the observation space)",
                       description="Structural observability and identifiability of a model file: the generic rank of the "
                                   f"Jacobian of the output and its time derivatives ({cite('002')}), computed by truncated "
                                   f"power series modulo a prime ({cite('sedoglavic2002')}); unobservable directions, "
                                   "sign symmetries, and functions of the states you ask about.")
    a.add_argument("model", help="model file (TOML)")
    a.add_argument("--params", default=None, metavar="NAMES",
                   help="comma-separated parameters to treat as unknown constants (identifiability), or 'all' "
                        "(default: the parameters the file declares unknown = true)")
    a.add_argument("--inputs", default="generic", metavar="CLASS",
                   help="the inputs the verdict covers: 'generic' (default: any smooth input), 'constant', or N "
                        "(polynomials of degree N)")
    a.add_argument("--function", action="append", default=[], metavar="EXPR",
                   help="a function of the states to test for observability (repeatable), e.g. 'x1**2 + x2**2'")
    a.add_argument("--regime", default="auto", metavar="WHICH",
                   help="for abs/sign/min/max/sat: 'auto' (default: the regimes the file's [simulation] visits, else the "
                        "default branches), 'simulation', 'default' (abs(g) = g, unsaturated min/max/sat), or a point "
                        "'x1=1,x2=12' (its active branches)")
    a.add_argument("--global", dest="global_check", action="store_true",
                   help=f"also decide global observability/identifiability ({cite('hong2019')}): globally, locally only "
                        "(with the number of solutions) or not")
    a.add_argument("--identifiable-functions", action="store_true",
                   help="also list generators of the identifiable (observable) functions of the states and parameters, "
                        "simplest first")
    a.add_argument("--params-only", action="store_true",
                   help="the identifiable functions of the parameters only (StructuralIdentifiability.jl's default, "
                        "with_states = false); implies --identifiable-functions")
    a.add_argument("--experiments", type=int, default=None, metavar="N",
                   help="also analyse N experiments sharing the parameters (own initial states and inputs) and "
                        "count how many experiments are needed")
    a.add_argument("--engine", default="auto", choices=["auto", "msolve", "singular", "sympy"],
                   help="Gröbner engine of the global parts (default: msolve, else Singular)")
    a.add_argument("--seed", type=int, default=0, help="seed of the random point and prime (default 0)")
    a.add_argument("--json", action="store_true", help="print one JSON object")
    a.set_defaults(run=run)


def unknown_params_of(mf: Any, given: str | None) -> Any:
    """The unknown parameters: `--params` if given (checked here, so errors name the flag), else the file's."""
    if given is None:
        return mf.unknown_params
    text = given.strip()
    if text == "all":
        return "all"
    names = [p.strip() for p in text.split(",") if p.strip()]
    params = mf.system.param_names
    bad = [n for n in names if n not in params]
    if bad:
        raise ValueError(f"--params: {bad[0]!r} is not a parameter of {mf.path}; its parameters are: "
                         f"{', '.join(params) or '(none)'} (or give --params all)")
    return names


def _point(text: str, mf: Any) -> dict[str, float]:
    out = {}
    for part in text.split(","):
        name, sep, value = part.partition("=")
        if not sep:
            raise ValueError(f"--regime: {part.strip()!r} is not NAME=VALUE; give 'auto', 'simulation', 'default' or a point "
                             f"such as {mf.system.states[0]}=1.0,...")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--regime: {value.strip()!r} is not a number (in {part.strip()!r})") from None
    return out


def _simulated_regimes(mf: Any, required: bool) -> tuple[list[Any], str]:
    """The regimes the file's noise-free [simulation] visits, or ([], why not)."""
    import numpy as np

    from ..analysis import visited_regimes
    from ..simulate import simulate

    cfg = mf.simulation
    if cfg.x0 is None or cfg.t_final is None:
        why = "the file's [simulation] has no x0 and t_final to simulate"
        if required:
            raise ValueError(f"--regime simulation: {why}; set them, or give a point --regime x1=...,x2=...")
        return [], why
    try:
        run = simulate(mf.true_system, None, t_final=cfg.t_final, dt=cfg.dt or 1e-3, x0=cfg.x0, inputs=dict(cfg.inputs))
    except (ValueError, RuntimeError) as e:
        if required:
            raise
        return [], f"the simulation failed ({str(e).splitlines()[0][:120]})"
    every = max(1, run.t.size // 2000)
    samples = {n: run.x[::every, i] for i, n in enumerate(mf.system.states)}
    samples.update({n: run.u[::every, i] for i, n in enumerate(mf.system.inputs)})
    samples["t"] = run.t[::every]
    return visited_regimes(mf.system, samples), f"the noise-free [simulation] (t in [0, {float(np.max(run.t)):g}])"


def run(args: argparse.Namespace) -> int:
    from ..analysis import analyze
    from ..analysis.structural._regimes import piecewise_nodes
    from ..model import load_model

    mf = load_model(args.model)
    unknown = unknown_params_of(mf, args.params)
    inputs: Any = int(args.inputs) if args.inputs.strip().isdigit() else args.inputs.strip()
    options = dict(unknown_params=unknown, inputs=inputs, functions=args.function, seed=args.seed,
                   global_check=args.global_check,
                   identifiable_functions="parameters" if args.params_only else args.identifiable_functions,
                   experiments=args.experiments, engine=args.engine)
    choice = args.regime.strip()
    regimes: list[Any] = []
    source = ""
    if choice not in ("auto", "simulation", "default"):
        point = _point(choice, mf)
        report = analyze(mf.system, regime=point, **options)
        regimes_out = [{"point": point, "fraction": None, "report": report}]
    else:
        if choice != "default" and piecewise_nodes(mf.system):
            regimes, source = _simulated_regimes(mf, required=choice == "simulation")
        if regimes:
            regimes_out = [{"point": r.point, "fraction": r.fraction, "branches": list(r.branches),
                            "report": analyze(mf.system, regime=r.point, **options)} for r in regimes[:MAX_REGIMES]]
        else:
            regimes_out = [{"point": None, "fraction": None, "report": analyze(mf.system, **options)}]
            if source and piecewise_nodes(mf.system):
                source = f"default branches ({source})"
    main = regimes_out[0]["report"]
    if args.json:
        out = main.to_dict()
        if regimes:
            out["regimes"] = [{"fraction": r["fraction"], "point": r["point"], "branches": r["branches"],
                               "report": r["report"].to_dict()} for r in regimes_out]
            out["regimes_source"] = source
        print(json.dumps(clean(out)))
        return 0
    if len(regimes_out) == 1 and not regimes:
        print(main)
        if source:
            print(f"  note: piecewise functions analysed on their {source}")
        return 0
    print(f"{mf.system.name}: {len(regimes)} regime(s) visited by {source}"
          + (f"; the {MAX_REGIMES} most visited are analysed" if len(regimes) > MAX_REGIMES else ""))
    for i, r in enumerate(regimes_out, 1):
        where = ", ".join(f"{k}={v:.4g}" for k, v in r["point"].items())
        print(f"\nregime {i} ({100 * r['fraction']:.0f} % of the samples; e.g. at {where}):")
        print("  " + "; ".join(r["branches"]))
        print(r["report"])
    return 0
