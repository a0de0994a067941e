"""The registry of observer kinds: the one place that knows which kinds exist.

Each design module declares its kind next to its design function::

    @kind("ekf", summary="extended Kalman filter (continuous-discrete, Joseph form)",
          references=(("kalman1961", ""),), tune=tune_ekf)
    def design_ekf(system, *, Q, R, P0=None, ...) -> ObserverDesign: ...

:data:`KINDS` then feeds everything that lists or tries kinds: model files (``[observers.NAME] kind = "ekf"``,
:func:`~nlobs.design.design_from_config`), ``nlobs kinds``, the advisor's trials, the public re-exports
(``nlobs.design_ekf``), the docs' list of kinds and the conformance test. Adding a kind is one design module
(imported in ``design/__init__.py``) and one conformance case (``tests/conformance/test_designs.py``).

A kind may carry two optional functions of the advisor's context (duck-typed: this layer never imports the advisor;
:class:`TuningContext` lists what a context offers):

- ``precheck(context) -> (ok, why)``: a quick refusal built from the design's own checks (the public functions the
  design itself calls), for when designing would take long only to refuse;
- ``tune(context) -> Tuning``: options chosen from the model and its nominal run, with the reasons; a tuning that
  finds the kind does not apply returns ``Tuning.fails(why)``, one that needs what only the user knows
  ``Tuning.needs(what)``.
"""

from __future__ import annotations

import functools
import inspect
import types
import typing
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

from .._deprecate import renamed
from .._deprecate import warn_renamed as _warn_renamed
from .._text import shorten
from ..model import System
from ..model._budget import symbolic_budget
from ..references import cite

__all__ = ["Kind", "KINDS", "kind", "renamed", "Tuning", "TuningContext", "requires_model", "options_of", "register_design",
           "DesignsView", "TIME_BASES"]

#: The time bases a kind can run on: "continuous" (ẋ = f), "discrete" (x[k+1] = f) or "both".
TIME_BASES = ("continuous", "discrete", "both")


class TuningContext(Protocol):
    """What the advisor's context offers a kind's ``precheck`` and ``tune`` (see ``nlobs.advise._context.Context``)."""

    system: System            # the system the observer is designed on (unknown parameters appended as states)
    report: Any               # nlobs.analysis.ObservabilityReport of `system`
    nominal: Any              # the nominal run (nlobs.Run) or None without [simulation] x0
    scenario: Any             # the run's settings (t_final, dt, sample_period, inputs) or None
    region: dict[str, tuple[float, float]]   # the box the run visits (states, inputs, outputs), {} without a run
    xhat0: Any                # the initial estimate the comparison uses
    Q: Any                    # process-noise covariance per unit time, from the run's scales
    R: Any                    # measurement-noise covariance per sample
    R_rate: Any               # R as an intensity (R · sample period)
    P0: Any                   # initial covariance from the offset of x̂(0)
    omega_p: float            # the plant's fastest rate on the run (rad/s)
    omega_o: float            # the observer's target rate (3 ω_p)
    rate_unit: str            # how a rate is written in the model's time unit ("s⁻¹", "h⁻¹")
    noise_note: str           # how Q and R were chosen, as a user reads it
    uco: dict[str, Any] | None

    @property
    def n(self) -> int: ...

    @property
    def p(self) -> int: ...

    @property
    def output_gain(self) -> float: ...

    def step_limit(self) -> float: ...

    def samples(self, count: int = 200) -> dict[str, Any]: ...

    def form(self, prefix: str) -> tuple[bool, str]: ...

    def riccati_weights(self, W: Any, M0: Any, Q: Any, C: Any = None, CA: Any = None) -> tuple[Any, Any, str]: ...

    def jacobians(self, count: int = 300) -> Any: ...


@dataclass(frozen=True)
class Tuning:
    """What a kind's ``tune`` found: options for its design and why; or why the kind does not apply, or what it needs.

    `status` is "tuned" (design it with `options`), "fails" (the kind does not apply: `why` names the condition) or
    "needs input" (what only the user can give: `why`; `options` shows the keys to fill in). `runnable` False keeps a
    tuned design out of the advisor's comparison run (too costly there; `extra` says why). `choice` (a one-line note)
    and `choice_reason` are set when a rule marks this kind as *the* choice for the model; of several such rules the
    one with the highest `choice_rank` wins (a multimodal posterior, 2, outweighs a tiny R, 1).
    """

    status: Literal["tuned", "fails", "needs input"]
    options: dict[str, Any] = field(default_factory=dict)
    why: str = ""
    runnable: bool = True
    extra: str = ""
    choice: str = ""
    choice_reason: str = ""
    choice_rank: int = 0

    @classmethod
    def tuned(cls, options: Mapping[str, Any], why: str, *, runnable: bool = True, extra: str = "", choice: str = "",
              choice_reason: str = "", choice_rank: int = 1) -> Tuning:
        return cls("tuned", dict(options), why, runnable, extra, choice, choice_reason, choice_rank if choice else 0)

    @classmethod
    def fails(cls, why: str, **options: Any) -> Tuning:
        return cls("fails", options, why)

    @classmethod
    def needs(cls, what: str, **options: Any) -> Tuning:
        return cls("needs input", options, f"needs input: {what}")


