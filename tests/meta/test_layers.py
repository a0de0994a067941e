"""The package's layers, read from its source: data flows one way and no module imports its own importers.

Every ``import`` counts, at module level or inside a function (a function-level import is a real dependency, only
a later one); imports under ``if TYPE_CHECKING:`` do not (annotations only). Two rules:

1. No cycle between modules, and no two files that import each other (here an import under ``TYPE_CHECKING``
   counts too). There is no exception (:data:`ALLOWED_CYCLES` is empty): ``System.lti`` builds through the
   registry ``model._system.FORMS`` that ``model/_forms.py`` fills, and ``simulate/_plot.py`` reads a run through
   a protocol.
2. A lower layer never imports a higher one (:data:`LAYERS`, lowest first; packages in one layer do not import
   each other either way round beyond what is listed). Inside a package split into rooms (:data:`ROOMS`: the
   sub-packages of ``analysis``; the shared modules and the family sub-packages of ``design``) the same rule
   holds between its rooms; the package's ``__init__`` re-exports them all.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"

#: Lowest first. Leaf utilities (no nlobs imports of their own, or only of each other) form layer 0.
LAYERS: tuple[frozenset[str], ...] = (
    frozenset({"_version", "_text", "_display", "_progress", "_deprecate", "_process", "_memory", "references", "errors"}),
    frozenset({"model"}),
    frozenset({"engine"}),
    frozenset({"algebra"}),             # exact and modular tools (no verdicts): below analysis, used by design too
    frozenset({"analysis"}),
    frozenset({"design"}),
    frozenset({"observer"}),
    frozenset({"simulate"}),            # plant and observer runs, Monte Carlo, results
    frozenset({"estimation"}),          # observers and smoothers on recordings, the sensor check
    frozenset({"learning"}),            # parameters and noise fitted to recordings (fit, likelihood, tune)
    frozenset({"advise", "interop"}),
    frozenset({"examples"}),
    frozenset({"report"}),
    frozenset({"cli"}),
    frozenset({"__init__"}),            # the package's public face re-exports every layer
)

#: Packages split into rooms (their sub-packages and shared private modules), lowest first, by the same rule as
#: :data:`LAYERS`: a room never imports a higher one, and rooms of one level do not import each other.
ROOMS: dict[str, tuple[frozenset[str], ...]] = {
    "analysis": (
        frozenset({"_reports"}),                      # the result types and number formatting the rooms share
        frozenset({"structural", "trajectory"}),      # from the equations / along one trajectory
        frozenset({"forms", "sensors"}),              # structure for designs; sensor selection (rank + Fisher information)
    ),
    # design: the shared modules at the bottom, then the families (sub-packages) in the order they build on each other
    "design": (
        frozenset({"_base"}),                                   # ObserverDesign, Certificate, Check
        frozenset({"_checks", "_kind", "_common", "_bounds"}),  # preconditions, the kind registry, symbolic helpers
        frozenset({"_constructions"}),                          # chains, Ψ, KKL maps, Banks' gain
        frozenset({"_tune"}),                                   # the advisor's tunings shared by the kinds
        frozenset({"lipschitz", "banks", "mhe", "_custom", "_registry"}),
        frozenset({"high_gain"}),                               # uses the region's Lipschitz constant
        frozenset({"kalman"}),                                  # the high-gain Kalman observer uses the high-gain chains
        frozenset({"pebo", "linear"}),                          # GPEBO and the augmented observer use the Riccati design
    ),
}

#: Module cycles that are allowed, each as the sorted tuple of its modules (none).
ALLOWED_CYCLES: set[tuple[str, ...]] = set()


def _modules() -> dict[str, tuple[Path, bool]]:
    out = {}
    for p in (SRC / "nlobs").rglob("*.py"):
        parts = list(p.relative_to(SRC).with_suffix("").parts)
        pkg = parts[-1] == "__init__"
        out[".".join(parts[:-1] if pkg else parts)] = (p, pkg)
    return out


def _type_checking_lines(tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for sub in node.body:
                lines.update(range(sub.lineno, (sub.end_lineno or sub.lineno) + 1))
    return lines


def import_graph(src: Path = SRC, *, type_checking: bool = False) -> dict[str, set[str]]:
    """Module -> the nlobs modules it imports (resolved to modules or packages); with `type_checking`, the imports
    under ``if TYPE_CHECKING:`` too."""
    mods = _modules()
    edges: dict[str, set[str]] = {m: set() for m in mods}
    for mod, (path, pkg) in mods.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        skip = set() if type_checking else _type_checking_lines(tree)
        for node in ast.walk(tree):
            if not isinstance(node, (ast.Import, ast.ImportFrom)) or node.lineno in skip:
                continue
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names if a.name.split(".")[0] == "nlobs"]
            else:
                if node.level:
                    base = mod.split(".") if pkg else mod.split(".")[:-1]
                    base = base[:len(base) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                if target.split(".")[0] != "nlobs":
                    continue
                targets = [f"{target}.{a.name}" if f"{target}.{a.name}" in mods else target for a in node.names]
            for t in targets:
                while t and t not in mods:
                    t = t.rsplit(".", 1)[0] if "." in t else ""
                if t and t != mod:
                    edges[mod].add(t)
    return edges


def module_cycles(edges: dict[str, set[str]], packages: frozenset[str] | None = None) -> list[tuple[str, ...]]:
    """Strongly connected components of more than one module (edges into a package's ``__init__`` are re-exports
    and left out: the package-level rule below covers them)."""
    if packages is None:
        packages = frozenset(m for m, (_, pkg) in _modules().items() if pkg)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[tuple[str, ...]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w in packages:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(tuple(sorted(comp)))

    for v in edges:
        if v not in index:
            visit(v)
    return out


def _layer(module: str) -> int:
    parts = module.split(".")
    top = parts[1] if len(parts) > 1 else "__init__"
    for i, layer in enumerate(LAYERS):
        if top in layer:
            return i
    raise AssertionError(f"{module}: its package `{top}` has no layer in tests/meta/test_layers.py LAYERS; add it")


def _room(module: str) -> int | None:
    """The room of a module inside a package of :data:`ROOMS` (the package's own ``__init__`` above them all), or
    None outside such a package."""
    parts = module.split(".")
    if len(parts) < 2 or parts[1] not in ROOMS:
        return None
    rooms = ROOMS[parts[1]]
    if len(parts) == 2:
        return len(rooms)
    for i, room in enumerate(rooms):
        if parts[2] in room:
            return i
    raise AssertionError(f"{module}: `{parts[2]}` has no room in tests/meta/test_layers.py ROOMS[{parts[1]!r}]; add it")


def _crosses_rooms(m: str, t: str) -> bool:
    """`m` imports `t` in the same roomed package, from a room below `t`'s or from a neighbour of its level."""
    if m.split(".")[:2] != t.split(".")[:2] or (rm := _room(m)) is None or rm == len(ROOMS[m.split(".")[1]]):
        return False
    rt = _room(t)
    assert rt is not None
    return rt > rm or (rt == rm and m.split(".")[2] != t.split(".")[2] and len(ROOMS[m.split(".")[1]][rm]) > 1)


def upward_imports(edges: dict[str, set[str]]) -> list[str]:
    bad = []
    for m, ts in edges.items():
        for t in ts:
            if _layer(t) > _layer(m) or (_layer(t) == _layer(m) and m.split(".")[:2] != t.split(".")[:2]
                                         and len(LAYERS[_layer(m)]) > 1 and _layer(m) > 0) or _crosses_rooms(m, t):
                bad.append(f"{m} imports {t}")
    return sorted(bad)


def test_no_import_cycles():
    cycles = [c for c in module_cycles(import_graph()) if c not in ALLOWED_CYCLES]
    assert not cycles, "import cycles (imports inside functions count): " + "; ".join(" <-> ".join(c) for c in cycles)


def mutual_imports(edges: dict[str, set[str]]) -> list[tuple[str, str]]:
    """Pairs of files that import each other, packages' ``__init__`` files included."""
    return sorted({tuple(sorted((m, t))) for m, ts in edges.items() for t in ts if m in edges.get(t, ())})


def test_no_two_files_import_each_other():
    # stricter than the cycle check: an import for annotations only (under TYPE_CHECKING) counts too
    pairs = mutual_imports(import_graph(type_checking=True))
    assert not pairs, "files that import each other: " + "; ".join(" <-> ".join(p) for p in pairs)


def test_no_import_goes_up_a_layer():
    bad = upward_imports(import_graph())
    assert not bad, "imports that go up a layer: " + "; ".join(bad)


def test_the_checks_see_a_cycle_and_an_upward_import():
    # the same checks on a hand-made graph: a cycle through a function-level import, and model importing design
    edges = {"nlobs.model._a": {"nlobs.model._b"}, "nlobs.model._b": {"nlobs.model._a", "nlobs.design._x"},
             "nlobs.design._x": set()}
    assert module_cycles(edges, packages=frozenset()) == [("nlobs.model._a", "nlobs.model._b")]
    assert mutual_imports(edges) == [("nlobs.model._a", "nlobs.model._b")]
    assert mutual_imports({"nlobs.x": {"nlobs.x._a"}, "nlobs.x._a": {"nlobs.x"}}) == [("nlobs.x", "nlobs.x._a")]
    assert upward_imports(edges) == ["nlobs.model._b imports nlobs.design._x"]
    # algebra sits below analysis; inside analysis a room never imports a higher one, nor its neighbour
    edges = {"nlobs.algebra._m": {"nlobs.analysis.structural._g"},
             "nlobs.analysis.structural._g": {"nlobs.analysis.forms._r", "nlobs.analysis.trajectory._t",
                                              "nlobs.analysis._reports", "nlobs.algebra._m", "nlobs.analysis.structural._h"},
             "nlobs.analysis.structural._h": set(),
             "nlobs.analysis.forms._r": {"nlobs.analysis.trajectory._t", "nlobs.analysis._reports", "nlobs.analysis"},
             "nlobs.analysis.trajectory._t": {"nlobs.analysis._reports"},
             "nlobs.analysis._reports": {"nlobs.analysis.trajectory"},
             "nlobs.analysis.trajectory": {"nlobs.analysis.trajectory._t"},
             "nlobs.analysis": {"nlobs.analysis.forms._r", "nlobs.algebra._m"}}
    assert upward_imports(edges) == ["nlobs.algebra._m imports nlobs.analysis.structural._g",
                                     "nlobs.analysis._reports imports nlobs.analysis.trajectory",
                                     "nlobs.analysis.forms._r imports nlobs.analysis",
                                     "nlobs.analysis.structural._g imports nlobs.analysis.forms._r",
                                     "nlobs.analysis.structural._g imports nlobs.analysis.trajectory._t"]
    # in design a shared module never imports a family, nor a family a higher or neighbouring one
    edges = {"nlobs.design._tune": {"nlobs.design.pebo._regression", "nlobs.design._constructions"},
             "nlobs.design.kalman._riccati": {"nlobs.design.high_gain._high_gain", "nlobs.design._tune"},
             "nlobs.design.pebo._gpebo": {"nlobs.design.kalman._riccati", "nlobs.design.linear._linear"},
             "nlobs.design.lipschitz._lipschitz": {"nlobs.design.high_gain._high_gain"}}
    assert upward_imports(edges) == ["nlobs.design._tune imports nlobs.design.pebo._regression",
                                     "nlobs.design.lipschitz._lipschitz imports nlobs.design.high_gain._high_gain",
                                     "nlobs.design.pebo._gpebo imports nlobs.design.linear._linear"]


def test_function_level_imports_count():
    # observer/_base.py once imported observer/_particles inside a function while _particles imported _base: a
    # cycle the module-level view misses. The graph must contain function-level edges.
    src = "def f():\n    from ._particles import P\n"
    tree = ast.parse(src)
    found = [n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert found and found[0].module == "_particles"
    edges = import_graph()
    assert "nlobs.analysis.structural._lie" in edges["nlobs.analysis.structural._analyze"]  # a module-level edge
    assert "nlobs.design.lipschitz._lipschitz" in edges["nlobs.design.high_gain._high_gain"]  # a function-level one
