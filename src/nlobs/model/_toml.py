"""Model files: TOML parsed with :mod:`tomllib`, expressions through the AST whitelist.

The format (a contract other tools rely on)::

    name = "van_der_pol"
    states = ["x1", "x2"]
    inputs = ["u"]            # optional
    outputs = ["y"]
    [parameters]
    mu = 1.0
    [dynamics]                # one time derivative per state
    x1 = "x2"
    x2 = "mu*(1 - x1**2)*x2 - x1 + u"
    [output]
    y = "x1"
    [simulation]              # defaults for `simulate` and the demo
    t_final = 20.0
    dt = 1e-3
    x0 = [2.0, 0.0]
    inputs = { u = "0.5*sin(t)" }     # expressions of t (and the parameters)
    noise = { y = 0.01 }              # std of Gaussian measurement noise per output
    noise_bound = { y = 0.02 }        # or: bound of uniform noise in [-b, b]
    sample_period = 0.01              # optional: sampled measurements, zero-order hold
    seed = 1
    [observers.ekf]           # named observer configurations: kind + tuning
    kind = "ekf"
    xhat0 = [0.0, 0.0]

A file that tries anything else is rejected with a :class:`~nlobs.errors.ModelFileError`
naming the file, the key and the offending text.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import sympy as sp

from ..errors import ModelError, ModelFileError
from ._expr import ExpressionError, parse_expression
from ._library import bundled_path
from ._system import TIME, System, symbol

__all__ = ["ModelFile", "SimulationConfig", "ObserverConfig", "load_model", "loads_model"]

_TOP = ("name", "description", "states", "inputs", "outputs", "parameters", "dynamics", "output", "simulation", "observers")
_SIM = ("t_final", "dt", "x0", "inputs", "noise", "noise_bound", "process_noise", "sample_period", "seed")


@dataclass(frozen=True)
class SimulationConfig:
    """The ``[simulation]`` table: defaults for ``simulate`` and the demo (all optional)."""

    t_final: float | None = None
    dt: float | None = None
    x0: tuple[float, ...] | None = None
    inputs: Mapping[str, sp.Expr] = field(default_factory=dict)
    noise: Mapping[str, float] = field(default_factory=dict)
    noise_bound: Mapping[str, float] = field(default_factory=dict)
    process_noise: Mapping[str, float] = field(default_factory=dict)
    sample_period: float | None = None
    seed: int | None = None


@dataclass(frozen=True)
class ObserverConfig:
    """One ``[observers.NAME]`` table: the design ``kind`` and its tuning options (raw)."""

    name: str
    kind: str
    options: Mapping[str, Any]


@dataclass(frozen=True)
class ModelFile:
    """A parsed model file: the system, its simulation defaults and its observer configurations."""

    path: str
    system: System
    simulation: SimulationConfig
    observers: Mapping[str, ObserverConfig]
    description: str = ""


def load_model(path: str | Path) -> ModelFile:
    """Read a TOML model file, or a bundled model by name (``load_model("lorenz")``; see ``nlobs models``).

    A path that exists always wins over a bundled name.

    Raises
    ------
    ModelFileError
        If the file cannot be read, is not valid TOML, or breaks the format.
    """
    p = Path(path)
    if not p.exists():  # a bare name of the bundled library (`nlobs models`); an existing path always wins
        p = bundled_path(str(path)) or p
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        hint = "; not a bundled model name either (`nlobs models` lists them)" if not p.exists() else ""
        raise ModelFileError(f"cannot read the model file: {e.strerror}{hint}", path=str(p)) from None
    except UnicodeDecodeError:
        raise ModelFileError("the model file is not UTF-8 text", path=str(p)) from None
    return loads_model(text, path=str(p), default_name=p.stem)


def loads_model(text: str, *, path: str = "<string>", default_name: str = "model") -> ModelFile:
    """Parse model-file `text` (see :func:`load_model`); `path` names it in messages and
    `default_name` is the model's name when the file has no ``name``."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ModelFileError(f"not valid TOML: {e}", path=path) from None
    return _Loader(path).load(doc, default_name)