def options_of(fn: Callable[..., Any]) -> tuple[str, ...]:
    """The keyword-only tuning options a design function accepts."""
    return tuple(n for n, p in inspect.signature(fn).parameters.items() if p.kind is inspect.Parameter.KEYWORD_ONLY)


@dataclass(frozen=True)
class Kind:
    """One observer kind: its name in model files, its design function and what is known about it."""

    name: str
    design: Callable[..., Any]                       # the public design function, wrapped once (requires_model)
    summary: str                                     # one line, as `nlobs kinds` shows it
    references: tuple[tuple[str, str], ...] = ()     # (key in nlobs.references, place in the work)
    time_base: str = "continuous"
    precheck: Callable[[Any], tuple[bool, str]] | None = None
    tune: Callable[[Any], Tuning] | None = None
    map_smoother: str = ""                           # on a map: "extended" or "unscented" RTS smoother, "" none
    likelihood: str = ""                             # the filter whose innovations likelihood tunes its Q, R ("" none)

    @property
    def options(self) -> dict[str, Any]:
        """The design's keyword-only options and their defaults (``inspect.Parameter.empty`` when required)."""
        sig = inspect.signature(self.design)
        return {n: p.default for n, p in sig.parameters.items() if p.kind is inspect.Parameter.KEYWORD_ONLY}

    @property
    def citation(self) -> str:
        """The works this kind implements, as a user reads them (authors, year, place)."""
        return "; ".join(cite(k, where) for k, where in self.references) if self.references else ""

    @property
    def reference_keys(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(k for k, _ in self.references))

    @property
    def renamed(self) -> dict[str, str]:
        """Old option names still accepted for one release: old -> new."""
        return dict(getattr(self.design, "_nlobs_renamed", {}))

    def runs_on(self, time_base: str) -> bool:
        return self.time_base in ("both", time_base)


#: Every observer kind, by the name model files use (filled by the design modules' ``@kind`` declarations).
KINDS: dict[str, Kind] = {}


