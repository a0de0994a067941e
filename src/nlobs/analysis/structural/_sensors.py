r"""Which candidate sensors make a model observable: the generic rank of each candidate's output jets, once, and the
inclusion-minimal sets of candidates, by the same exact rank as :func:`nlobs.analyze`.

Each candidate's jets (its value and time derivatives, orders 0..M for M unknowns) are expanded once as truncated
power series at a random point of GF(p), with their gradients with respect to the unknowns (Sedoglavic (2002)); their
rows are reduced once per candidate. A set of candidates is judged by the rank over GF(p) of the union of its
candidates' rows: full rank (or every target's unit vector in the row space) is a proof of local observability
(identifiability); a deficiency is confirmed at a second independent point and prime, as in :func:`nlobs.analyze`.

The influence graph (an edge u -> x_i when the unknown u appears in x_i's equation) prunes the search before any rank
is taken: a target that reaches none of the unknowns a set's expressions use has a zero column in every jet, so the set
cannot observe it. With every state a target this is the condition of Liu, Slotine & Barabási (2013): a sensor in
every sink strongly connected component of the influence graph (a root SCC of their inference diagram).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from ...algebra._modular import RowEchelon, random_prime
from ...algebra._series import ModField, Resample
from ...errors import ModelError
from ...model import System, symbol
from ...model._budget import symbolic_budget
from ...model._system import exact
from ...model._tables import generic_surrogates, table_calls
from ...references import cite
from ._inputs import _input_classes, _unknown_params, require_system
from ._lie import _jets, _leaf_coefficients, _setup

__all__ = ["CandidateJets", "candidate_jets", "InfluenceGraph", "influence_graph", "StructuralSearch", "minimal_sets",
           "EXHAUSTIVE_LIMIT"]

#: Pools up to this many candidates are searched exhaustively for every inclusion-minimal set; larger pools get the
#: minimum-size sets (iterative deepening with pruning; greedy when that exceeds its budget).
EXHAUSTIVE_LIMIT = 19
#: Most subsets whose rank is taken in one search (past it the search stops and says what it covered).
RANK_BUDGET = 200_000


@dataclass
class _Point:
    prime: int
    bases: list[np.ndarray]      # per candidate: its reduced jet rows (rank x M) over GF(prime)
    degree: int                  # Schwartz-Zippel degree bound of a minor of the union


@dataclass
class CandidateJets:
    """The jets of every candidate at two independent random points (see the module's documentation).

    Attributes
    ----------
    names : tuple of str
        The candidates.
    unknowns : tuple of str
        States, then unknown parameters: the columns of every row.
    points : list
        Per point: the prime, the reduced rows of each candidate and the degree bound.
    notes : tuple of str
        The analysed branch of piecewise functions, tables as generic functions, constants treated as generic.
    """

    names: tuple[str, ...]
    unknowns: tuple[str, ...]
    points: list[_Point]
    notes: tuple[str, ...] = ()

    def ranks(self) -> tuple[int, ...]:
        """Each candidate's own generic rank (the larger of the two points')."""
        return tuple(max(int(p.bases[i].shape[0]) for p in self.points) for i in range(len(self.names)))

    def span(self, members: Sequence[int], point: int = 0, start: RowEchelon | None = None) -> RowEchelon:
        """The row space of the candidates `members` at one point (added to a copy of `start`)."""
        pt = self.points[point]
        ech = start.widened(0) if start is not None else RowEchelon(len(self.unknowns), pt.prime)
        for i in members:
            if ech.rank == ech.ncols:
                break
            if pt.bases[i].shape[0]:
                ech.add_many(pt.bases[i])
        return ech

    def sees(self, ech: RowEchelon, targets: Sequence[int]) -> bool:
        """Whether every target's unit vector lies in the row space `ech`."""
        if ech.rank == ech.ncols:
            return True
        e = np.zeros((len(targets), ech.ncols), dtype=np.int64)
        e[np.arange(len(targets)), list(targets)] = 1
        return not np.any(ech.reduce_many(e))

    def observes(self, members: Sequence[int], targets: Sequence[int]) -> bool:
        """The verdict of a set: its targets locally observable at the first point, else at the second."""
        return any(self.sees(self.span(members, k), targets) for k in range(len(self.points)))

    def error_bound(self) -> float:
        """Probability bound that one deficient verdict is wrong (both points unlucky; Schwartz-Zippel)."""
        return float(np.prod([min(1.0, p.degree / p.prime) for p in self.points]))


