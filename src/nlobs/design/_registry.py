"""Observer kinds by name, for model files (``[observers.NAME] kind = "..."``), the CLI and the API.

A model file and the API meet here (the ``model`` layer cannot import designs):

- :func:`design_from_config` designs one :class:`~nlobs.model.ObserverConfig` (or a system, a
  kind and options);
- :func:`designs_from_file` designs all (or some) observers of a :class:`~nlobs.model.ModelFile`,
  after checking that its unknown parameters are identifiable;
- :func:`requires_model` gives every public design function one clear TypeError when it is
  called with something that is not a model.

With unknown parameters (``[parameters] k = { value = 0.3, unknown = true }``) the observers are
designed on the augmented system (k appended to the state, :meth:`nlobs.System.augmented`); the
default initial estimate x̂0 ends with the parameters' initial guesses, and an x̂0 given for the
plant's states only is completed with them.
"""

from __future__ import annotations

import functools
import inspect
import types
import typing
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .._text import shorten, shorten_list
from ..analysis import analyze
from ..errors import ModelError, PreconditionError
from ..model import ObserverConfig, System
from ..model._budget import symbolic_budget
from ..references import cite
from ._augmented import design_augmented
from ._banks import design_banks
from ._base import ObserverDesign
from ._custom import design_custom
from ._ekf import design_ekf
from ._high_gain import design_high_gain, design_high_gain_derivatives
from ._kalman import design_high_gain_kalman, design_kalman_bucy, design_kalman_like
from ._linear import design_luenberger, design_output_injection
from ._lipschitz import design_lipschitz
from ._mhe import design_mhe
from ._ukf import design_ukf
from ._srukf import design_srukf
from ._srekf import design_srekf
from ._iekf import design_iekf
from ._pf import design_pf

__all__ = ["DESIGNS", "register_design", "design_from_config", "designs_from_file", "check_identifiable", "requires_model"]

#: Design functions by the ``kind`` used in model files.
DESIGNS: dict[str, Callable[..., ObserverDesign]] = {
    "luenberger": design_luenberger,
    "output_injection": design_output_injection,
    "ekf": design_ekf,
    "augmented": design_augmented,
    "custom": design_custom,
    "high_gain": design_high_gain,
    "high_gain_derivatives": design_high_gain_derivatives,
    "lipschitz": design_lipschitz,
    "kalman_bucy": design_kalman_bucy,
    "kalman_like": design_kalman_like,
    "high_gain_kalman": design_high_gain_kalman,
    "banks": design_banks,
    "ukf": design_ukf,
    "mhe": design_mhe,
    "srukf": design_srukf,
    "srekf": design_srekf,
    "iekf": design_iekf,
    "pf": design_pf,
}


def register_design(kind: str, fn: Callable[..., ObserverDesign]) -> None:
    """Make a design function `fn` available to model files under the name `kind`."""
    DESIGNS[kind] = requires_model(fn)


def options_of(fn: Callable[..., Any]) -> tuple[str, ...]:
    """The keyword-only tuning options a design function accepts."""
    return tuple(n for n, p in inspect.signature(fn).parameters.items() if p.kind is inspect.Parameter.KEYWORD_ONLY)


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


_WRAPPED: dict[Callable[..., Any], Callable[..., Any]] = {}


def requires_model(fn: Callable[..., ObserverDesign]) -> Callable[..., ObserverDesign]:
    """Wrap a design function so that a first argument of the wrong type is one clear TypeError
    (instead of an AttributeError deep inside), and its symbolic work runs within the budget of
    :func:`nlobs.model.symbolic_budget`."""
    if getattr(fn, "_nlobs_checked", False):
        return fn
    if fn in _WRAPPED:  # one wrapper per function, so nlobs.design_x is DESIGNS["x"]
        return _WRAPPED[fn]
    allowed = _model_types(fn)
    first = next(iter(inspect.signature(fn).parameters))
    missing = object()

    @functools.wraps(fn)
    def checked(model: Any = missing, /, *args: Any, **kwargs: Any) -> ObserverDesign:
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
        with symbolic_budget(fn.__name__):
            return fn(model, *args, **kwargs)

    checked._nlobs_checked = True  # type: ignore[attr-defined]
    _WRAPPED[fn] = checked
    return checked


# -- options as a file writes them ----------------------------------------------------------
def _wants_sequence_not_string(fn: Callable[..., Any], option: str) -> bool:
    """Whether the annotation of `option` accepts a sequence but not a bare string (so "x1" means ["x1"])."""
    try:
        hint = typing.get_type_hints(fn).get(option)
    except Exception:  # noqa: BLE001 - unresolvable annotation: leave the value alone
        return False
    if hint is None:
        return False
    members = typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType) else (hint,)
    if any(m is Any or m is str or typing.get_origin(m) is typing.Literal for m in members):
        return False
    import collections.abc as cabc

    return any(typing.get_origin(m) in (list, tuple, cabc.Sequence) for m in members)