class _Loader:
    def __init__(self, path: str):
        self.path = path

    def err(self, message: str, key: str = "", text: Any = "") -> ModelFileError:
        return ModelFileError(message, path=self.path, key=key, text=text if isinstance(text, str) else repr(text) if text != "" else "")

    def names(self, doc: Mapping[str, Any], key: str, required: bool) -> tuple[str, ...]:
        if key not in doc:
            if required:
                raise self.err(f"the key `{key}` is required (a list of names)")
            return ()
        value = doc[key]
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.err("must be a list of names (strings)", key, value)
        return tuple(value)

    def table(self, doc: Mapping[str, Any], key: str) -> Mapping[str, Any]:
        value = doc.get(key.rsplit(".", 1)[-1], {})
        if not isinstance(value, dict):
            raise self.err("must be a table", key, value)
        return value

    def number(self, value: Any, key: str, *, positive: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.err("must be a finite number", key, value)
        if positive and value <= 0:
            raise self.err("must be positive", key, value)
        return float(value)

    def expr(self, value: Any, key: str, symbols: Mapping[str, sp.Symbol]) -> sp.Expr:
        if isinstance(value, bool):
            raise self.err("must be an expression string or a number", key, value)
        if isinstance(value, (int, float)):
            return sp.Rational(repr(float(self.number(value, key))))
        if not isinstance(value, str):
            raise self.err("must be an expression string or a number", key, value)
        try:
            return parse_expression(value, symbols)
        except ExpressionError as e:
            raise self.err(str(e), key, value) from None

    def load(self, doc: Mapping[str, Any], default_name: str) -> ModelFile:
        unknown = [k for k in doc if k not in _TOP]
        if unknown:
            raise self.err(f"unknown key(s) {', '.join(map(repr, unknown))}; allowed top-level keys: {', '.join(_TOP)}", unknown[0])
        name = doc.get("name", default_name)
        if not isinstance(name, str):
            raise self.err("must be a string", "name", name)
        description = doc.get("description", "")
        if not isinstance(description, str):
            raise self.err("must be a string", "description", description)
        states = self.names(doc, "states", True)
        inputs = self.names(doc, "inputs", False)
        outputs = self.names(doc, "outputs", True)
        params = {}
        for k, v in self.table(doc, "parameters").items():
            params[k] = self.number(v, f"parameters.{k}")
        try:  # validate the names (duplicates, reserved words) before parsing expressions
            System(states=states, f=[0] * len(states), outputs=outputs, h=[0] * len(outputs), inputs=inputs, params=params)
        except ModelError as e:
            raise self.err(str(e)) from None
        symbols = {n: symbol(n) for n in (*states, *inputs, *params)}
        symbols["t"] = TIME
        f = self.equations(doc, "dynamics", states, "state", symbols)
        h = self.equations(doc, "output", outputs, "output", symbols)
        system = System(states=states, f=f, outputs=outputs, h=h, inputs=inputs, params=params, name=name)
        return ModelFile(self.path, system, self.simulation(doc, system), self.observers(doc), description)

    def equations(self, doc: Mapping[str, Any], key: str, names: tuple[str, ...], what: str,
                  symbols: Mapping[str, sp.Symbol]) -> list[sp.Expr]:
        if key not in doc:
            raise self.err(f"the table [{key}] is required: one expression per {what}")
        table = self.table(doc, key)
        extra = [k for k in table if k not in names]
        if extra:
            raise self.err(f"`{extra[0]}` is not a declared {what}; declared: {', '.join(names)}", f"{key}.{extra[0]}")
        missing = [n for n in names if n not in table]
        if missing:
            raise self.err(f"no expression for the {what}(s) {', '.join(missing)}; give one per {what}", key)
        return [self.expr(table[n], f"{key}.{n}", symbols) for n in names]

    def simulation(self, doc: Mapping[str, Any], system: System) -> SimulationConfig:
        sim = self.table(doc, "simulation")
        unknown = [k for k in sim if k not in _SIM]
        if unknown:
            raise self.err(f"unknown key; allowed: {', '.join(_SIM)}", f"simulation.{unknown[0]}")
        out: dict[str, Any] = {}
        for k in ("t_final", "dt", "sample_period"):
            if k in sim:
                out[k] = self.number(sim[k], f"simulation.{k}", positive=True)
        if "x0" in sim:
            x0 = sim["x0"]
            if not isinstance(x0, list) or len(x0) != system.n_states:
                raise self.err(f"must be a list of {system.n_states} numbers (one per state: {', '.join(system.states)})", "simulation.x0", x0)
            out["x0"] = tuple(self.number(v, "simulation.x0") for v in x0)
        if "seed" in sim:
            seed = sim["seed"]
            if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
                raise self.err("must be a non-negative integer", "simulation.seed", seed)
            out["seed"] = seed
        sym_t = {"t": TIME, **{k: symbol(k) for k in system.params}}
        inputs = {}
        for k, v in self.table(sim, "simulation.inputs").items():
            if k not in system.inputs:
                raise self.err(f"`{k}` is not an input; inputs: {', '.join(system.inputs) or '(none)'}", f"simulation.inputs.{k}")
            inputs[k] = self.expr(v, f"simulation.inputs.{k}", sym_t)
        out["inputs"] = MappingProxyType(inputs)
        for key, names in (("noise", system.outputs), ("noise_bound", system.outputs), ("process_noise", system.states)):
            values = {}
            for k, v in self.table(sim, f"simulation.{key}").items():
                if k not in names:
                    raise self.err(f"`{k}` is not one of {', '.join(names)}", f"simulation.{key}.{k}")
                values[k] = self.number(v, f"simulation.{key}.{k}")
                if values[k] < 0:
                    raise self.err("must be non-negative", f"simulation.{key}.{k}", v)
            out[key] = MappingProxyType(values)
        both = set(out["noise"]) & set(out["noise_bound"])
        if both:
            raise self.err("an output has both Gaussian `noise` and uniform `noise_bound`; choose one", f"simulation.noise.{sorted(both)[0]}")
        return SimulationConfig(**out)

    def observers(self, doc: Mapping[str, Any]) -> Mapping[str, ObserverConfig]:
        out = {}
        for name, table in self.table(doc, "observers").items():
            key = f"observers.{name}"
            if not isinstance(table, dict):
                raise self.err("must be a table with at least `kind`", key, table)
            kind = table.get("kind")
            if not isinstance(kind, str):
                raise self.err("`kind` is required and must be a string (e.g. \"ekf\", \"luenberger\")", f"{key}.kind", kind if kind is not None else "")
            options = {k: v for k, v in table.items() if k != "kind"}
            out[name] = ObserverConfig(name, kind, MappingProxyType(options))
        return MappingProxyType(out)