def _candidate_system(system: System, exprs: Sequence[sp.Expr], seed: int) -> tuple[System, list[str]]:
    """`system` with the candidates as its outputs (names that clash with nothing), tables as generic functions."""
    taken = {*system.states, *system.inputs, *system.params, *system.outputs}
    names = []
    for i in range(len(exprs)):
        name = f"sensor{i}"
        while name in taken:
            name += "_"
        names.append(name)
    f, h, notes = list(system.f), list(exprs), []
    if table_calls([*f, *h]):
        out, notes = generic_surrogates([*f, *h], seed)
        f, h = out[: len(f)], out[len(f):]
    return system._copy(f=f, outputs=names, h=h), list(notes)


def candidate_jets(system: System, exprs: Sequence[sp.Expr], *, names: Sequence[str] | None = None, unknown_params: Any = (),
                   inputs: Any = "generic", seed: int = 0) -> CandidateJets:
    """Each candidate's output jets at two independent random points of GF(p), reduced once (see the module).

    Parameters
    ----------
    system : System
        The model (its own outputs are not used).
    exprs : sequence of sympy.Expr
        What each candidate measures (expressions of the states, inputs, parameters and t).
    names : sequence of str, optional
        The candidates' names (default ``c0, c1, ...``).
    unknown_params : sequence of str, "all" or bool, optional
        Parameters that are unknown constants, as for :func:`nlobs.analyze`.
    inputs : "generic", "constant", int or mapping, optional
        The input class, as for :func:`nlobs.analyze`.
    seed : int
        Seed of the random points and primes.

    Returns
    -------
    CandidateJets
    """
    require_system(system, "sensor selection")
    if getattr(system, "is_discrete", False):
        raise ModelError(f"sensor selection: {system.name!r} is a discrete-time model; the candidate search is available "
                         "for continuous-time models only")
    if not exprs:
        raise ModelError("sensor selection: the pool of candidate sensors is empty; give at least one candidate")
    names = tuple(names) if names is not None else tuple(f"c{i}" for i in range(len(exprs)))
    with symbolic_budget(f"sensor selection on {system.name!r}"):
        sysc, notes = _candidate_system(system, list(exprs), seed)
        params = _unknown_params(system, unknown_params)
        classes = _input_classes(sysc, inputs, {})
        st = _setup(sysc, params, classes, {}, [])
        rng = np.random.default_rng(seed)
        points = [_jet_point(st, sysc, rng) for _ in range(2)]
    return CandidateJets(names, st.unknowns, points, tuple([*st.prog.notes, *notes]))


def _jet_point(st: Any, system: System, rng: np.random.Generator) -> _Point:
    """Every candidate's jets, orders 0..M, at one random point and prime (another draw on a zero denominator)."""
    M = len(st.unknowns)
    for _ in range(20):
        p = random_prime(rng, st.prog.roots)
        F = ModField(p)
        try:
            x0, coef = _leaf_coefficients(st, system, F, rng, M, None, True)
            run = _jets(st, system, F, rng, M, x0, coef, st.prog.h)
            rows: list[list[np.ndarray]] = [[] for _ in st.prog.h]
            degrees: list[int] = []
            for k in range(M + 1):
                run.step()
                for j, node in enumerate(st.prog.h):
                    rows[j].append(run.row(node, k)[1:])
                    degrees.append(run.degree(node, k))
        except Resample:
            continue
        bases = []
        for r in rows:
            ech = RowEchelon(M, p)
            ech.add_many(np.array(r, dtype=np.int64))
            bases.append(ech.basis.copy())
        top = sorted(degrees, reverse=True)[:M]
        return _Point(p, bases, int(sum(top)) * (1 + int(run.extra_degree)))
    raise ModelError(f"{system.name!r}: the generic-rank test of the candidate sensors hit a zero denominator at 20 random "
                     "points; the expressions may be undefined almost everywhere (check divisions and logarithms)")


