"""``nlobs kinds [KIND]``: the observer kinds a model file can configure, their options and references.

Everything comes from the registry (:data:`nlobs.design.KINDS`): the summary, time base and the works each kind
implements from its declaration, the options and defaults from the design function's signature, their descriptions
from its NumPy-style docstring; further works that the docstring and the certificate cite (the module's ``REF...``
strings, :func:`nlobs.references.cited_keys`) follow the kind's own.
"""

from __future__ import annotations

import argparse
import inspect
import json
import re
import sys
import textwrap
from collections.abc import Callable
from typing import Any

__all__ = ["kind_info", "add_parser", "run"]


def _clean_rst(text: str) -> str:
    """Docstring markup as plain text: roles, literals and inline maths."""
    text = re.sub(r":(?:func|class|meth|attr|mod|data|obj|exc):`~?([^`]+)`", r"\1", text)
    text = re.sub(r":math:`([^`]+)`", r"\1", text)
    return text.replace("``", "")


def _sections(doc: str) -> dict[str, list[str]]:
    """The sections of a NumPy-style docstring by heading ('' for the text before the first)."""
    out: dict[str, list[str]] = {"": []}
    lines = doc.splitlines()
    current = ""
    i = 0
    while i < len(lines):
        if i + 1 < len(lines) and lines[i].strip() and set(lines[i + 1].strip()) == {"-"} \
                and len(lines[i + 1].strip()) >= len(lines[i].strip()) - 1:
            current = lines[i].strip()
            out[current] = []
            i += 2
            continue
        out.setdefault(current, []).append(lines[i])
        i += 1
    return out


def _parameter_docs(doc: str) -> dict[str, str]:
    """name -> description from the Parameters and Other Parameters sections."""
    secs = _sections(doc)
    out: dict[str, str] = {}
    for heading in ("Parameters", "Other Parameters"):
        names: list[str] = []
        for line in secs.get(heading, []):
            if line and not line.startswith(" "):
                names = [n.strip() for n in line.split(":")[0].split(",")]
                for n in names:
                    out[n] = ""
            elif line.strip() and names:
                for n in names:
                    out[n] = (out[n] + " " + line.strip()).strip()
    return out


def kind_info(kind: str) -> dict[str, Any]:
    """What ``nlobs kinds KIND`` shows: summary, time base, design function, options (default, description), references."""
    from ..design import KINDS
    from ..references import REFERENCES, cited_keys

    if kind not in KINDS:
        raise KeyError(f"no observer kind {kind!r}; available: {', '.join(sorted(KINDS))} (nlobs kinds lists them)")
    k = KINDS[kind]
    fn: Callable[..., Any] = k.design
    doc = inspect.getdoc(fn) or ""
    params = _parameter_docs(doc)
    options = []
    for name, default in k.options.items():
        required = default is inspect.Parameter.empty
        default = None if required else default
        options.append({"name": name, "required": required,
                        "default": default if isinstance(default, (int, float, str, bool, type(None))) else repr(default),
                        "description": _clean_rst(params.get(name, ""))})
    module = sys.modules[fn.__module__]
    certificate_refs = [v for key, v in vars(module).items() if key.startswith("REF") and isinstance(v, str)]
    keys = list(k.reference_keys)
    keys += [key for key in cited_keys("\n".join([*certificate_refs, doc])) if key not in keys]
    places = dict(k.references)
    return {"kind": kind, "function": f"nlobs.{fn.__name__}", "summary": k.summary, "time_base": k.time_base,
            "tuned_by_advisor": k.tune is not None, "options": options,
            "references": [{"key": key, "cite": REFERENCES[key].label, "full": str(REFERENCES[key]),
                            "where": places.get(key, ""), "implements": key in places} for key in keys]}


def add_parser(sub: Any) -> None:
    k = sub.add_parser("kinds", help="list the observer kinds (model files' [observers.NAME] kind = ...), their options "
                                     "and references",
                       description="Without KIND: every observer kind with its design function and reference. With KIND: "
                                   "its options (required, or their defaults) as a model file sets them, and the works it "
                                   "implements.")
    k.add_argument("kind", nargs="?", metavar="KIND", help="one kind, e.g. ekf")
    k.add_argument("--json", action="store_true", help="print one JSON object")
    k.set_defaults(run=run)


def _fmt_default(o: dict[str, Any]) -> str:
    return "required" if o["required"] else f"default {o['default']!r}" if o["default"] is not None else "optional"


def run(args: argparse.Namespace) -> int:
    from ..design import KINDS

    if args.kind:
        info = kind_info(args.kind)
        if args.json:
            print(json.dumps(info))
            return 0
        print(f"{info['kind']}: {info['summary']}")
        print(f"time base: {info['time_base']}")
        print(f"design function: {info['function']}(system, **options)")
        print("options ([observers.NAME] keys of a model file):")
        width = max([len(o["name"]) for o in info["options"]] + [4])
        for o in info["options"]:
            head = f"  {o['name']:<{width}}  {_fmt_default(o)}"
            print(head)
            if o["description"]:
                print(textwrap.fill(o["description"], width=88, initial_indent=" " * (width + 4),
                                    subsequent_indent=" " * (width + 4)))
        if info["references"]:
            print("references:")
            for r in info["references"]:
                where = f" [{r['where']}]" if r["where"] else ""
                print(textwrap.fill(r["full"] + where, width=88, initial_indent="  ", subsequent_indent="    "))
        return 0
    infos = [kind_info(k) for k in sorted(KINDS)]
    if args.json:
        print(json.dumps({"kinds": infos}))
        return 0
    width = max(len(i["kind"]) for i in infos)
    for i in infos:
        refs = "; ".join(r["cite"] for r in i["references"] if r["implements"]) or "—"
        pad = " " * (width + 2)
        print(textwrap.fill(i["summary"], width=100, initial_indent=f"{i['kind']:<{width}}  ", subsequent_indent=pad))
        print(textwrap.fill(f"[{refs}]", width=100, initial_indent=pad, subsequent_indent=pad))
    print("\nnlobs kinds KIND: the options of one kind, with their defaults")
    return 0
