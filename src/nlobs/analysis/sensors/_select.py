r"""``select_sensors``: what should I measure? Exact observability of every set of candidate sensors, and the estimation
quality each set allows on the model's ``[simulation]`` run.

Structural part (:mod:`..structural._sensors`): the inclusion-minimal sets of candidates that make the targets
locally observable (identifiable), by the exact generic rank of :func:`nlobs.analyze`; the influence graph prunes
first (Liu, Slotine & Barabási (2013)). Quality part (:mod:`..trajectory._fisher`): per set and unknown, the
Cramér–Rao bound of x(0) (and of the unknown parameters) from the run's samples with each candidate's noise, the
unobservability index (Krener & Ide (2009)), the ranking by log det of the Fisher information under a cost budget, and
the cost–quality Pareto front.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...errors import ModelError
from ...model import ModelFile, System
from ...references import cite
from ..structural._inputs import _unknown_params
from ..structural._sensors import (EXHAUSTIVE_LIMIT, CandidateJets, InfluenceGraph, StructuralSearch, candidate_jets,
                                   influence_graph, minimal_sets)
from ..trajectory._fisher import CandidateFisher, candidate_fisher
from ._pool import Candidate, sensor_pool, with_default_noise
from ._quality import GREEDY_GUARANTEE, all_subsets, greedy_path, pareto_front, quality

__all__ = ["SensorSet", "SensorSelection", "select_sensors", "QUALITY_LIMIT"]

#: Pools up to this many candidates have every subset's quality computed (exact best set under the budget, exact
#: Pareto front); larger pools are ranked by greedy search.
QUALITY_LIMIT = 16

CRITERION = ("log det of the Fisher information of the targets (the inverse of their Cramér–Rao covariance; "
             "D-optimal design): larger is better, +1 per factor e in the volume of the confidence ellipsoid's inverse")


@dataclass(frozen=True)
class SensorSet:
    """One set of candidate sensors, with its verdict and its bounds.

    Attributes
    ----------
    sensors : tuple of str
    cost : float
    observable : bool
        The targets are locally observable (identifiable) from this set: the exact generic rank.
    crb : mapping of str to float, or None
        Cramér–Rao bound (standard deviation) of each unknown's initial value on the run; inf where the run does not
        inform it; None without a run.
    log_det : float or None
        The ranking criterion (see :data:`CRITERION`).
    unobservability_index, condition : float or None
        Krener & Ide (2009)'s local unobservability index and estimation condition number of the set's information,
        in units of each unknown's σ₀ (``[simulation] initial_std``, else its largest magnitude on the run): the
        index is the Cramér–Rao bound along the worst direction, as a multiple of σ₀.
    roles : tuple of str
        Why it is listed: ``minimal``, ``pareto``, ``best``, ``pool``.
    within_budget : bool
    """

    sensors: tuple[str, ...]
    cost: float
    observable: bool
    crb: Mapping[str, float] | None = None
    log_det: float | None = None
    unobservability_index: float | None = None
    condition: float | None = None
    roles: tuple[str, ...] = ()
    within_budget: bool = True

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (inf and NaN become None)."""
        def num(v: Any) -> Any:
            return None if v is None or not math.isfinite(v) else float(v)

        return {"sensors": list(self.sensors), "cost": self.cost, "observable": self.observable,
                "crb": None if self.crb is None else {k: num(v) for k, v in self.crb.items()},
                "log_det": num(self.log_det), "unobservability_index": num(self.unobservability_index),
                "condition": num(self.condition), "roles": list(self.roles), "within_budget": self.within_budget}