@dataclass(frozen=True)
class InfluenceGraph:
    """The influence graph of the unknowns (u -> x_i when u appears in x_i's equation) and what each candidate reaches.

    Attributes
    ----------
    unknowns : tuple of str
    components : tuple of tuple of str
        Its strongly connected components.
    sinks : tuple of tuple of str
        The sink components (no edge leaves them): each needs a sensor of its own (Liu, Slotine & Barabási (2013)).
    seen : tuple of int
        Per candidate, the bit mask of the unknowns from which a path reaches an unknown its expression uses.
    """

    unknowns: tuple[str, ...]
    components: tuple[tuple[str, ...], ...]
    sinks: tuple[tuple[str, ...], ...]
    seen: tuple[int, ...]


def influence_graph(system: System, exprs: Sequence[sp.Expr], unknown_params: Sequence[str] = ()) -> InfluenceGraph:
    """The influence graph of the states and `unknown_params` and the unknowns each candidate expression can see.

    Parameters
    ----------
    system : System
    exprs : sequence of expressions
        The candidates.
    unknown_params : sequence of str
        The unknown parameters (nodes of the graph with the states).

    Returns
    -------
    InfluenceGraph
    """
    unknowns = (*system.states, *unknown_params)
    index = {symbol(u): i for i, u in enumerate(unknowns)}
    known = {symbol(k): exact(v) for k, v in system.params.items() if k not in unknown_params}
    m = len(unknowns)
    src, dst = [], []
    for i, fi in enumerate(system.f):
        for s in _symbols_of(fi.xreplace(known)):
            if s in index:
                src.append(index[s])
                dst.append(i)
    A = csr_matrix((np.ones(len(src)), (src, dst)), shape=(m, m))
    count, label = connected_components(A, directed=True, connection="strong")
    comps = [tuple(unknowns[j] for j in range(m) if label[j] == c) for c in range(count)]
    leaves = [c for c in range(count) if not any(label[a] == c and label[b] != c for a, b in zip(src, dst))]
    reach = _ancestors(m, src, dst)
    seen = []
    for e in exprs:
        used = [index[s] for s in _symbols_of(e.xreplace(known)) if s in index]
        mask = 0
        for u in used:
            mask |= reach[u]
        seen.append(mask)
    return InfluenceGraph(unknowns, tuple(comps), tuple(comps[c] for c in leaves), tuple(seen))


def _symbols_of(e: sp.Expr) -> set[sp.Symbol]:
    """The free symbols of `e`, those inside table calls included."""
    out = set(e.free_symbols)
    for a in e.atoms(sp.core.function.AppliedUndef):
        for arg in a.args:
            out |= arg.free_symbols
    return out


def _ancestors(m: int, src: Sequence[int], dst: Sequence[int]) -> list[int]:
    """Per node, the bit mask of the nodes with a path to it (itself included)."""
    parents: list[list[int]] = [[] for _ in range(m)]
    for a, b in zip(src, dst):
        parents[b].append(a)
    out = []
    for v in range(m):
        mask, stack = 1 << v, [v]
        while stack:
            w = stack.pop()
            for a in parents[w]:
                if not mask >> a & 1:
                    mask |= 1 << a
                    stack.append(a)
        out.append(mask)
    return out


