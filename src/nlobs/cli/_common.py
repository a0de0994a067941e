"""What several commands share: loading designs from a model file, JSON cleaning, error lines."""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .._text import shorten

__all__ = ["designs_of", "clean", "error_message", "positive_float", "parse_vector", "parse_assignments", "parse_matrix",
           "parse_columns", "HELP_ENGINE", "HELP_HOLD"]

#: Help texts shared by the commands that integrate.
HELP_ENGINE = ("numeric backend (default: auto): 'c' generates C from the model, compiles it with the system's C compiler and "
               "caches it on disk (fast for long runs); 'vm' runs on CasADi's virtual machine (no compiler, slower per step); "
               "'auto' compiles long runs when a compiler exists and uses the virtual machine otherwise")
HELP_HOLD = ("how outputs and inputs are held between samples (default: zoh): 'zoh' keeps the last sample until the next "
             "(causal, as in a real loop); 'linear' interpolates to the next sample (offline only; more accurate when the "
             "signals change fast between samples)")


def error_message(e: BaseException) -> str:
    """The first line of an error's message (a KeyError's message without its quotes)."""
    text = e.args[0] if isinstance(e, KeyError) and e.args else str(e)
    return (str(text).splitlines() or [type(e).__name__])[0]


def designs_of(model_file: Any, names: Sequence[str] | None, *, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The designs of the observers `names` configured in `model_file` (all when `names` is empty),
    on its observer system (unknown parameters appended to the state), after the identifiability
    check of those parameters (as ``nlobs.design.designs_from_file``).

    `overrides` replace design options of every chosen observer (e.g. ``{"P0": ...}`` from the
    command line); an observer whose kind does not take an option is refused with the kinds that do.
    """
    from dataclasses import replace

    from ..design import KINDS, check_identifiable, design_from_config

    configured = model_file.observers
    auto: dict[str, Any] = {}
    if names:
        unknown = [n for n in names if n not in configured]
        bad = [n for n in unknown if n not in KINDS]
        if bad:
            raise KeyError(f"{model_file.path}: no observer {bad[0]!r}; configured: {', '.join(configured) or '(none)'}; "
                           f"or name an observer kind to design it with its automatic tuning ({', '.join(sorted(KINDS))})")
        auto = _auto_designs(model_file, unknown)
    chosen = names or list(configured)
    check_identifiable(model_file.observer_system, where=model_file.path)
    out = {}
    for n in chosen:
        if n in auto:
            out[n] = auto[n]
            continue
        kind, options = configured[n].kind, dict(configured[n].options)
        for key, value in (overrides or {}).items():
            if kind in KINDS and key not in KINDS[kind].options:
                takes = sorted(k for k, spec in KINDS.items() if key in spec.options)
                raise ValueError(f"--{key}: observer {n!r} (kind {kind!r}) has no option {key}; "
                                 f"kinds that take it: {', '.join(takes)}")
            options[key] = value
        out[n] = design_from_config(replace(configured[n], options=options), where=f"{model_file.path}: observers.{n}")
    return out


def _auto_designs(model_file: Any, kinds: Sequence[str]) -> dict[str, Any]:
    """Kinds named on the command line but not configured in the file: designed with the advisor's automatic tuning
    (as ``nlobs design`` proposes them); a kind that does not apply is refused with the advisor's reason."""
    if not kinds:
        return {}
    from ..advise import advise

    adv = advise(model_file, kinds=list(kinds), run=False, progress=False)
    out = {}
    for c in adv.candidates:
        if c.kind not in kinds:
            continue
        if c.design is None or not c.applies:
            raise ValueError(f"{model_file.path}: --observer {c.kind}: no observer of that name is configured, and the kind "
                             f"{c.kind!r} cannot be tuned automatically for this model: {c.why}")
        out[c.kind] = c.design
    return out


def _positive(convert: Any, what: str) -> Any:
    """An argparse type: `text` converted by `convert`, finite and > 0, or one line saying what was expected."""

    def parse(text: str) -> Any:
        try:
            v = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a positive {what}, got {text!r}") from None
        if not (math.isfinite(v) and v > 0):
            raise argparse.ArgumentTypeError(f"expected a positive {what} (finite and > 0), got {text!r}")
        return v

    return parse


#: argparse type: a whole number > 0.
positive_int = _positive(int, "whole number")
#: argparse type: a finite number > 0.
positive_float = _positive(float, "number")


def _number(text: str, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"{what}: {shorten(text.strip())} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{what}: {shorten(text.strip())} is not a finite number")
    return v


def parse_vector(text: str, names: Sequence[str], what: str, default: Sequence[float] | None = None) -> np.ndarray:
    """One number per name: ``"1,0"`` (in order) or ``"x1=1,x2=0"`` (by name; names left out keep `default`)."""
    items = [p.strip() for p in text.split(",") if p.strip()]
    if items and all("=" in p for p in items):
        values = parse_assignments(items, names, what)
        missing = [n for n in names if n not in values]
        if missing and default is None:
            raise ValueError(f"{what}: no value for {', '.join(missing)}; give one per state ({', '.join(names)})")
        base = np.asarray(default if default is not None else np.zeros(len(names)), dtype=float).copy()
        for i, n in enumerate(names):
            if n in values:
                base[i] = values[n]
        return base
    if any("=" in p for p in items):
        raise ValueError(f"{what}: mix of named and unnamed values in {text!r}; write either '1,0' or '{names[0]}=1,...'")
    v = np.array([_number(p, what) for p in items])
    if v.size != len(names):
        raise ValueError(f"{what}: {v.size} value(s) for {len(names)} state(s) ({', '.join(names)}); "
                         f"give one per state in order, or NAME=VALUE pairs")
    return v


def _pairs(items: Sequence[str] | None, what: str, form: str) -> dict[str, str]:
    """``["a=1", "b=2,c=3"]`` -> ``{"a": "1", "b": "2", "c": "3"}``: repeatable and comma-separated NAME=VALUE pairs."""
    out: dict[str, str] = {}
    for item in items or ():
        for part in (p.strip() for p in item.split(",")):
            if not part:
                continue
            if "=" not in part:
                raise ValueError(f"{what}: expected {form}, got {part!r}")
            k, v = (s.strip() for s in part.split("=", 1))
            if k in out:
                raise ValueError(f"{what}: {k!r} is given twice")
            out[k] = v
    return out


def parse_assignments(items: Sequence[str], names: Sequence[str], what: str) -> dict[str, float]:
    """``["a=1", "b=2,c=3"]`` -> ``{"a": 1.0, ...}``, each name one of `names`."""
    out = _pairs(items, what, "NAME=VALUE")
    for k in out:
        if k not in names:
            raise ValueError(f"{what}: {k!r} is not one of {', '.join(names) or '(none)'}")
    return {k: _number(v, f"{what} {k}") for k, v in out.items()}


def parse_matrix(text: str, n: int, what: str) -> np.ndarray:
    """An n×n matrix: one number (that times the identity), n numbers (the diagonal) or a JSON list of rows."""
    text = text.strip()
    if text.startswith("["):
        try:
            m = np.asarray(json.loads(text), dtype=float)
        except (ValueError, TypeError):
            raise ValueError(f"{what}: {text[:60]!r} is not a JSON list of {n} rows of {n} numbers") from None
        if m.shape != (n, n):
            raise ValueError(f"{what}: expected {n}×{n}, got shape {m.shape}")
    else:
        v = np.array([_number(p, what) for p in text.split(",") if p.strip()])
        if v.size == 1:
            m = v[0] * np.eye(n)
        elif v.size == n:
            m = np.diag(v)
        else:
            raise ValueError(f"{what}: give one number (times the identity), {n} numbers (the diagonal) or a JSON matrix; "
                             f"got {v.size} numbers")
    if not np.all(np.isfinite(m)):
        raise ValueError(f"{what}: entries must be finite")
    return m


def parse_columns(items: Sequence[str] | None) -> dict[str, str]:
    """``["time=t", "h2=y"]`` (CSV name = model name) -> ``{"time": "t", "h2": "y"}``."""
    return _pairs(items, "--column", "CSV_NAME=MODEL_NAME")


def clean(value: Any) -> Any:
    """JSON-safe: NaN/inf become null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: clean(v) for k, v in value.items()}
    if isinstance(value, list):
        return [clean(v) for v in value]
    return value


#: The exit status of a run in which some observers failed while the others completed (their output written).
SOME_FAILED = 3


def failed_status(run: Any) -> int:
    """0, or :data:`SOME_FAILED` when observers of `run` failed (each named with its reason on stderr)."""
    failures = getattr(run, "failures", None) or {}
    for name, f in failures.items():
        print(f"nlobs: observer {name!r} failed: {f.message}", file=sys.stderr)
    return SOME_FAILED if failures else 0