@dataclass(frozen=True, eq=False)
class SensorSelection:
    """The answer of :func:`select_sensors`: the minimal sets, each set's bounds, the ranking and the Pareto front.

    Attributes
    ----------
    model : str
    targets, unknowns : tuple of str
    pool : tuple of Candidate
        The candidates (with the noise used).
    graph : InfluenceGraph
    search : StructuralSearch
        How the minimal sets were found, and whether the list is complete or the minimum proven.
    minimal_sets : tuple of tuple of str
    sets : tuple of SensorSet
        Every minimal set, then the Pareto sets, the best set under the budget and the whole pool (each once).
    best : SensorSet or None
        The set of largest criterion within the budget (None without a run or when none observes the targets).
    pareto : tuple of tuple of str
        The cost–quality front, cheapest first.
    budget : float or None
    ranking : str
        How the best set and the front were found (exhaustive, or greedy with its guarantee).
    run : mapping or None
        The run the bounds are computed on (t_final, dt, samples, sample period).
    notes : tuple of str
    seconds : float
    criterion, reference : str
    fisher : CandidateFisher or None
        Each candidate's information (noise-weighted), the run's sample times, states and noise-free readings.
    """

    model: str
    targets: tuple[str, ...]
    unknowns: tuple[str, ...]
    pool: tuple[Candidate, ...]
    graph: InfluenceGraph
    search: StructuralSearch
    minimal_sets: tuple[tuple[str, ...], ...]
    sets: tuple[SensorSet, ...]
    best: SensorSet | None
    pareto: tuple[tuple[str, ...], ...]
    budget: float | None
    ranking: str
    run: Mapping[str, Any] | None
    notes: tuple[str, ...] = ()
    seconds: float = 0.0
    criterion: str = CRITERION
    reference: str = field(default_factory=lambda: f"{cite('sedoglavic2002')}; {cite('liu2013')}; {cite('krener2009')}")
    fisher: CandidateFisher | None = field(default=None, repr=False)

    def set_of(self, names: Sequence[str]) -> SensorSet | None:
        """The listed set with exactly these sensors (None if it is not listed)."""
        key = set(names)
        return next((s for s in self.sets if set(s.sensors) == key), None)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``minimal_sets``, ``sets`` (each with ``crb``), ``best``, ``pareto``, the pool and the search."""
        return {
            "model": self.model, "targets": list(self.targets), "unknowns": list(self.unknowns),
            "pool": [{"name": c.name, "expr": c.text, "noise": c.noise, "noise_source": c.noise_source, "cost": c.cost,
                      "origin": c.origin} for c in self.pool],
            "sink_components": [list(c) for c in self.graph.sinks],
            "search": {"method": self.search.method, "complete": self.search.complete,
                       "proven_minimum": self.search.proven_minimum, "rank_checks": self.search.checked,
                       "pruned_by_graph": self.search.pruned, "pool_observes": self.search.pool_observes,
                       "error_probability": self.search.error_probability},
            "minimal_sets": [list(s) for s in self.minimal_sets],
            "sets": [s.to_dict() for s in self.sets],
            "best": None if self.best is None else self.best.to_dict(),
            "pareto": [list(s) for s in self.pareto], "budget": self.budget, "criterion": self.criterion,
            "ranking": self.ranking, "run": None if self.run is None else dict(self.run),
            "notes": list(self.notes), "reference": self.reference, "seconds": self.seconds,
        }

    def __str__(self) -> str:
        from ._text import selection_text

        return selection_text(self)


def _simulation_of(model: Any, simulation: Any) -> Any:
    if simulation is not None:
        return simulation
    return model.simulation if isinstance(model, ModelFile) else None


def _get(cfg: Any, key: str, default: Any = None) -> Any:
    if cfg is None:
        return default
    if isinstance(cfg, Mapping):
        return cfg.get(key, default)
    return getattr(cfg, key, default)


def _targets(targets: Any, unknowns: Sequence[str]) -> tuple[str, ...]:
    if targets is None:
        return tuple(unknowns)
    names = [t.strip() for t in targets.split(",")] if isinstance(targets, str) else list(targets)
    names = [t for t in names if t]
    bad = [t for t in names if t not in unknowns]
    if bad:
        raise ModelError(f"targets: {bad[0]!r} is not a state or an unknown parameter; choose among {', '.join(unknowns)}")
    if not names:
        raise ModelError(f"targets: no name given; choose among {', '.join(unknowns)}")
    return tuple(dict.fromkeys(names))


def _common_period(periods: Sequence[float], pool: Sequence[Candidate], dt: float | None) -> float:
    """The grid every candidate's period is a whole multiple of: their greatest common divisor (20 Hz and 50 Hz
    sensors on a 100 Hz grid), the periods read as fractions of at most 1e9 in the denominator. With the run's `dt`
    each period must be a whole multiple of it, as the [simulation] sample periods must."""
    from fractions import Fraction

    from ...model._toml import period_multiple_problem

    for c in pool:
        why = period_multiple_problem(float(c.period), float(dt)) if dt and c.period is not None else ""
        if why:
            raise ModelError(f"sensors.{c.name}.period: {why}")

    fr = [Fraction(p).limit_denominator(10 ** 9) for p in periods]
    g = fr[0]
    for f in fr[1:]:
        g = Fraction(math.gcd(g.numerator * f.denominator, f.numerator * g.denominator), g.denominator * f.denominator)
    grid = float(g)
    for c, p in zip(pool, periods):
        if abs(p / grid - round(p / grid)) > 1e-9 * max(1.0, p / grid):  # a period not near a fraction of 1e9 at most
            raise ModelError(f"sensors.{c.name}.period: {p:g} s has no common divisor with the other periods of the "
                             "pool; choose periods that are whole multiples of one grid (the run's dt)")
    return grid


def _fisher(system: System, pool: Sequence[Candidate], unknown: Sequence[str], cfg: Any,
            engine: str) -> tuple[CandidateFisher, tuple[Candidate, ...], dict[str, Any], list[str]]:
    """Each candidate's information on the run (computed with unit noise, then scaled by its noise), the pool with
    default noises filled in, the run's description and notes."""
    notes = []
    true = dict(_get(cfg, "true_parameters", {}) or {})
    plant = system.with_params(**true) if true else system
    period = _get(cfg, "sample_period")
    if isinstance(period, Mapping):
        period = min(float(v) for v in period.values())   # the run's grid; each output candidate keeps its own period
        without = [c.name for c in pool if c.period is None]
        if without:
            notes.append(f"the outputs have sample periods of their own: a candidate without one ({', '.join(without)}) "
                         f"is taken every {period:g} (the fastest; [sensors.NAME] period sets one)")
    every_each = None
    if any(c.period is not None for c in pool):
        base = float(period) if period else min(float(c.period) for c in pool if c.period is not None)
        grid = _common_period([float(c.period) if c.period is not None else base for c in pool], pool,
                              _get(cfg, "dt"))
        every_each = [int(round((float(c.period) if c.period is not None else base) / grid)) for c in pool]
        period = grid
    if any(float(v) > 0 for v in (_get(cfg, "process_noise", {}) or {}).values()):
        notes.append("the bounds are those of the deterministic model: the [simulation] process_noise is not in them "
                     "(with process noise x(0) is less informative than they say)")
    t_final = float(_get(cfg, "t_final") or 10.0)
    dt = float(_get(cfg, "dt") or 1e-3)
    fi = candidate_fisher(plant, [c.expr for c in pool], np.ones(len(pool)), x0=_get(cfg, "x0"), t_final=t_final, dt=dt,
                          inputs=dict(_get(cfg, "inputs", {}) or {}), sample_period=period, unknown_params=unknown,
                          names=[c.name for c in pool], engine=engine, sample_every=every_each)
    pool = with_default_noise(pool, fi.outputs, fi.states)
    sigma = np.array([c.noise for c in pool], dtype=float)
    fi = CandidateFisher(fi.names, fi.unknowns, fi.information / sigma[:, None, None] ** 2, fi.times, fi.dt, fi.states,
                         fi.outputs, None, fi.method)
    run = {"t_final": float(fi.times[-1]), "dt": fi.dt, "samples": int(fi.times.size),
           "sample_period": None if period is None else float(period), "x0": [float(v) for v in _get(cfg, "x0")],
           "periods": None if every_each is None else {c.name: k * float(period) for c, k in zip(pool, every_each)},
           "true_parameters": true, "method": fi.method}
    return fi, pool, run, notes


