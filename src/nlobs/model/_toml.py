"""Model files: TOML parsed with :mod:`tomllib`, expressions through the AST whitelist.

The format (a contract other tools rely on)::

    name = "tanks"
    description = "Two cascaded tanks"   # optional; one line, printable characters
    states = ["x1", "x2"]
    inputs = ["u"]            # optional
    outputs = ["y"]
    [parameters]
    k1 = 0.5                                # a known value
    k2 = { value = 0.3, unknown = true }    # unknown: estimated with the states, value = initial guess
    [definitions]             # optional: named intermediate expressions, in order
    q1 = "k1*sqrt(max(x1, 0))"              # may use states, inputs, parameters, t, earlier definitions
    q2 = "k2*sqrt(max(x2, 0))"
    [dynamics]                # one time derivative per state
    x1 = "-q1 + u"
    x2 = "q1 - q2"
    [output]
    y = "sat(x2, 0, 10)"      # min(a, b), max(a, b), sat(x, lo, hi) = min(max(x, lo), hi)
    [units]                   # optional: per state, input, output, parameter or t (for plots)
    x1 = "m"
    t = "s"
    [simulation]              # defaults for `simulate` and the demo
    t_final = 20.0
    dt = 1e-3
    x0 = [2.0, 0.0]
    inputs = { u = "0.5*sin(t)" }     # expressions of t (and the parameters)
    noise = { y = 0.01 }              # std of Gaussian measurement noise per output
    noise_bound = { y = 0.02 }        # or: bound of uniform noise in [-b, b]
    sample_period = 0.01              # optional: sampled measurements, zero-order hold (or one per output: { y = 0.01, gps = 1.0 })
    delay = { y = 0.15 }              # optional: known measurement delays (s), for simulate and estimate
    true_parameters = { k2 = 0.25 }   # the plant's values in a simulation (default: the values above)
    initial_std = { x2 = 0.5, k2 = 0.1 }  # optional: std of the initial estimation error per state or unknown parameter
                                      # (process_noise may also name an unknown parameter: its random walk, σ per √s)
    seed = 1
    [observers.ekf]           # named observer configurations: kind + tuning
    kind = "ekf"
    xhat0 = [0.0, 0.0]        # with unknown parameters: their initial guesses are appended
    [sensors.level2]          # candidate sensors for `nlobs sensors` (default pool: every state and every output)
    expr = "x2"               # any expression of states, inputs, parameters, t, tables and definitions
    noise = 0.01              # standard deviation of its measurement noise (> 0)
    cost = 3                  # optional (default 1, >= 0)

A file that tries anything else is rejected with a :class:`~nlobs.errors.ModelFileError`
naming the file, the key and the offending text (shortened).

With unknown parameters, :attr:`ModelFile.system` is the model with every parameter at its
file value (the initial guess for unknown ones), and the observers are designed on
:attr:`ModelFile.observer_system`, the system with the unknown parameters appended to the
state (:meth:`~nlobs.System.augmented`).
"""

from __future__ import annotations

import ast
import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import sympy as sp

from .._text import LabelError, check_label, shorten, shorten_list
from ..errors import ModelError, ModelFileError
from ._budget import check_tree
from ._expr import CONSTANTS, FUNCTIONS, ExpressionError, huge_integer, parse_expression
from ._library import LibraryEntry, bundled_folder, bundled_names, bundled_path
from ._system import _NAME, RESERVED, TIME, System, symbol
from ._tables import Table, parse_table

__all__ = ["ModelFile", "SimulationConfig", "ObserverConfig", "SensorConfig", "load_model", "loads_model", "library"]

_TOP = ("name", "description", "time", "sample_time", "states", "inputs", "outputs", "parameters", "tables", "definitions",
        "dynamics", "output", "units", "simulation", "observers", "sensors")
def _depth(expr: sp.Expr) -> int:
    """The nesting depth of an expression tree, level by level (iterative: the tree may be too deep for recursion;
    a subtree shared by many parents is visited once per level)."""
    depth, level = 0, {id(expr): expr}
    while level:
        depth += 1
        level = {id(a): a for e in level.values() for a in getattr(e, "args", ())}
    return depth


