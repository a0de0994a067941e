"""``nlobs export``: an observer's sample-to-sample step as dependency-free C."""

from __future__ import annotations

import argparse
from typing import Any

from ._common import designs_of


def add_parser(sub: Any) -> None:
    x = sub.add_parser("export", help="write an observer's sample-to-sample step as dependency-free C",
                       description="Write NAME.c and NAME.h (the observer's step from one sample to the next, C99, only "
                                   "<math.h>, no allocation) and an example main.c that reads t,u...,y... lines from stdin.")
    x.add_argument("model", help="model file (TOML)")
    x.add_argument("--observer", required=True, metavar="NAME", help="observer configured in the file")
    x.add_argument("--c", required=True, metavar="DIR", dest="c_dir", help="folder for NAME.c, NAME.h and an example main.c")
    x.add_argument("--name", help="C prefix and file name (default: MODEL_KIND)")
    x.add_argument("--max-step", type=float, help="largest RK4 step between samples (default: one step per interval)")
    x.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..model import load_model
    from ..observer import export_c

    mf = load_model(args.model)
    design = designs_of(mf, [args.observer])[args.observer]
    print(export_c(design, args.c_dir, name=args.name, max_step=args.max_step))
    return 0