def _prior(fi: CandidateFisher, unknown: Sequence[str], system: System, cfg: Any) -> np.ndarray:
    """Prior information diag(1/σ₀²) of the greedy's objective: ``[simulation] initial_std``, else the largest
    magnitude of the state on the run (of the parameter's value), else 1."""
    given = dict(_get(cfg, "initial_std", {}) or {})
    scales = []
    for i, name in enumerate(fi.unknowns):
        if name in given:
            s = float(given[name])
        elif i < system.n_states:
            s = float(np.max(np.abs(fi.states[:, i]))) if fi.states.size else 0.0
        else:
            s = abs(float(system.params[name]))
        scales.append(s if s > 0 and math.isfinite(s) else 1.0)
    return np.diag(1.0 / np.array(scales) ** 2)


def select_sensors(model: ModelFile | System | str, candidates: Any = None, *, targets: Any = None,
                   budget: float | None = None, unknown_params: Any = None, inputs: Any = "generic",
                   simulation: Any = None, quality_part: bool = True, seed: int = 0, engine: str = "auto",
                   exhaustive_limit: int = EXHAUSTIVE_LIMIT, quality_limit: int = QUALITY_LIMIT) -> SensorSelection:
    r"""What should I measure? Every inclusion-minimal set of candidate sensors that makes the targets locally
    observable (identifiable), and the Cramér–Rao bounds each set allows on the model's ``[simulation]`` run.

    *Structural part.* Each candidate's output jets are expanded once at a random point of GF(p) (Sedoglavic (2002),
    as :func:`nlobs.analyze`) and a set is judged by the exact rank of the union of its candidates' rows: a full rank
    (every target's unit vector in the row space) proves local observability; a deficiency is confirmed at a second
    point and prime. Before any rank, a set that cannot see a target through the influence graph is ruled out: with
    every state a target, it must see every sink strongly connected component (Liu, Slotine & Barabási (2013)).
    Pools of up to `exhaustive_limit` candidates are searched exhaustively (every minimal set); larger ones get the
    minimum-size sets, proven minimum unless the search ran out of budget and fell back to a greedy set.

    *Quality part.* With :math:`F_c = \sum_k \sigma_c^{-2} (\partial y_c(t_k)/\partial z)^\top
    (\partial y_c(t_k)/\partial z)` the Fisher information of z = (x(0), unknown parameters) from candidate c's samples
    (exact sensitivities of the run's RK4 steps), a set's information is :math:`F_S = \sum_{c\in S} F_c` and its
    bounds are :math:`\sqrt{\mathrm{diag}\,F_S^{-1}}`. Sets are ranked by log det of the targets' information; up to
    `quality_limit` candidates every subset is scored (exact best set within `budget`, exact Pareto front), beyond
    that greedily, with the guarantee of submodularity (Summers, Cortesi & Lygeros (2016)).

    Parameters
    ----------
    model : ModelFile, System or str
        A model file (loaded, or its path / bundled name) or a System.
    candidates : mapping or sequence, optional
        The pool (see :func:`sensor_pool`); default: the file's ``[sensors.NAME]`` tables, else every state and output.
    targets : sequence of str or str, optional
        States and unknown parameters to observe (default: all of them).
    budget : float, optional
        Most total cost of the best set (default: no limit).
    unknown_params : sequence of str, "all" or bool, optional
        Parameters taken as unknown (default: the file's ``unknown = true`` ones).
    inputs : "generic", "constant", int or mapping
        The input class of the structural part, as for :func:`nlobs.analyze`.
    simulation : SimulationConfig or mapping, optional
        The run of the quality part (x0, t_final, dt, inputs, sample_period, true_parameters, initial_std); default
        the file's ``[simulation]``. Without x0 there is no quality part.
    quality_part : bool
        Compute the bounds (False: the structural part only).
    seed : int
        Seed of the random points and primes.
    engine : {"auto", "vm", "c"}
        Where the run's sensitivities are computed.
    exhaustive_limit, quality_limit : int
        Largest pools searched exhaustively by the structural and the quality parts.

    Returns
    -------
    SensorSelection

    Raises
    ------
    ModelError
        An empty pool, a bad candidate or target, a discrete-time model.

    Examples
    --------
    >>> from nlobs import System
    >>> s = System(states=["x", "v"], f=["v", "-x"], outputs=["y"], h=["x"])
    >>> sel = select_sensors(s, {"pos": {"expr": "x", "noise": 0.1}, "vel": {"expr": "v", "noise": 0.1}},
    ...                      quality_part=False)
    >>> sel.minimal_sets
    (('pos',), ('vel',))
    """
    t0 = time.perf_counter()
    if isinstance(model, str):
        from ...model import load_model

        model = load_model(model)
    pool = sensor_pool(model, candidates)
    system = model.system if isinstance(model, ModelFile) else model
    unknown = tuple(_unknown_params(system, unknown_params if unknown_params is not None else
                                    (model.unknown_params if isinstance(model, ModelFile) else ())))
    jets = candidate_jets(system, [c.expr for c in pool], names=[c.name for c in pool], unknown_params=unknown,
                          inputs=inputs, seed=seed)
    graph = influence_graph(system, [c.expr for c in pool], unknown)
    tnames = _targets(targets, jets.unknowns)
    search = minimal_sets(jets, graph, tnames, exhaustive_limit=exhaustive_limit)
    notes = [*jets.notes, *search.notes]
    cfg = _simulation_of(model, simulation)
    fisher = run = None
    if quality_part and _get(cfg, "x0") is not None:
        fisher, pool, run, more = _fisher(system, pool, unknown, cfg, engine)
        notes += more
    elif quality_part:
        notes.append("no bounds: the model has no [simulation] x0 to run (give x0 and t_final in [simulation])")
    return _assemble(model, system, pool, jets, graph, search, tnames, fisher, run, cfg, budget, quality_limit,
                     notes, t0)


