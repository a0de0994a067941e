"""Observer kinds by name, for model files (``[observers.NAME] kind = "..."``), the CLI and the API.

A model file and the API meet here (the ``model`` layer cannot import designs):

- :func:`design_from_config` designs one :class:`~nlobs.model.ObserverConfig` (or a system, a
  kind and options);
- :func:`designs_from_file` designs all (or some) observers of a :class:`~nlobs.model.ModelFile`,
  after checking that its unknown parameters are identifiable;
- the kinds themselves are declared next to their design functions (:mod:`nlobs.design._kind`).

With unknown parameters (``[parameters] k = { value = 0.3, unknown = true }``) the observers are
designed on the augmented system (k appended to the state, :meth:`nlobs.System.augmented`); the
default initial estimate x̂0 ends with the parameters' initial guesses, and an x̂0 given for the
plant's states only is completed with them.
"""

from __future__ import annotations

import types
import typing
import warnings
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .._text import shorten, shorten_list
from ..errors import ModelError, PreconditionError
from ..model import ObserverConfig, System
from ..model._budget import symbolic_budget
from ..references import cite
from ._base import ObserverDesign
from ._kind import KINDS, DesignsView, options_of, register_design, requires_model

__all__ = ["DESIGNS", "register_design", "design_from_config", "designs_from_file", "check_identifiable", "requires_model",
           "options_of"]

#: The design function of each kind (a read-only view of :data:`nlobs.design.KINDS`, kept for older code).
DESIGNS = DesignsView()


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
        from ..analysis import analyze  # deferred: a Monte Carlo worker unpickling a design runs no analysis

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
    if kind not in KINDS:
        raise ModelError(f"{prefix}unknown observer kind {shorten(kind, 40)}; available: {', '.join(sorted(KINDS))}")
    fn = KINDS[kind].design
    allowed = options_of(fn)
    old_names = {k: v for k, v in KINDS[kind].renamed.items() if k in options and v in allowed}
    for old, new in old_names.items():   # an option renamed in this release: accepted with a warning naming the new one
        if new in options:
            raise ModelError(f"{prefix}give `{new}` only (`{old}` is its old name)")
        warnings.warn(f"{prefix}option `{old}` of kind {kind!r} is renamed `{new}`; the old name is accepted until the next "
                      "release", DeprecationWarning, stacklevel=2)
    options = {old_names.get(k, k): v for k, v in options.items()}
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
