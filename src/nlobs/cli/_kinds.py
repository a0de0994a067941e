"""``nlobs kinds [KIND]``: the observer kinds a model file can configure, their options and references.

Everything comes from the design functions themselves: the options and defaults from their
signatures, the descriptions from their NumPy-style docstrings, the references from the works
those docstrings and the certificates' references (the module's ``REF...`` strings) cite
(:func:`nlobs.references.cited_keys`).
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
    """What ``nlobs kinds KIND`` shows: summary, design function, options (default, description), references."""
    from ..design import DESIGNS
    from ..references import REFERENCES, cited_keys

    if kind not in DESIGNS:
        raise KeyError(f"no observer kind {kind!r}; available: {', '.join(sorted(DESIGNS))} (nlobs kinds lists them)")
    fn: Callable[..., Any] = DESIGNS[kind]
    doc = inspect.getdoc(fn) or ""
    module_doc = inspect.getdoc(sys.modules[fn.__module__]) or ""
    params = _parameter_docs(doc)
    options = []
    for name, p in inspect.signature(fn).parameters.items():
        if p.kind is not inspect.Parameter.KEYWORD_ONLY:
            continue
        default = None if p.default is inspect.Parameter.empty else p.default
        options.append({"name": name, "required": p.default is inspect.Parameter.empty,
                        "default": default if isinstance(default, (int, float, str, bool, type(None))) else repr(default),
                        "description": _clean_rst(params.get(name, ""))})
    module = sys.modules[fn.__module__]
    certificate_refs = [v for k, v in vars(module).items() if k.startswith("REF") and isinstance(v, str)]
    keys = cited_keys("\n".join([*certificate_refs, doc])) or cited_keys(module_doc)  # the certificate's works first
    summary = _clean_rst(" ".join(_sections(doc)[""][:1]).strip()) if doc else ""
    return {"kind": kind, "function": f"nlobs.{fn.__name__}", "summary": summary, "options": options,
            "references": [{"key": k, "cite": REFERENCES[k].label, "full": str(REFERENCES[k])} for k in keys]}


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
    from ..design import DESIGNS

    if args.kind:
        info = kind_info(args.kind)
        if args.json:
            print(json.dumps(info))
            return 0
        print(f"{info['kind']}: {info['summary']}")
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
                print(textwrap.fill(r["full"], width=88, initial_indent="  ", subsequent_indent="    "))
        return 0
    infos = [kind_info(k) for k in sorted(DESIGNS)]
    if args.json:
        print(json.dumps({"kinds": infos}))
        return 0
    width = max(len(i["kind"]) for i in infos)
    for i in infos:
        refs = "; ".join(r["cite"] for r in i["references"]) or "—"
        pad = " " * (width + 2)
        print(textwrap.fill(i["summary"], width=100, initial_indent=f"{i['kind']:<{width}}  ", subsequent_indent=pad))
        print(textwrap.fill(f"[{refs}]", width=100, initial_indent=pad, subsequent_indent=pad))
    print("\nnlobs kinds KIND: the options of one kind, with their defaults")
    return 0
