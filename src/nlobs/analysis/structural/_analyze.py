"""`analyze`: the structural verdict, with the global parts on request — the top of the structural routes.

The local route (:func:`._lie.local_analysis`, generic rank of the output jets) is below the global ones
(:mod:`._global`: SIAN, multi-experiment; :mod:`._identifiable`: identifiable functions, which use
:mod:`._reparam`); this module calls them all, and none of them calls back up.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

from ...errors import ModelError, ResourceError
from ...model import System
from ...model._tables import generic_surrogates, table_calls
from ...model._system import ExprLike
from ._global import global_identifiability, multi_experiment
from ...algebra._groebner import get_engine
from ._identifiable import find_identifiable_functions
from ._lie import local_analysis
from .._reports import ObservabilityReport

__all__ = ["analyze", "extend_report"]


def analyze(system: System, *, unknown_params: Any = (), inputs: Any = "generic",
            unknown_inputs: Mapping[str, int] | None = None, functions: Sequence[ExprLike] = (),
            at: Mapping[str, float] | None = None, symmetries: bool = True, seed: int = 0,
            regime: Mapping[str, float] | None = None, global_check: bool = False,
            identifiable_functions: bool | str = False, experiments: int | None = None,
            engine: str = "auto") -> ObservabilityReport:
    r"""Structural observability (and identifiability) of a model by the generic rank.

    The rank condition of Besançon (2010) asks for :math:`\dim d\mathcal O(h)|_x = n`, where the observation
    space :math:`\mathcal O(h)` is spanned by the outputs and their repeated Lie derivatives along
    :math:`f_u` for constant u. Its generic value is the rank of

    .. math::

        J = \frac{\partial\,(y, \dot y, \ddot y, \dots, y^{(N)})}{\partial (x_0, \theta, w)}

    for a generic input, with N = number of unknowns (the ranks of the jets increase strictly until
    they stop). J is evaluated at a random point of GF(p), p a random 27-bit prime, through
    truncated power series of the solution carrying gradients (Sedoglavic (2002)), and reduced over
    GF(p): rank, observable unknowns (unit vector in the row space), kernel.

    *Error.* A rank over GF(p) at one point is never above the generic rank over Q, so a full rank
    is a proof of local observability. A smaller rank is wrong only if a nonzero minor of degree D
    vanishes at the random point: probability at most D/p (Schwartz-Zippel); D is bounded by
    propagating degrees through the evaluation program, and a deficient rank is confirmed at a
    second independent point and prime, so the bound is (D/p)^2.

    *Piecewise models.* ``abs``, ``sign``, ``min``, ``max`` and ``sat`` are analysed on one regime,
    where each equals one smooth branch, named in the notes: the branch active at the point
    `regime` (e.g. a state the simulation visits), else abs(g) = g, sign(g) = 1 and the
    unsaturated branch of min/max/sat. :func:`visited_regimes` finds the regimes a trajectory
    goes through.

    *Local, not global.* The rank condition proves local weak observability (Besançon (2010)). When a sign
    change of some unknowns leaves f and h invariant (checked for every sign pattern of up to 12
    unknowns, proved symbolically), x and σx are indistinguishable: reported in ``symmetries``
    (Viegas, Batista, Oliveira & Silvestre (2015), §IV-C: x1' = x2², x2' = 0, y = x1).

    Parameters
    ----------
    system : System
    unknown_params : sequence of str, "all" or bool, optional
        Parameters taken as unknown constants (identifiability); the others keep their values.
    inputs : "generic", "constant", int or mapping, optional
        How known inputs are taken: ``"generic"`` (default; the observation space of Besançon (2010)),
        ``"constant"`` (one generic constant), an int d (generic polynomials of degree d), or a
        mapping ``{input: class or signal}`` where a signal is a number or an expression of t
        (``{"u": 0}`` analyses the singular input u = 0).
    unknown_inputs : mapping of str to int, optional
        Inputs that are not measured, each a polynomial of the given degree with unknown coefficients.
    functions : sequence of expressions, optional
        Functions of the states (and unknown parameters) to test: observable iff the gradient lies
        in the row space of J (e.g. ``"x1**2 + x2**2"``).

    Other Parameters
    ----------------
    at : mapping of str to float, optional
        Real point (states, unknown parameters) where the unobservable directions are computed;
        default a random point with entries in [0.5, 1.5] (unknown parameters at their values).
    symmetries : bool, default True
        Search sign symmetries (global non-observability).
    seed : int, default 0
        Seed of the random point, prime and input coefficients.
    regime : mapping of str to float, optional
        A point (every state; optionally inputs, parameters, t) that selects the branch of each
        piecewise function (abs, sign, min, max, sat): the one active there.
    global_check : bool, default False
        Also decide global identifiability/observability (SIAN, :func:`global_identifiability`):
        fills ``report.global_check``.
    identifiable_functions : bool or "parameters", default False
        Also find generators of the identifiable functions (:func:`find_identifiable_functions`):
        fills ``report.identifiable_functions``. True: the field of the states (initial values) and
        parameters (observable functions); ``"parameters"``: the field of the parameters only,
        StructuralIdentifiability.jl's default (``with_states = false``).
    experiments : int, optional
        Also analyse this many independent experiments sharing the parameters
        (:func:`multi_experiment`): fills ``report.experiments``.
    engine : str, default "auto"
        Gröbner engine of the global parts ("auto", "msolve", "singular", "sympy").

    Returns
    -------
    ObservabilityReport

    Raises
    ------
    ModelError
        On unknown names, an unsupported function, or an input specification that is not understood.

    References
    ----------
    Besançon (2010), "Observation space", "Observability rank condition", "Local weak
    observability"; Viegas, Batista, Oliveira & Silvestre (2015), §IV-C (local vs global); A. Sedoglavic, "A
    probabilistic algorithm to test local algebraic observability in polynomial time", J. Symb.
    Comput. 33(5), 2002.

    Examples
    --------
    >>> from nlobs import System
    >>> s = System(states=["x1", "x2"], f=["u*x2", "0"], outputs=["y"], h=["x1"], inputs=["u"])
    >>> analyze(s).observable, analyze(s, inputs={"u": 0}).observable
    (True, False)
    """
    stage = ["the local rank (the output jets of every unknown by truncated power series)"]
    try:
        return _analyze(system, stage, unknown_params=unknown_params, inputs=inputs, unknown_inputs=unknown_inputs,
                        functions=functions, at=at, symmetries=symmetries, seed=seed, regime=regime,
                        global_check=global_check, identifiable_functions=identifiable_functions,
                        experiments=experiments, engine=engine)
    except RecursionError:  # (the frames are gone by now: the message can be built)
        raise ResourceError("Python's recursion depth", f"{stage[0]} of {system.name!r}",
                            "Its expressions nest too deeply for the symbolic steps (nested function calls): replace an "
                            "inner call by a new state (z = g(x) with z' = g'(x) x') or simplify the model") from None
    except MemoryError as e:
        if isinstance(e, ResourceError):
            raise
        raise ResourceError("memory", f"{stage[0]} of {system.name!r}",
                            "The expressions of its derivatives outgrew what this process may allocate (its address-space "
                            "limit, `ulimit -v`, or the machine's memory): run it with more memory, analyse fewer unknowns "
                            "(--params / unknown_params), take constant inputs (--inputs constant), leave out the global "
                            "parts (--global, --identifiable-functions), or replace a long chain of nested functions by new "
                            "states") from None


def _analyze(system: System, stage: list[str], *, unknown_params: Any, inputs: Any, unknown_inputs: Any,
             functions: Sequence[ExprLike], at: Any, symmetries: bool, seed: int, regime: Any, global_check: bool,
             identifiable_functions: bool | str, experiments: int | None, engine: str) -> ObservabilityReport:
    system, table_notes = _without_tables(system, seed)
    if table_notes:
        return _table_report(system, table_notes, unknown_params=unknown_params, inputs=inputs, unknown_inputs=unknown_inputs,
                             functions=functions, at=at, symmetries=symmetries, seed=seed, regime=regime,
                             global_parts=global_check or identifiable_functions or experiments is not None)
    if getattr(system, "is_discrete", False):
        return _map_report(system, unknown_params=unknown_params, inputs=inputs, unknown_inputs=unknown_inputs,
                           functions=functions, seed=seed, global_check=global_check,
                           identifiable_functions=identifiable_functions, experiments=experiments)
    report = local_analysis(system, unknown_params=unknown_params, inputs=inputs, unknown_inputs=unknown_inputs,
                            functions=functions, at=at, symmetries=symmetries, seed=seed, regime=regime)
    if global_check or identifiable_functions or experiments is not None:  # the global parts
        stage[0] = "the global parts (" + ", ".join(w for w, asked in (("the global check", global_check),
                                                                         ("identifiable functions", identifiable_functions),
                                                                         ("multiple experiments", experiments is not None))
                                                     if asked) + ")"
        report = extend_report(report, system, unknown_params=report.unknown_params, inputs=inputs,
                               unknown_inputs=dict(unknown_inputs or {}), functions=functions, seed=seed,
                               global_check=global_check, identifiable_functions=identifiable_functions,
                               experiments=experiments, engine=engine)
    return report


def _without_tables(system: System, seed: int) -> tuple[System, list[str]]:
    """The system with its lookup tables replaced by generic smooth functions (and the note saying so), or itself."""
    if not isinstance(system, System):   # local_analysis names what it got
        return system, []
    exprs = [*system.f, *system.h]
    if not table_calls(exprs):
        return system, []
    out, notes = generic_surrogates(exprs, seed)
    return system._copy(f=out[:system.n_states], h=out[system.n_states:]), notes


def _table_report(system: System, notes: list[str], *, global_parts: bool, **local: Any) -> ObservabilityReport:
    """The local verdict of a model with lookup tables (each a generic smooth function); the global parts refused."""
    report = analyze(system, **local)
    extra = list(notes)
    if global_parts:
        extra.append("the global check, identifiable functions and multi-experiment identifiability are not done for a "
                     "model with lookup tables (a table is not a rational function); the local verdict above stands")
    return dataclasses.replace(report, notes=(*report.notes, *extra))


def _map_report(system: System, *, unknown_params: Any, inputs: Any, unknown_inputs: Any, functions: Any, seed: int,
                global_check: bool, identifiable_functions: bool, experiments: int | None) -> ObservabilityReport:
    """A discrete-time model: the local rank of the map; the global parts are refused with the reason, the local
    verdict kept."""
    from ._maps import map_analysis

    if unknown_inputs:
        raise ModelError(f"analyze: unknown inputs are not available for the discrete-time model {system.name!r} yet")
    if functions:
        raise ModelError(f"analyze: `functions` are not available for the discrete-time model {system.name!r} yet")
    report = map_analysis(system, unknown_params=unknown_params, inputs=inputs, seed=seed)
    refused = [what for what, asked in (("the global check", global_check), ("identifiable functions", identifiable_functions),
                                        ("multi-experiment identifiability", experiments is not None)) if asked]
    if refused:
        note = (f"{', '.join(refused)}: not done for a discrete-time model (the differential-algebra route of SIAN "
                "needs an ODE); the local verdict above stands")
        report = dataclasses.replace(report, notes=(*report.notes, note))
    return report


def extend_report(report: Any, system: System, *, unknown_params: Any, inputs: Any, unknown_inputs: Any,
                  functions: Sequence[ExprLike], seed: int, global_check: bool, identifiable_functions: bool | str,
                  experiments: int | None, engine: str) -> Any:
    """The local report with the global parts requested from :func:`nlobs.analysis.analyze` filled in."""
    changes: dict[str, Any] = {}
    eng = get_engine(engine) if engine != "sympy" else get_engine("sympy")
    if global_check:
        changes["global_check"] = global_identifiability(
            system, unknown_params=unknown_params, inputs=inputs, unknown_inputs=unknown_inputs, functions=functions,
            local=report, engine=eng if eng is not None else engine, seed=seed)
    if identifiable_functions:
        if identifiable_functions not in (True, "parameters", "states"):
            raise ValueError(f"analyze: `identifiable_functions` must be True, 'states' or 'parameters', got "
                             f"{identifiable_functions!r}")
        changes["identifiable_functions"] = find_identifiable_functions(
            system, unknown_params=unknown_params, inputs=inputs, local=report, with_states=identifiable_functions != "parameters",
            engine=eng if eng is not None else engine, seed=seed)
    if experiments is not None:
        changes["experiments"] = multi_experiment(system, experiments, unknown_params=unknown_params or "all",
                                                  inputs=inputs, engine=eng if eng is not None else engine, seed=seed)
    return dataclasses.replace(report, **changes)