def period_multiple_problem(period: float, dt: float) -> str:
    """Why a sample `period` is not a whole multiple of the integration step `dt` ("" when it is): the simulation
    samples on its RK4 grid. The tolerance is the one of :meth:`nlobs.simulate.Sampling.every`."""
    m = float(period) / float(dt)
    if abs(m - round(m)) <= 1e-9 * max(1.0, m) and round(m) >= 1:
        return ""
    k = max(1, round(m))
    return (f"the sample period {period:g} s must be a whole multiple of dt = {dt:g} s (the simulation samples on its "
            f"integration grid; here {m:.6g} steps): choose a period of {k * dt:g} s, or a dt that divides it "
            f"({period:g} / {math.ceil(m)} = {period / math.ceil(m):.6g} s)")


_SIM = ("t_final", "dt", "x0", "inputs", "noise", "noise_bound", "process_noise", "sample_period", "delay", "true_parameters",
        "initial_std", "seed")
_PARAM_KEYS = ("value", "unknown")
_SENSOR_KEYS = ("expr", "noise", "cost", "period")
#: Observer names become JSON keys, CSV column prefixes and C file names: a conservative alphabet.
_OBSERVER_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,59}")


@dataclass(frozen=True)
class SimulationConfig:
    """The ``[simulation]`` table: defaults for ``simulate`` and the demo (all optional).

    `true_parameters` are the plant's parameter values in a simulation when they differ from
    the file's (so a run can show an unknown parameter being recovered from its initial guess).
    """

    t_final: float | None = None
    dt: float | None = None
    x0: tuple[float, ...] | None = None
    inputs: Mapping[str, sp.Expr] = field(default_factory=dict)
    noise: Mapping[str, float] = field(default_factory=dict)
    noise_bound: Mapping[str, float] = field(default_factory=dict)
    process_noise: Mapping[str, float] = field(default_factory=dict)
    #: Known measurement delays by output (seconds): a sample taken at t reaches the observers at t + delay.
    delay: Mapping[str, float] = field(default_factory=dict)
    sample_period: float | Mapping[str, float] | None = None  #: one period, or one per output
    seed: int | None = None
    true_parameters: Mapping[str, float] = field(default_factory=dict)
    #: The standard deviation of the initial estimation error per state or unknown parameter (as PX4's EKF2_GBIAS_INIT):
    #: the automatic tuning (``nlobs design``) offsets x̂(0) by it and takes P(0) = σ² for each one named.
    initial_std: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class ObserverConfig:
    """One ``[observers.NAME]`` table: the design ``kind`` and its tuning options (raw).

    ``nlobs.design.design_from_config(config)`` designs it; :func:`nlobs.simulate` and
    :func:`nlobs.estimate` accept configs wherever they accept designs.

    Attributes
    ----------
    name, kind : str
    options : mapping
        The table's other keys, as written (strings that mention a ``[definitions]`` name are
        already expanded into SymPy expressions).
    system : System or None
        The system the observer is designed on: the file's :attr:`ModelFile.observer_system`
        (with the unknown parameters appended to the state). None for a config built by hand
        without one.
    guesses : mapping of str to float
        Initial guesses of the unknown parameters, the default tail of x̂0.
    """

    name: str
    kind: str
    options: Mapping[str, Any]
    system: System | None = None
    guesses: Mapping[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class SensorConfig:
    """One ``[sensors.NAME]`` table: a candidate sensor for ``nlobs sensors`` (:func:`nlobs.analysis.select_sensors`).

    Attributes
    ----------
    name : str
    expr : sympy.Expr
        What it measures: an expression of the states, inputs, parameters, t (tables and definitions expanded).
    noise : float
        Standard deviation of its measurement noise (> 0), in the units of `expr`.
    cost : float
        Its cost (>= 0; default 1).
    text : str
        The expression as written.
    period : float or None
        Its own sample period on the ``[simulation]`` run (default: the run's ``sample_period``, the fastest one
        when there is one per output).
    """

    name: str
    expr: sp.Expr
    noise: float
    cost: float = 1.0
    text: str = ""
    period: float | None = None


@dataclass(frozen=True)
class ModelFile:
    """A parsed model file: the system, its simulation defaults and its observer configurations.

    Attributes
    ----------
    path : str
    system : System
        The model as written, every parameter at its file value (initial guesses for the unknown ones).
    simulation : SimulationConfig
    observers : mapping of name to ObserverConfig
    description : str
    unknown_params : tuple of str
        The parameters declared ``unknown = true``, in file order.
    definitions : mapping of str to sympy.Expr
        The ``[definitions]``, each with the earlier ones substituted.
    units : mapping of str to str
        The ``[units]`` of states, inputs, outputs, parameters and ``t``.
    sensors : mapping of name to SensorConfig
        The candidate sensors of ``[sensors.NAME]`` tables, in file order (empty without them).
    """

    path: str
    system: System
    simulation: SimulationConfig
    observers: Mapping[str, ObserverConfig]
    description: str = ""
    unknown_params: tuple[str, ...] = ()
    definitions: Mapping[str, sp.Expr] = field(default_factory=dict)
    units: Mapping[str, str] = field(default_factory=dict)
    sensors: Mapping[str, SensorConfig] = field(default_factory=dict)

    @property
    def observer_system(self) -> System:
        """The system observers are designed on: :attr:`system` with the unknown parameters appended
        to the state (itself when there are none)."""
        return self.system.augmented(self.unknown_params)

    @property
    def true_system(self) -> System:
        """The plant of a simulation: :attr:`system` with ``[simulation] true_parameters`` applied."""
        return self.system.with_params(**self.simulation.true_parameters) if self.simulation.true_parameters else self.system

    @property
    def guesses(self) -> dict[str, float]:
        """Initial guesses of the unknown parameters (their file values)."""
        return {k: self.system.params[k] for k in self.unknown_params}


def load_model(path: str | Path) -> ModelFile:
    """Read a TOML model file (UTF-8, with or without a byte-order mark), or a bundled model by name
    (``load_model("lorenz")``; see ``nlobs models``).

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
        text = p.read_bytes().decode("utf-8")
    except OSError as e:
        hint = "; not a bundled model name either (`nlobs models` lists them)" if not p.exists() else ""
        raise ModelFileError(f"cannot read the model file: {e.strerror}{hint}", path=str(p)) from None
    except UnicodeDecodeError as e:
        raise ModelFileError(f"the model file is not UTF-8 text (byte {e.start} cannot be decoded); save it as UTF-8",
                             path=str(p)) from None
    return loads_model(text, path=str(p), default_name=p.stem)


def loads_model(text: str, *, path: str = "<string>", default_name: str = "model") -> ModelFile:
    """Parse model-file `text` (see :func:`load_model`); `path` names it in messages and
    `default_name` is the model's name when the file has no ``name``."""
    if not isinstance(text, str):
        raise ModelFileError(f"loads_model takes the text of a model file (a str), got {type(text).__name__}; "
                             "for a file on disk use load_model(path)", path=path)
    if text.startswith("\ufeff"):  # a byte-order mark, as some editors write it
        text = text[1:]
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        twice = _sensor_twice(text, str(e))
        if twice:   # a candidate sensor declared twice: say so with the table's name
            raise ModelFileError(f"the candidate sensor `{twice}` is declared twice ({str(e).rsplit('(', 1)[-1].rstrip(')')}); "
                                 "give each [sensors.NAME] table its own name", path=path, key=f"sensors.{twice}") from None
        raise ModelFileError(f"not valid TOML: {e}", path=path) from None
    except RecursionError:
        raise ModelFileError("not valid TOML for nlobs: arrays or tables are nested too deeply", path=path) from None
    except ValueError as e:  # e.g. an integer of more than 4300 digits
        huge = huge_integer(str(e))
        if huge:
            line = next((i + 1 for i, ln in enumerate(text.splitlines()) if re.search(r"\d{4301}", ln)), None)
            raise ModelFileError(f"not valid TOML for nlobs: {huge}" + (f" (line {line})" if line else ""),
                                 path=path) from None
        raise ModelFileError(f"not valid TOML for nlobs: a value cannot be read ({shorten(str(e), 80)}); "
                             "numbers must be ordinary floats or integers", path=path) from None
    return _Loader(path).load(doc, default_name)


def _sensor_twice(text: str, message: str) -> str | None:
    """The name of a candidate sensor that tomllib refused as declared twice (``[sensors.A]`` twice, or ``A = {...}``
    twice under ``[sensors]``), else None."""
    m = re.search(r"\('sensors', '([^']*)'\)", message)
    if m:
        return m.group(1)
    line = re.search(r"Cannot overwrite a value \(at line (\d+)", message)
    if not line:
        return None
    lines = text.splitlines()
    k = int(line.group(1)) - 1
    key = re.match(r"\s*([A-Za-z][A-Za-z0-9_]*)\s*=", lines[k]) if 0 <= k < len(lines) else None
    header = next((h.strip() for h in reversed(lines[:k]) if h.lstrip().startswith("[")), "")
    return key.group(1) if key and re.fullmatch(r"\[\s*sensors\s*\](\s*#.*)?", header) else None


def _names_in(text: str) -> set[str]:
    """The names an expression text mentions (through ast.parse only; empty if it does not parse)."""
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        return set()
    return {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}


class _Loader:
    def __init__(self, path: str):
        self.path = path

    def err(self, message: str, key: str = "", text: Any = "") -> ModelFileError:
        shown = text if isinstance(text, str) else shorten(text, 200) if text != "" else ""
        return ModelFileError(message, path=self.path, key=key, text=shown)

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
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.err("must be a finite number", key, value)
        if isinstance(value, int) and abs(value) > 10**300:
            raise self.err("must be a finite number (at most 1e300 in magnitude)", key, value)
        if not math.isfinite(value):
            raise self.err("must be a finite number", key, value)
        if positive and value <= 0:
            raise self.err("must be positive", key, value)
        return float(value)

    def label(self, value: Any, key: str, what: str, max_length: int = 200) -> str:
        try:
            return check_label(value, what, max_length=max_length)
        except LabelError as e:
            raise self.err(str(e), key, value) from None

    def expr(self, value: Any, key: str, symbols: Mapping[str, sp.Expr]) -> sp.Expr:
        if isinstance(value, bool):
            raise self.err("must be an expression string or a number", key, value)
        if isinstance(value, (int, float)):
            return sp.Rational(repr(float(self.number(value, key))))
        if not isinstance(value, str):
            raise self.err("must be an expression string or a number", key, value)
        try:
            return check_tree(parse_expression(value, symbols), f"{self.path}, key `{key}`")
        except ExpressionError as e:
            raise self.err(str(e), key, value) from None

    def load(self, doc: Mapping[str, Any], default_name: str) -> ModelFile:
        unknown = [k for k in doc if k not in _TOP]
        if unknown:
            raise self.err(f"unknown key(s) {shorten_list(map(shorten, unknown), 5)}; allowed top-level keys: {', '.join(_TOP)}",
                           unknown[0])
        name = self.label(doc.get("name", default_name), "name", "model name")
        description = self.label(doc.get("description", ""), "description", "description", 2000)
        states = self.names(doc, "states", True)
        inputs = self.names(doc, "inputs", False)
        outputs = self.names(doc, "outputs", True)
        params, unknown_params = self.parameters(doc)
        base = {k: doc[k] for k in ("time", "sample_time") if k in doc}
        try:  # validate the names (duplicates, reserved words) and the time base before parsing expressions
            System(states=states, f=[0] * len(states), outputs=outputs, h=[0] * len(outputs), inputs=inputs, params=params,
                   name=name, **base)
        except ModelError as e:
            raise self.err(str(e), next((k for k in ("time", "sample_time") if k in base and f"`{k}`" in str(e)), "")) from None
        symbols: dict[str, sp.Expr] = {n: symbol(n) for n in (*states, *inputs, *params)}
        symbols["t"] = TIME
        tables = self.tables(doc, taken={*states, *inputs, *outputs, *params})
        symbols.update({k: tb.function() for k, tb in tables.items()})
        definitions = self.definitions(doc, symbols, taken={*states, *inputs, *outputs, *params, *tables})
        symbols.update(definitions)
        f = self.equations(doc, "dynamics", states, "state", symbols)
        h = self.equations(doc, "output", outputs, "output", symbols)
        try:
            system = System(states=states, f=f, outputs=outputs, h=h, inputs=inputs, params=params, name=name, **base)
        except ModelError as e:
            raise self.err(str(e)) from None
        except RecursionError:  # SymPy walks trees recursively: a long chain of nested calls exhausts Python's stack
            keys = [*(f"dynamics.{k}" for k in states), *(f"output.{k}" for k in outputs)]
            depth = [_depth(e) for e in (*f, *h)]
            i = max(range(len(depth)), key=depth.__getitem__)
            raise self.err(f"the expression nests {depth[i]} levels deep (calls within calls): SymPy, which nlobs's symbolic "
                           "steps use, ran out of Python's recursion depth on it. Replace an inner call by a new state "
                           "(z = g(x) with its own equation) or simplify the chain", keys[i]) from None
        units = self.units(doc, system)
        simulation = self.simulation(doc, system, definitions, unknown_params)
        observer_system = system.augmented(unknown_params)
        guesses = {k: params[k] for k in unknown_params}
        observers = self.observers(doc, definitions, observer_system, guesses)
        sensors = self.sensors(doc, symbols, None if system.is_discrete else simulation.dt)
        return ModelFile(self.path, system, simulation, observers, description, unknown_params,
                         MappingProxyType(definitions), MappingProxyType(units), sensors)

    def parameters(self, doc: Mapping[str, Any]) -> tuple[dict[str, float], tuple[str, ...]]:
        params: dict[str, float] = {}
        unknown: list[str] = []
        for k, v in self.table(doc, "parameters").items():
            key = f"parameters.{k}"
            if isinstance(v, dict):
                extra = [e for e in v if e not in _PARAM_KEYS]
                if extra:
                    raise self.err(f"unknown key `{shorten(extra[0], 40)[1:-1]}`; a parameter table has `value` (a number) and "
                                   "optionally `unknown` (true: estimated with the states, value = initial guess)",
                                   f"{key}.{extra[0]}")
                if "value" not in v:
                    raise self.err("a parameter table needs `value` (the value, or the initial guess when unknown = true)", key)
                flag = v.get("unknown", False)
                if not isinstance(flag, bool):
                    raise self.err("must be true or false", f"{key}.unknown", flag)
                params[k] = self.number(v["value"], f"{key}.value")
                if flag:
                    unknown.append(k)
            else:
                params[k] = self.number(v, key)
        return params, tuple(unknown)

    def definitions(self, doc: Mapping[str, Any], symbols: Mapping[str, sp.Expr], taken: set[str]) -> dict[str, sp.Expr]:
        table = self.table(doc, "definitions")
        out: dict[str, sp.Expr] = {}
        later = set(table)
        for k, v in table.items():
            key = f"definitions.{k}"
            if not _NAME.fullmatch(k):
                raise self.err("a definition's name starts with a letter and contains only letters, digits and underscores",
                               key, k)
            if k in taken or k in RESERVED:
                raise self.err(f"the name `{k}` is already declared (as a state, input, output or parameter) or reserved; "
                               "give the definition its own name", key)
            later.discard(k)
            if isinstance(v, str):
                ahead = sorted(_names_in(v) & later)
                if ahead:
                    raise self.err(f"uses `{ahead[0]}`, which is defined further down; definitions are read in order, "
                                   "so move it above", key, v)
            out[k] = self.expr(v, key, {**symbols, **out})
        return out

    def equations(self, doc: Mapping[str, Any], key: str, names: tuple[str, ...], what: str,
                  symbols: Mapping[str, sp.Expr]) -> list[sp.Expr]:
        if key not in doc:
            raise self.err(f"the table [{key}] is required: one expression per {what}")
        table = self.table(doc, key)
        extra = [k for k in table if k not in names]
        if extra:
            raise self.err(f"`{shorten(extra[0], 40)[1:-1]}` is not a declared {what}; declared: {shorten_list(names)}",
                           f"{key}.{extra[0]}")
        missing = [n for n in names if n not in table]
        if missing:
            raise self.err(f"no expression for the {what}(s) {shorten_list(missing)}; give one per {what}", key)
        return [self.expr(table[n], f"{key}.{n}", symbols) for n in names]

    def tables(self, doc: Mapping[str, Any], taken: set[str]) -> dict[str, Table]:
        """[tables.NAME]: measured characteristics, called as NAME(x) or NAME(x, z) in any expression."""
        out = {}
        for name, spec in self.table(doc, "tables").items():
            key = f"tables.{name}"
            if not _NAME.fullmatch(name) or name in RESERVED or name in FUNCTIONS or name in CONSTANTS:
                raise self.err("a table's name is an identifier that is not a function or reserved name", key, name)
            if name in taken:
                raise self.err(f"`{name}` is already a state, input, output or parameter", key, name)
            if not isinstance(spec, dict):
                raise self.err("must be a table with x and y (and z for a 2-D table)", key, spec)
            try:
                out[name] = parse_table(name, spec)
            except ModelError as e:
                raise self.err(str(e).removeprefix(f"table `{name}`: "), key) from None
        return out

    def units(self, doc: Mapping[str, Any], system: System) -> dict[str, str]:
        allowed = (*system.states, *system.inputs, *system.outputs, *system.params, "t")
        out = {}
        for k, v in self.table(doc, "units").items():
            if k not in allowed:
                raise self.err(f"`{shorten(k, 40)[1:-1]}` is not a state, input, output, parameter or t",
                               f"units.{k}")
            out[k] = self.label(v, f"units.{k}", "unit", 40)
        return out

    def simulation(self, doc: Mapping[str, Any], system: System, definitions: Mapping[str, sp.Expr],
                   unknown_params: tuple[str, ...] = ()) -> SimulationConfig:
        sim = self.table(doc, "simulation")
        unknown = [k for k in sim if k not in _SIM]
        if unknown:
            raise self.err(f"unknown key; allowed: {', '.join(_SIM)}", f"simulation.{unknown[0]}")
        out: dict[str, Any] = {}
        for k in ("t_final", "dt", "sample_period"):
            if k in sim and not (k == "sample_period" and isinstance(sim[k], Mapping)):
                out[k] = self.number(sim[k], f"simulation.{k}", positive=True)
        if isinstance(sim.get("sample_period"), Mapping):   # one clock per output: { y = 0.01, gps = 1.0 }
            periods = {}
            for k, v in sim["sample_period"].items():
                if k not in system.outputs:
                    raise self.err(f"`{shorten(k, 40)[1:-1]}` is not an output; outputs: {shorten_list(system.outputs)}",
                                   f"simulation.sample_period.{k}")
                periods[k] = self.number(v, f"simulation.sample_period.{k}", positive=True)
            missing = [k for k in system.outputs if k not in periods]
            if missing:
                raise self.err(f"no period for {', '.join(missing)}: give one per output ({shorten_list(system.outputs)}), or "
                               "one number for all", "simulation.sample_period")
            out["sample_period"] = MappingProxyType(periods)
        if not system.is_discrete and "dt" in out and "sample_period" in out:  # at once, not at the run's first sample
            sp_ = out["sample_period"]
            for key, period in ({f"sample_period.{k}": v for k, v in sp_.items()} if isinstance(sp_, Mapping)
                                else {"sample_period": sp_}).items():
                why = period_multiple_problem(period, out["dt"])
                if why:
                    raise self.err(why, f"simulation.{key}", period)
        if system.is_discrete:
            for k in ("dt", "sample_period"):
                if k in out:
                    raise self.err(f"a discrete-time model steps by its `sample_time` ({system.sample_time:g} s) and is measured "
                                   f"at every step; remove `{k}`", f"simulation.{k}", sim[k])
            if "t_final" in out:
                steps = out["t_final"] / system.sample_time
                if abs(steps - round(steps)) > 1e-9 * max(1.0, steps):
                    raise self.err(f"must be a whole number of steps of sample_time = {system.sample_time:g} s (here "
                                   f"{steps:.6g} steps); e.g. t_final = {round(steps) * system.sample_time:g}",
                                   "simulation.t_final", sim["t_final"])
        if "x0" in sim:
            x0 = sim["x0"]
            if not isinstance(x0, list) or len(x0) != system.n_states:
                raise self.err(f"must be a list of {system.n_states} numbers (one per state: {shorten_list(system.states)})",
                               "simulation.x0", x0)
            out["x0"] = tuple(self.number(v, "simulation.x0") for v in x0)
        if "seed" in sim:
            seed = sim["seed"]
            if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
                raise self.err("must be a non-negative integer (below 2**63)", "simulation.seed", seed)
            out["seed"] = seed
        true = {}
        for k, v in self.table(sim, "simulation.true_parameters").items():
            if k not in system.params:
                raise self.err(f"`{shorten(k, 40)[1:-1]}` is not a parameter; parameters: {shorten_list(system.params)}",
                               f"simulation.true_parameters.{k}")
            true[k] = self.number(v, f"simulation.true_parameters.{k}")
        out["true_parameters"] = MappingProxyType(true)
        initial = {}
        for k, v in self.table(sim, "simulation.initial_std").items():
            key = f"simulation.initial_std.{k}"
            if k in system.params and k not in unknown_params:
                raise self.err(f"`{shorten(k, 40)[1:-1]}` is a known parameter: an initial uncertainty applies to the states and "
                               f"to parameters declared unknown ({k} = {{ value = ..., unknown = true }} in [parameters])", key)
            if k not in system.states and k not in unknown_params:
                raise self.err(f"`{shorten(k, 40)[1:-1]}` is not a state or an unknown parameter; states: "
                               f"{shorten_list(system.states)}" + (f"; unknown parameters: {shorten_list(unknown_params)}"
                                                                   if unknown_params else ""), key)
            initial[k] = self.number(v, key, positive=True)
        out["initial_std"] = MappingProxyType(initial)
        # inputs are signals of time: t, the parameters and the definitions built from those only
        base = {"t", *system.params}
        sym_t: dict[str, sp.Expr] = {"t": TIME, **{k: symbol(k) for k in system.params}}
        sym_t.update({k: e for k, e in definitions.items() if {s.name for s in e.free_symbols} <= base})
        inputs = {}
        for k, v in self.table(sim, "simulation.inputs").items():
            key = f"simulation.inputs.{k}"
            if k not in system.inputs:
                raise self.err(f"`{shorten(k, 40)[1:-1]}` is not an input; inputs: {shorten_list(system.inputs)}", key)
            if isinstance(v, str):
                bad = sorted((_names_in(v) & set(definitions)) - set(sym_t))
                if bad:
                    raise self.err(f"the definition `{bad[0]}` depends on states or inputs; an input signal may use only t, "
                                   "the parameters and definitions built from those", key, v)
            inputs[k] = self.expr(v, key, sym_t)
        out["inputs"] = MappingProxyType(inputs)
        for key, names in (("noise", system.outputs), ("noise_bound", system.outputs),
                           ("process_noise", [*system.states, *unknown_params]), ("delay", system.outputs)):
            values = {}
            for k, v in self.table(sim, f"simulation.{key}").items():
                if key == "process_noise" and k in system.params and k not in unknown_params:
                    raise self.err(f"`{shorten(k, 40)[1:-1]}` is a known parameter: a random walk applies to the states and to "
                                   f"parameters declared unknown ({k} = {{ value = ..., unknown = true }} in [parameters])",
                                   f"simulation.{key}.{k}")
                if k not in names:
                    raise self.err(f"`{shorten(k, 40)[1:-1]}` is not one of {shorten_list(names)}"
                                   + (" (the states and the unknown parameters)" if key == "process_noise" else ""),
                                   f"simulation.{key}.{k}")
                values[k] = self.number(v, f"simulation.{key}.{k}")
                if values[k] < 0:
                    raise self.err("must be non-negative", f"simulation.{key}.{k}", v)
            out[key] = MappingProxyType(values)
        both = set(out["noise"]) & set(out["noise_bound"])
        if both:
            raise self.err("an output has both Gaussian `noise` and uniform `noise_bound`; choose one", f"simulation.noise.{sorted(both)[0]}")
        return SimulationConfig(**out)

    def observers(self, doc: Mapping[str, Any], definitions: Mapping[str, sp.Expr], system: System,
                  guesses: Mapping[str, float]) -> Mapping[str, ObserverConfig]:
        out = {}
        for name, table in self.table(doc, "observers").items():
            key = f"observers.{name}"
            if not _OBSERVER_NAME.fullmatch(name):
                raise self.err("an observer's name starts with a letter and has at most 60 letters, digits, `_` or `-` "
                               "(it becomes a column name, a JSON key and a file name)", key, name)
            if not isinstance(table, dict):
                raise self.err("must be a table with at least `kind`", key, table)
            kind = table.get("kind")
            if not isinstance(kind, str):
                raise self.err("`kind` is required and must be a string (e.g. \"ekf\", \"luenberger\")", f"{key}.kind", kind if kind is not None else "")
            options = {k: self.with_definitions(v, definitions, f"{key}.{k}") for k, v in table.items() if k != "kind"}
            out[name] = ObserverConfig(name, kind, MappingProxyType(options), system, MappingProxyType(dict(guesses)))
        return MappingProxyType(out)

    def sensors(self, doc: Mapping[str, Any], symbols: Mapping[str, sp.Expr],
                dt: float | None = None) -> Mapping[str, SensorConfig]:
        """[sensors.NAME]: candidate sensors (expr, noise, optional cost) for ``nlobs sensors``."""
        if "sensors" not in doc:
            return MappingProxyType({})
        table = self.table(doc, "sensors")
        if not table:
            raise self.err("declares no candidate sensor; add [sensors.NAME] tables with `expr` and `noise`, or remove "
                           "[sensors] to use the default pool (every state and every output)", "sensors")
        out = {}
        for name, spec in table.items():
            key = f"sensors.{name}"
            if not _NAME.fullmatch(name):
                raise self.err("a sensor's name starts with a letter and contains only letters, digits and underscores "
                               "(it becomes a JSON key and a column name)", key, name)
            if not isinstance(spec, dict):
                raise self.err("must be a table with `expr` and `noise` (and optionally `cost`), e.g. "
                               "[sensors.NAME] expr = \"x1\" noise = 0.01", key, spec)
            extra = [k for k in spec if k not in _SENSOR_KEYS]
            if extra:
                raise self.err(f"unknown key `{shorten(extra[0], 40)[1:-1]}`; a sensor table has `expr`, `noise` and "
                               "optionally `cost` and `period`", f"{key}.{extra[0]}")
            for k in ("expr", "noise"):
                if k not in spec:
                    what = ("what it measures (an expression of the states, inputs, parameters and t)" if k == "expr" else
                            "the standard deviation of its measurement noise (a positive number)")
                    raise self.err(f"`{k}` is required: {what}", key)
            expr = self.expr(spec["expr"], f"{key}.expr", symbols)
            noise = self.number(spec["noise"], f"{key}.noise")
            if noise <= 0:
                raise self.err("must be positive (the standard deviation of the sensor's noise; a perfect sensor has no "
                               "finite bound)", f"{key}.noise", spec["noise"])
            cost = self.number(spec.get("cost", 1.0), f"{key}.cost")
            if cost < 0:
                raise self.err("must be non-negative", f"{key}.cost", spec["cost"])
            period = self.number(spec["period"], f"{key}.period", positive=True) if "period" in spec else None
            why = period_multiple_problem(period, dt) if period is not None and dt else ""
            if why:  # at once, as the [simulation] sample periods
                raise self.err(why, f"{key}.period", spec["period"])
            text = spec["expr"] if isinstance(spec["expr"], str) else repr(spec["expr"])
            out[name] = SensorConfig(name, expr, noise, cost, text, period)
        return MappingProxyType(out)

    def with_definitions(self, value: Any, definitions: Mapping[str, sp.Expr], key: str) -> Any:
        """An option value with every string that mentions a definition parsed, the definitions substituted
        (other names stay symbols, for the design to check); everything else unchanged."""
        if isinstance(value, list):
            return [self.with_definitions(v, definitions, key) for v in value]
        if isinstance(value, dict):
            return {k: self.with_definitions(v, definitions, key) for k, v in value.items()}
        if not isinstance(value, str) or not definitions:
            return value
        names = _names_in(value)
        if not names & set(definitions):
            return value
        symbols = {n: symbol(n) for n in names if n not in FUNCTIONS and n not in CONSTANTS}
        symbols.update(definitions)
        symbols["t"] = TIME
        return self.expr(value, key, symbols)


def library() -> tuple[LibraryEntry, ...]:
    """Every bundled model, parsed (so a broken bundled file fails loudly here, not in a user's session)."""
    out = []
    for name in bundled_names():
        mf = load_model(bundled_folder() / f"{name}.toml")
        s = mf.system
        out.append(LibraryEntry(name, mf.description, s.states, s.inputs, s.outputs, mf.path))
    return tuple(out)