def _converted(fn: Callable[..., Any], options: Mapping[str, Any]) -> dict[str, Any]:
    """Options as the design function takes them: a single string where a list is expected becomes a
    one-element list (``perturbation = "x1"`` is ``["x1"]``, not the characters 'x' and '1')."""
    return {k: [v] if isinstance(v, str) and _wants_sequence_not_string(fn, k) else v for k, v in options.items()}


def _with_guesses(system: System, options: dict[str, Any], guesses: Mapping[str, float], accepted: Sequence[str],
                  prefix: str) -> dict[str, Any]:
    """x̂0 for an augmented system: the plant part (given, else zeros) followed by the parameters' guesses."""
    est = system.estimated_params
    if not est or "xhat0" not in accepted:
        return options
    n_plant = system.n_states - len(est)
    tail = [float(guesses.get(k, 0.0)) for k in est]
    given = options.get("xhat0")
    if given is None:
        return {**options, "xhat0": [0.0] * n_plant + tail}
    try:
        v = np.asarray(given, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        return options  # the design reports the bad value
    if v.size == n_plant:
        return {**options, "xhat0": [*v.tolist(), *tail]}
    if v.size != system.n_states:
        raise ModelError(f"{prefix}`xhat0` has {v.size} entries; give {n_plant} (the states "
                         f"{shorten_list(system.states[:n_plant])}; the initial guesses of {', '.join(est)} are appended) "
                         f"or {system.n_states} (states and parameters)")
    return options


# -- identifiability of unknown parameters ----------------------------------------------------
_IDENT_CACHE: OrderedDict[Any, tuple[tuple[str, ...], str]] = OrderedDict()


def check_identifiable(system: System, *, inputs: Any = "generic", where: str = "") -> None:
    """Refuse to estimate parameters that the outputs cannot determine, before any estimation runs.

    `system` is an augmented system (:meth:`nlobs.System.augmented`); its
    :attr:`~nlobs.System.estimated_params` must be locally identifiable by the structural test of
    :func:`nlobs.analyze` (generic rank of the output jets) for the `inputs` given (``"generic"``,
    or a mapping ``{input: expression of t}`` for a simulation's inputs). `where` (a file, an
    observer) starts the message.

    Raises
    ------
    PreconditionError
        Naming each parameter that is not identifiable, the rank, and the unidentifiable direction.
    """
    est = system.estimated_params
    if not est:
        return
    key = (system.key, tuple(system.params.items()), repr(inputs))
    if key not in _IDENT_CACHE:
        report = analyze(system, inputs=inputs, symmetries=False)
        bad = tuple(k for k in est if k not in report.observable_states)
        detail = ""
        if bad:
            dirs = []
            for v in report.unobservable_directions[:2]:
                moved = [f"{n}" for n, c in zip(report.unknowns, v) if np.isfinite(c) and abs(c) > 1e-6]
                if moved:
                    dirs.append(" and ".join(moved) if len(moved) > 1 else f"{moved[0]} alone")
            inputs_text = "generic inputs" if inputs == "generic" else f"the inputs {report.inputs}"
            detail = (f"structural test ({cite('002')}, generic rank) with {inputs_text}: rank {report.rank} for "
                      f"{len(report.unknowns)} unknowns (the states and the unknown parameters)"
                      + (f"; the output does not change when {'; or when '.join(dirs)} "
                         f"{'change' if len(dirs) > 1 or ' and ' in dirs[0] else 'changes'} along the unidentifiable "
                         f"direction{'s' if len(dirs) > 1 else ''}" if dirs else ""))
        _IDENT_CACHE[key] = (bad, detail)
        if len(_IDENT_CACHE) > 64:
            _IDENT_CACHE.popitem(last=False)
    bad, detail = _IDENT_CACHE[key]
    if bad:
        prefix = f"{where}: " if where else ""
        which = ", ".join(f"`{k}`" for k in bad)
        many = len(bad) > 1
        raise PreconditionError(
            f"{prefix}the unknown parameter{'s' if many else ''} {which} {'are' if many else 'is'} not identifiable from "
            f"the output{'s' if len(system.outputs) > 1 else ''} {', '.join(system.outputs)} — {detail}. No observer can "
            f"estimate {'them' if many else 'it'}; nothing was run. Fix {'one of them' if many else 'its value'} (drop "
            "`unknown = true`), measure another output, or excite the system with other inputs")


# -- model files ------------------------------------------------------------------------------
def design_from_config(system: System | ObserverConfig, kind: str | None = None, options: Mapping[str, Any] | None = None,
                       *, where: str = "") -> ObserverDesign:
    """Run the design `kind` on `system` with the `options` of a model file; or design an
    :class:`~nlobs.model.ObserverConfig` (``design_from_config(model.observers["ekf"])``).

    Options are taken as a file writes them: a string where the design wants a list is a
    one-element list. On an augmented system (unknown parameters), the default x̂0 ends with the
    parameters' initial guesses (an x̂0 for the plant's states only is completed with them), and
    the parameters' identifiability is checked first (:func:`check_identifiable`).

    Raises
    ------
    ModelError
        For an unknown kind or option (listing the allowed ones).
    PreconditionError
        For unknown parameters that are not identifiable; the design's own errors
        (PreconditionError, ShapeError) pass through with `where` prepended.
    TypeError
        If `system` is neither a System nor an ObserverConfig with a system.
    """
    guesses: Mapping[str, float] = {}
    if isinstance(system, ObserverConfig):
        config = system
        if config.system is None:
            raise TypeError(f"design_from_config: the ObserverConfig {config.name!r} has no system; "
                            "load it from a model file (load_model) or give the system")
        system, kind, options, guesses = config.system, config.kind, config.options, config.guesses
        where = where or f"observers.{config.name}"
    if not isinstance(system, System):
        raise TypeError(f"design_from_config: expected an nlobs.System or an ObserverConfig, got {type(system).__name__}")
    if kind is None or options is None:
        raise TypeError("design_from_config: give `kind` and `options` with a System (or pass an ObserverConfig)")
    prefix = f"{where}: " if where else ""
    if kind not in DESIGNS:
        raise ModelError(f"{prefix}unknown observer kind {shorten(kind, 40)}; available: {', '.join(sorted(DESIGNS))}")
    fn = DESIGNS[kind]
    allowed = options_of(fn)
    unknown = [k for k in options if k not in allowed]
    if unknown:
        raise ModelError(f"{prefix}unknown option `{shorten(unknown[0], 40)[1:-1]}` for kind {kind!r}; "
                         f"{fn.__name__} accepts: {', '.join(allowed)}")
    opts = _with_guesses(system, _converted(fn, options), guesses, allowed, prefix)
    check_identifiable(system, where=where)
    try:
        with symbolic_budget(f"{prefix}{fn.__name__}"):
            return fn(system, **opts)
    except (ValueError, TypeError) as e:
        raise type(e)(f"{prefix}{e}") from e


def designs_from_file(model_file: Any, names: Sequence[str] | None = None) -> dict[str, ObserverDesign]:
    """The designs of the observers `names` configured in `model_file` (all when `names` is empty).

    Parameters
    ----------
    model_file : nlobs.model.ModelFile
        A loaded file (:func:`nlobs.load_model`).
    names : sequence of str, optional
        Observer names (``[observers.NAME]``); default: all, in file order.

    Returns
    -------
    dict of name to ObserverDesign
        Designed on :attr:`~nlobs.model.ModelFile.observer_system` (the unknown parameters
        appended to the state), ready for :func:`nlobs.simulate` and :func:`nlobs.estimate`.

    Raises
    ------
    KeyError
        For a name the file does not configure.
    PreconditionError
        If an unknown parameter is not identifiable (before anything is designed).
    """
    configured = model_file.observers
    if isinstance(names, str):
        names = [names]
    if names:
        unknown = [n for n in names if n not in configured]
        if unknown:
            raise KeyError(f"{model_file.path}: no observer {shorten(unknown[0], 40)}; configured: "
                           f"{shorten_list(configured)}")
    check_identifiable(model_file.observer_system, where=model_file.path)
    chosen = list(names) if names else list(configured)
    return {n: design_from_config(configured[n], where=f"{model_file.path}: observers.{n}") for n in chosen}

# Parameter-estimation based observers and estimators (000, 004)
from ._cascade import design_kkl_pebo_cascade  # noqa: E402
from ._gpebo import design_2gd, design_gpebo  # noqa: E402
from ._iandi import design_iandi  # noqa: E402
from ._kkl import design_kkl_learned  # noqa: E402
from ._pebo import design_kkl, design_kkl_pebo, design_pebo  # noqa: E402
from ._regression import design_drem, design_gd, design_gradient, design_least_squares  # noqa: E402

DESIGNS.update({
    "gradient": design_gradient,
    "least_squares": design_least_squares,
    "drem": design_drem,
    "gd": design_gd,
    "gpebo": design_gpebo,
    "gpebo_2gd": design_2gd,
    "kkl": design_kkl,
    "kkl_learned": design_kkl_learned,
    "pebo": design_pebo,
    "kkl_pebo": design_kkl_pebo,
    "kkl_pebo_cascade": design_kkl_pebo_cascade,
    "iandi": design_iandi,
})
for _kind, _fn in DESIGNS.items():
    DESIGNS[_kind] = requires_model(_fn)