def _assemble(model: Any, system: System, pool: tuple[Candidate, ...], jets: CandidateJets, graph: InfluenceGraph,
              search: StructuralSearch, tnames: tuple[str, ...], fisher: CandidateFisher | None, run: Any, cfg: Any,
              budget: float | None, quality_limit: int, notes: list[str], t0: float) -> SensorSelection:
    """The ranking and the sets to list, each with its verdict and bounds."""
    names = [c.name for c in pool]
    costs = np.array([c.cost for c in pool], dtype=float)
    cols = [jets.unknowns.index(t) for t in tnames]
    limit = math.inf if budget is None else float(budget)
    pareto: list[tuple[int, ...]] = []
    best: tuple[int, ...] | None = None
    ranking = "no ranking without a run"
    if fisher is not None and len(pool) <= quality_limit:
        masks, cost_of, crit = all_subsets(fisher.information, costs, cols)
        members = [tuple(i for i in range(len(pool)) if int(b) >> i & 1) for b in masks]
        pareto = [members[i] for i in pareto_front(masks, cost_of, crit)]
        ok = np.flatnonzero(np.isfinite(crit) & (cost_of <= limit * (1 + 1e-12)))
        if ok.size:
            i = ok[np.lexsort((np.array([len(members[j]) for j in ok]), cost_of[ok], -crit[ok]))[0]]
            best = members[i]
        ranking = (f"every one of the {masks.size} sets scored: the best set within the budget and the Pareto front are "
                   "exact")
    elif fisher is not None:
        unknown = jets.unknowns[system.n_states:]
        prior = _prior(fisher, unknown, system, cfg)
        plain = greedy_path(fisher.information, costs, prior, limit, per_cost=False)
        per_cost = greedy_path(fisher.information, costs, prior, limit, per_cost=True)
        scored = list(dict.fromkeys([*(tuple(m) for m in search.minimal), *(tuple(sorted(p)) for p in (*plain, *per_cost))]))
        bits = np.array([sum(1 << i for i in m) for m in scored], dtype=np.int64)
        cost_of = np.array([costs[list(m)].sum() for m in scored])
        crit = np.array([quality(fisher.of(m), cols).log_det for m in scored])
        pareto = [scored[i] for i in pareto_front(bits, cost_of, crit)]
        ok = np.flatnonzero(np.isfinite(crit) & (cost_of <= limit * (1 + 1e-12)))
        best = scored[ok[np.lexsort((cost_of[ok], -crit[ok]))[0]]] if ok.size else None
        ranking = (f"{len(scored)} sets scored (the minimal sets and two greedy paths on log det(Λ₀ + F), Λ₀ = "
                   "diag(1/σ₀²) the prior information, σ₀ from [simulation] initial_std else the unknown's largest "
                   f"magnitude on the run): {GREEDY_GUARANTEE}; the best set and the front are the best of the sets "
                   "scored, not proven over every set")
        if len(cols) < len(jets.unknowns):
            notes.append("with targets a part of the unknowns the criterion is not submodular: the greedy ranking has no "
                         "guarantee")
    order: dict[tuple[int, ...], list[str]] = {}
    for m in (tuple(s) for s in search.minimal):
        order.setdefault(m, []).append("minimal")
    for m in pareto:
        order.setdefault(m, []).append("pareto")
    if best is not None:
        order.setdefault(best, []).append("best")
    order.setdefault(tuple(range(len(pool))), []).append("pool")
    # the index and condition number in units of each unknown's σ₀ (as the greedy's prior): mixed units otherwise
    scales = None if fisher is None else \
        1.0 / np.sqrt(np.diag(_prior(fisher, jets.unknowns[system.n_states:], system, cfg)))
    sets = tuple(_evaluate(m, roles, names, costs, jets, cols, fisher, limit, scales) for m, roles in order.items())
    by_members = dict(zip(order, sets))
    return SensorSelection(
        system.name, tnames, jets.unknowns, pool, graph, search,
        tuple(tuple(names[i] for i in m) for m in search.minimal), sets,
        by_members.get(best) if best is not None else None, tuple(tuple(names[i] for i in m) for m in pareto),
        budget, ranking, run, tuple(notes), time.perf_counter() - t0, fisher=fisher)


def _evaluate(members: tuple[int, ...], roles: list[str], names: Sequence[str], costs: np.ndarray, jets: CandidateJets,
              cols: Sequence[int], fisher: CandidateFisher | None, limit: float,
              scales: np.ndarray | None = None) -> SensorSet:
    cost = float(costs[list(members)].sum())
    observable = jets.observes(members, cols)
    if fisher is None:
        return SensorSet(tuple(names[i] for i in members), cost, observable, roles=tuple(roles),
                         within_budget=cost <= limit * (1 + 1e-12))
    q = quality(fisher.of(members), cols, scales)
    return SensorSet(tuple(names[i] for i in members), cost, observable, dict(zip(jets.unknowns, map(float, q.crb))),
                     q.log_det, q.unobservability_index, q.condition, tuple(roles), cost <= limit * (1 + 1e-12))