def kind(name: str, *, summary: str, references: tuple[tuple[str, str], ...] = (), time_base: str = "continuous",
         precheck: Callable[[Any], tuple[bool, str]] | None = None,
         tune: Callable[[Any], Tuning] | None = None,
         map_smoother: str = "", likelihood: str = "") -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Declare the observer kind `name`, designed by the decorated function (returned wrapped by
    :func:`requires_model`, so ``nlobs.design_x`` and ``KINDS["x"].design`` are the same object).

    Parameters
    ----------
    name : str
        The kind as model files write it (``[observers.NAME] kind = "name"``).
    summary : str
        One line for ``nlobs kinds``.
    references : tuple of (key, place)
        The works the kind implements: keys of :data:`nlobs.references.REFERENCES` and a place in the work
        (a proposition, an equation; "" for the whole work).
    time_base : {"continuous", "discrete", "both"}
        The models it runs on; the advisor refuses the others with this reason.
    precheck : callable, optional
        ``precheck(context) -> (ok, why)``: a quick refusal from the design's own checks.
    tune : callable, optional
        ``tune(context) -> Tuning``: options from the model and its run (the advisor's automatic tuning).
    map_smoother : {"", "extended", "unscented"}
        On a discrete-time model, the fixed-interval smoother of the kind's run: the extended RTS smoother (the kind
        predicts as the EKF does) or the unscented one (it predicts by sigma points); "" when it has none.
    likelihood : {"", "ekf", "ukf"}
        The filter whose innovations likelihood :func:`nlobs.tune` (and ``design --run``) fits this kind's Q and R
        with ("" when they are not tuned from data).
    """
    if time_base not in TIME_BASES:
        raise ValueError(f"kind {name!r}: time_base must be one of {', '.join(TIME_BASES)}, got {time_base!r}")
    if any(not (isinstance(r, tuple) and len(r) == 2) for r in references):
        raise ValueError(f"kind {name!r}: references must be a tuple of (key, place) pairs, e.g. (work('kalman1961'),)")
    if map_smoother not in ("", "extended", "unscented"):
        raise ValueError(f"kind {name!r}: map_smoother must be '', 'extended' or 'unscented', got {map_smoother!r}")
    if name in KINDS:
        raise ValueError(f"observer kind {name!r} is declared twice ({KINDS[name].design.__module__} and another module)")

    def register(fn: Callable[..., Any]) -> Callable[..., Any]:
        wrapped = requires_model(fn, time_base=time_base)
        KINDS[name] = Kind(name, wrapped, summary, tuple(references), time_base, precheck, tune, map_smoother, likelihood)
        return wrapped

    return register


def register_design(name: str, fn: Callable[..., Any], *, summary: str = "", time_base: str = "continuous") -> None:
    """Make your own design function `fn` available to model files and the advisor under the kind `name`
    (without an automatic tuning: the advisor lists it as "not tuned" unless the file gives its options).

    `summary` defaults to the first paragraph of `fn`'s docstring; `time_base` is "continuous", "discrete" or "both".
    """
    first = (inspect.getdoc(fn) or "").strip().split("\n\n")[0].replace("\n", " ")
    KINDS.pop(name, None)
    kind(name, summary=summary or first or f"your design function {fn.__name__}", time_base=time_base)(fn)


class DesignsView(Mapping[str, Callable[..., Any]]):
    """The design function of each kind (``DESIGNS["ekf"] is nlobs.design_ekf``): a live, read-only view of
    :data:`KINDS`, kept for code written against the older dictionary (``del DESIGNS[name]`` unregisters)."""

    def __getitem__(self, name: str) -> Callable[..., Any]:
        return KINDS[name].design

    def __iter__(self) -> Iterator[str]:
        return iter(KINDS)

    def __len__(self) -> int:
        return len(KINDS)

    def __delitem__(self, name: str) -> None:
        del KINDS[name]

    def __repr__(self) -> str:
        return f"DESIGNS({', '.join(KINDS)})"


# -- one TypeError for every design function ---------------------------------------------------
def _model_types(fn: Callable[..., Any]) -> tuple[type, ...]:
    """The classes the first parameter of `fn` is annotated with (System, StateAffine, LinearRegression, ...)."""
    first = next(iter(inspect.signature(fn).parameters))
    try:
        hint = typing.get_type_hints(fn).get(first, System)
    except Exception:  # noqa: BLE001 - an unresolvable annotation: fall back to System
        hint = System
    members = typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType) else (hint,)
    return tuple(m for m in members if isinstance(m, type)) or (System,)


def requires_model(fn: Callable[..., Any], *, time_base: str = "both") -> Callable[..., Any]:
    """Wrap a design function so that a first argument of the wrong type is one clear TypeError
    (instead of an AttributeError deep inside), a model of another time base than `time_base` is refused (a
    discrete-time map is never designed on as if it were an ODE), and its symbolic work runs within the budget of
    :func:`nlobs.model.symbolic_budget`. A function already wrapped is returned as it is.

    `fn` is the design function (its first parameter the model); `time_base` is "continuous", "discrete" or "both".
    """
    if getattr(fn, "_nlobs_checked", False):
        return fn
    allowed = _model_types(fn)
    first = next(iter(inspect.signature(fn).parameters))
    missing = object()

    old_first = [old for old, new in getattr(fn, "_nlobs_renamed", {}).items() if new == first]

    @functools.wraps(fn)
    def checked(model: Any = missing, /, *args: Any, **kwargs: Any) -> Any:
        if model is missing and first not in kwargs and old_first and old_first[0] in kwargs:
            _warn_renamed(fn.__name__, old_first[0], first)
            kwargs[first] = kwargs.pop(old_first[0])
        if model is missing:
            if first not in kwargs:
                raise TypeError(f"{fn.__name__}: the model (`{first}`) is required")
            model = kwargs.pop(first)
        if not isinstance(model, allowed):
            names = " or ".join(f"nlobs.{t.__name__}" for t in allowed)
            hint = ""
            if type(model).__name__ == "ModelFile":
                hint = " (for a model file, pass `model.observer_system`, or use nlobs.design.designs_from_file(model))"
            elif isinstance(model, str):
                hint = " (to read a model file, use nlobs.load_model(path) and pass its `.observer_system`)"
            raise TypeError(f"{fn.__name__}: the model must be an {names}, got {type(model).__name__} "
                            f"{shorten(model, 40)}{hint}")
        base = getattr(model, "time", "continuous")
        if time_base != "both" and base != time_base:
            from ..errors import PreconditionError

            other = [k.name for k in KINDS.values() if k.runs_on(base)]
            raise PreconditionError(f"{fn.__name__}: {time_base}-time only, and {getattr(model, 'name', 'the model')!r} is a "
                                    f"{base}-time model ({'x[k+1] = f(x[k], ...)' if base == 'discrete' else 'ẋ = f(x, ...)'}); "
                                    f"kinds for {base}-time models: {', '.join(other) or 'none yet'}")
        with symbolic_budget(fn.__name__):
            return fn(model, *args, **kwargs)

    checked._nlobs_checked = True  # type: ignore[attr-defined]
    return checked