@dataclass
class StructuralSearch:
    """The inclusion-minimal sets of candidates that make the targets locally observable (identifiable).

    Attributes
    ----------
    minimal : list of tuple of int
        The sets (candidate indices, sorted), smallest first. For a pool over :data:`EXHAUSTIVE_LIMIT`, the
        minimum-size sets only.
    method : str
        How they were found.
    complete : bool
        Every inclusion-minimal set is listed (exhaustive search).
    proven_minimum : bool
        The smallest size listed is proven to be the minimum (every smaller set was ruled out).
    checked : int
        Subsets whose rank was taken.
    pruned : int
        Subsets ruled out by the influence graph before any rank.
    pool_observes : bool
        The whole pool makes the targets observable.
    error_probability : float
        Bound on the probability that a set judged deficient is not (one set; Schwartz-Zippel at both points).
    notes : list of str
    seconds : float
    """

    minimal: list[tuple[int, ...]]
    method: str
    complete: bool
    proven_minimum: bool
    checked: int = 0
    pruned: int = 0
    pool_observes: bool = True
    error_probability: float = 0.0
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0


def minimal_sets(jets: CandidateJets, graph: InfluenceGraph, targets: Sequence[str], *,
                 exhaustive_limit: int = EXHAUSTIVE_LIMIT, budget: int = RANK_BUDGET) -> StructuralSearch:
    """The inclusion-minimal sets of candidates whose jets make every target locally observable (identifiable).

    Parameters
    ----------
    jets : CandidateJets
    graph : InfluenceGraph
        Of the same unknowns and candidates (prunes sets that cannot see a target).
    targets : sequence of str
        States and unknown parameters to observe.
    exhaustive_limit : int
        Pools up to this size are enumerated (every minimal set); larger ones get the minimum-size sets.
    budget : int
        Most subsets whose rank is taken.

    Returns
    -------
    StructuralSearch
    """
    t0 = time.perf_counter()
    cols = [jets.unknowns.index(t) for t in targets]
    need = sum(1 << c for c in cols)
    n = len(jets.names)
    if not jets.observes(range(n), cols):
        return StructuralSearch([], "the whole pool was checked first", True, True, 1, 0, False,
                                jets.error_bound(), [], time.perf_counter() - t0)
    if n <= exhaustive_limit:
        out = _exhaustive(jets, graph.seen, cols, need, budget)
    else:
        out = _minimum_size(jets, graph.seen, cols, need, budget)
    out.error_probability = jets.error_bound()
    out.seconds = time.perf_counter() - t0
    return out


def _exhaustive(jets: CandidateJets, seen: Sequence[int], cols: Sequence[int], need: int, budget: int) -> StructuralSearch:
    """Every subset by increasing size: supersets of a found set skipped, sets that cannot see a target pruned."""
    n = len(jets.names)
    found: list[tuple[int, ...]] = []
    masks: list[int] = []
    checked = pruned = 0
    for k in range(1, n + 1):
        for combo in itertools.combinations(range(n), k):
            bits = sum(1 << i for i in combo)
            if any(m & bits == m for m in masks):
                continue
            cover = 0
            for i in combo:
                cover |= seen[i]
            if cover & need != need:
                pruned += 1
                continue
            if checked >= budget:
                return StructuralSearch(found, f"every subset of up to {k - 1} candidates (then the budget of {budget} "
                                        "ranks ran out)", False, bool(found), checked, pruned,
                                        notes=[f"sets of {k} or more candidates were not all searched"])
            checked += 1
            if jets.observes(combo, cols):
                found.append(combo)
                masks.append(bits)
    return StructuralSearch(found, f"every subset of the {n} candidates by size, supersets of a found set skipped",
                            True, True, checked, pruned)


