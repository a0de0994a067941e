"""``nlobs models``: the bundled model library (names usable wherever a model file is expected)."""

from __future__ import annotations

import argparse
import json
from typing import Any


def add_parser(sub: Any) -> None:
    m = sub.add_parser("models", help="list the bundled models; a name works wherever a model file does (nlobs design lorenz)")
    m.add_argument("name", nargs="?", help="show this bundled model's file instead of the list")
    m.add_argument("--json", action="store_true", help="print one JSON object")
    m.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from ..model import bundled_path, library

    if args.name:
        path = bundled_path(args.name)
        if path is None:
            from ..model import bundled_names

            raise KeyError(f"no bundled model {args.name!r}; bundled: {', '.join(bundled_names())}")
        text = path.read_text(encoding="utf-8")
        print(json.dumps({"name": path.stem, "path": str(path), "text": text}) if args.json else text, end="" if not args.json else "\n")
        return 0
    entries = library()
    if args.json:
        print(json.dumps({"models": [e.to_dict() for e in entries]}))
        return 0
    width = max(len(e.name) for e in entries)
    print(f"{'name':<{width}}  {'n':>2}  {'outputs':<18} description")
    for e in entries:
        print(f"{e.name:<{width}}  {len(e.states):>2}  {', '.join(e.outputs)[:18]:<18} {e.description}")
    print(f"\n{len(entries)} models. Use a name wherever a model file is expected: nlobs design {entries[0].name}, "
          f"nlobs analyze {entries[0].name}; `nlobs models NAME` prints its file (copy it to start your own).")
    return 0