def _minimum_size(jets: CandidateJets, seen: Sequence[int], cols: Sequence[int], need: int,
                  budget: int) -> StructuralSearch:
    """The minimum-size sets: sizes 1, 2, ... by depth-first search over subsets that can still see every target and
    reach the rank; the first size with a set is the minimum when every smaller size was searched to the end."""
    n = len(jets.names)
    M = len(jets.unknowns)
    full = len(cols) == M
    ranks = jets.ranks()
    order = sorted(range(n), key=lambda i: -ranks[i])
    suffix = [0] * (n + 1)        # what the candidates order[j:] can still see together
    for j in range(n - 1, -1, -1):
        suffix[j] = suffix[j + 1] | seen[order[j]]
    state = {"checked": 0, "pruned": 0}
    for k in range(1, n + 1):
        hits: list[tuple[int, ...]] = []
        ok = _dfs(jets, seen, cols, need, full, ranks, order, suffix, k, 0, [], 0, None, hits, state, budget)
        if not ok:
            return _greedy(jets, cols, state, k)
        if hits:
            return StructuralSearch(sorted(hits), f"every set of 1 to {k} candidates, depth first, pruned by the influence "
                                    "graph and by rank", False, True, state["checked"], state["pruned"],
                                    notes=[f"the pool has {n} candidates: only the minimum-size sets ({k} candidates) are "
                                           "listed; larger inclusion-minimal sets may exist"])
    raise AssertionError("the whole pool observes the targets, so some size has a set")


def _dfs(jets: CandidateJets, seen: Sequence[int], cols: Sequence[int], need: int, full: bool, ranks: Sequence[int],
         order: Sequence[int], suffix: Sequence[int], k: int, start: int, chosen: list[int], cover: int,
         ech: RowEchelon | None, hits: list[tuple[int, ...]], state: dict[str, int], budget: int) -> bool:
    """Sets of exactly k candidates extending `chosen` (from order[start:]); False when the budget ran out."""
    left = k - len(chosen)
    if left == 0:
        if cover & need != need:
            state["pruned"] += 1
            return True
        if state["checked"] >= budget:
            return False
        state["checked"] += 1
        members = tuple(sorted(chosen))
        if jets.sees(ech, cols) or any(jets.sees(jets.span(members, k), cols) for k in range(1, len(jets.points))):
            hits.append(members)
        return True
    for j in range(start, len(order) - left + 1):
        c = order[j]
        if (cover | suffix[j]) & need != need:   # even every remaining candidate cannot see some target
            state["pruned"] += 1
            break
        nxt = jets.span([c], 0, ech)
        if full and nxt.rank + sum(ranks[i] for i in order[j + 1: j + left]) < len(jets.unknowns):
            state["pruned"] += 1        # candidates are in decreasing rank: the next left-1 add the most rank
            continue
        if not _dfs(jets, seen, cols, need, full, ranks, order, suffix, k, j + 1, [*chosen, c], cover | seen[c], nxt,
                    hits, state, budget):
            return False
    return True


def _greedy(jets: CandidateJets, cols: Sequence[int], state: dict[str, int], k: int) -> StructuralSearch:
    """A set by greedy rank gain, then reduced to an inclusion-minimal one: its size is not proven minimum."""
    n = len(jets.names)
    chosen: list[int] = []
    ech = RowEchelon(len(jets.unknowns), jets.points[0].prime)
    while not jets.sees(ech, cols) and len(chosen) < n:
        gains = [(jets.span([i], 0, ech).rank, -i) for i in range(n) if i not in chosen]
        best = -max(gains)[1]
        chosen.append(best)
        ech = jets.span([best], 0, ech)
    for c in list(chosen):
        rest = [i for i in chosen if i != c]
        if jets.observes(rest, cols):
            chosen = rest
    return StructuralSearch([tuple(sorted(chosen))], f"every set of up to {k - 1} candidates, then greedy rank gain "
                            f"reduced to an inclusion-minimal set (sets of {k} ran over the budget)", False, False, state["checked"],
                            state["pruned"], notes=[f"no set of fewer than {k} candidates exists; the set listed has "
                                                    f"{len(chosen)}: the minimum is not proven"])


REFERENCE = f"{cite('sedoglavic2002')} (generic rank); {cite('liu2013')} (sink components)"
