"""Mutation testing of the paper-equation modules (mutmut 3): do the tests catch a broken equation?

Each module below implements equations of the papers; mutmut changes its code one small edit
at a time (an operator, a constant, a sign, a dropped argument...) and runs the module's
focused tests against every mutant. A mutant is *killed* when a test fails (or times out);
a *survivor* is a change no test notices. The kill rate is killed / (killed + survived); mutants
no test reaches ("no tests") count as survivors.

Modules and why (the equations they implement):

- design/pebo/_regression.py: 000 eqs. (16)-(17) (the G+D estimator), DREM mixing, gradient and
  least squares, the filters of 004 eq. (37);
- design/kalman/_riccati.py: the Kalman-like observer for state-affine systems and its high-gain
  variant (002), the Riccati ODE Ṁ = λ[...];
- design/pebo/_gpebo.py: the GPEBO / 2G+D observer of 000 (eqs. 8-13, order (3 + 2n)n);
- design/banks/_banks.py and analysis/forms/_conditions.py: Banks' matrix measure, dissipativity and
  Theorem 2.6 (003);
- algebra/_identity.py: the exact identity test every PDE / left-inverse check relies on.

String literals are not mutated (see _LAUNCH), nor raise statements, Check(...) lines and
certificate values (do_not_mutate_patterns): messages and certificate text are not equations.

Each module runs in its own scratch copy (``/tmp/nlobs-mutation/<module>``), so the work tree is
never modified and modules do not interfere. A full run is long (tens of minutes per module on a
shared 2-core machine): it runs under ``nice``, one module at a time.

Run:  .venv/bin/pip install -e '.[mutation]'
      .venv/bin/python benchmarks/mutation.py [--only design/pebo/_regression.py ...] [--max-children 2]
Results: benchmarks/results/mutation.json (per module: killed, survived, no tests, timeouts, rate)
and the survivors' names in benchmarks/results/mutation_survivors.txt (``mutmut show NAME`` in the
scratch directory prints a mutant's diff).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRATCH = Path(os.environ.get("NLOBS_MUTATION_DIR", "/tmp/nlobs-mutation"))

#: module (relative to src/nlobs) -> the focused tests that check its equations
MODULES: dict[str, list[str]] = {
    "design/pebo/_regression.py": ["tests/design/test_regression.py", "tests/design/test_estimators.py",
                                   "tests/design/test_regression_edges.py"],
    "design/kalman/_riccati.py": ["tests/design/test_kalman.py", "tests/design/test_kalman_edges.py", "tests/design/test_high_gain.py"],
    "design/pebo/_gpebo.py": ["tests/design/test_gpebo.py", "tests/papers/test_000_2gd_not_uco.py::test_2gd_error_follows_the_paper_law_to_round_off"],
    "design/banks/_banks.py": ["tests/design/test_banks.py"],
    "analysis/forms/_conditions.py": ["tests/analysis/test_forms_banks.py", "tests/analysis/test_conditions_edges.py",
                                "tests/design/test_banks.py"],
    "algebra/_identity.py": ["tests/analysis/test_identity.py", "tests/analysis/test_identity_exact.py",
                              "tests/design/test_pebo.py", "tests/design/test_iandi.py"],
}

#: module -> the equations it implements, for the docs' table (cited as a user reads it)
EQUATIONS: dict[str, tuple[str, str]] = {
    "design/pebo/_regression.py": ("000", "eqs. (16)-(17); gradient, least squares, DREM"),
    "design/kalman/_riccati.py": ("002", "Kalman-like and high-gain observers"),
    "design/pebo/_gpebo.py": ("000", "Lemma 1, eqs. (5), (8)-(13)"),
    "design/banks/_banks.py": ("003", "Lemma 2.3, Theorem 2.6"),
    "analysis/forms/_conditions.py": ("003", "λ(A), μ_N, Theorem 2.6"),
    "algebra/_identity.py": ("004", "PDE (4) and left-inverse identities"),
}

#: Survivors that are equivalent mutants (no input of the documented domain tells them from the original),
#: each with the reason. They stay in the survivor lists and in the raw kill rate; the docs table also shows the
#: rate among the non-equivalent mutants. Prefix match on the mutant's name.
EQUIVALENT: dict[str, str] = {
    # design/pebo/_regression.py
    "nlobs.design.pebo._regression.x_adjugate__mutmut_2": "the matrix is square: shape[1] == shape[0]",
    "nlobs.design.pebo._regression.x_adjugate__mutmut_25": "(-1)^(i - j) == (-1)^(i + j): i - j and i + j have the same parity",
    "nlobs.design.pebo._regression.xǁExcitationMonitorǁof__mutmut_8": "the placeholder Δ of an estimator without Δ is never read "
                                                                   "(has_delta is False)",
    # design/kalman/_riccati.py (002 Kalman, Kalman-like and LTV-based high-gain observers)
    "nlobs.design.kalman._riccati.x__riccati_design__mutmut_3": "A is square (n x n from state_affine_parts): shape[1] == shape[0]",
    "nlobs.design.kalman._riccati.x__riccati_design__mutmut_154": "the high-gain branch (lam given) is only reached with V = None, so Vm = 0 "
                                                          "and lam*Ric + 0 == lam*Ric - 0",
    "nlobs.design.kalman._riccati.x__riccati_design__mutmut_253": "M0 is exactly symmetric (check_matrix symmetrises it): its C-order and "
                                                          "F-order ravel are the same vector",
    "nlobs.design.kalman._riccati.x__riccati_design__mutmut_255": "M0 is exactly symmetric: C-order (the default) == F-order ravel",
    "nlobs.design.kalman._riccati.x__riccati_design__mutmut_257": "reshape(-2) == reshape(-1): numpy reads any negative size as the inferred one",
    "nlobs.design.kalman._riccati.x__sup_norm__mutmut_28": "box_of does not read its `system` argument (design/_common.py)",
    "nlobs.design.kalman._riccati.x__sup_norm__mutmut_71": "A is square: C-order reshape gives Aᵀ, and ‖Aᵀ‖₂ == ‖A‖₂",
    "nlobs.design.kalman._riccati.x__sup_norm__mutmut_73": "A is square: C-order reshape (the default) gives Aᵀ, and ‖Aᵀ‖₂ == ‖A‖₂",
    "nlobs.design.kalman._riccati.x_design_high_gain_kalman__mutmut_2": "the public design_high_gain_kalman (design/_registry.py wrapper) "
                                                                "refuses a non-System before require_system runs",
    "nlobs.design.kalman._riccati.x_design_high_gain_kalman__mutmut_31": "sp.zeros(n, None) == sp.zeros(n) == sp.zeros(n, n)",
    "nlobs.design.kalman._riccati.x_design_high_gain_kalman__mutmut_32": "sp.zeros(n) == sp.zeros(n, n)",
    "nlobs.design.kalman._riccati.x_design_high_gain_kalman__mutmut_33": "sp.zeros(n, ) == sp.zeros(n, n)",
    "nlobs.design.kalman._riccati.x_design_high_gain_kalman__mutmut_65": "parts.b is not read on the high-gain branch (φ carries the drift): "
                                                                 "its shape does not matter",
    "nlobs.design.kalman._riccati.x_design_high_gain_kalman__mutmut_66": "parts.b is not read on the high-gain branch (see mutmut_65)",
    "nlobs.design.kalman._riccati.x_design_high_gain_kalman__mutmut_67": "parts.b is not read on the high-gain branch (see mutmut_65)",
    "nlobs.design.kalman._riccati.x_design_high_gain_kalman__mutmut_68": "parts.b is not read on the high-gain branch (see mutmut_65)",
    "nlobs.design.kalman._riccati.x_state_affine_parts__mutmut_40": "the caller only enters measured_states' PreconditionError, which "
                                                            "state_affine_parts catches and drops (meas = [])",
    # design/pebo/_gpebo.py, _uniform_stability: 000 assumption (5) for a constant A
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_10": "`eig.size` is never 0: a state-affine model has n >= 1 states",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_12": "the empty-spectrum default is never used (n >= 1)",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_30": "`initial=None` only matters for an empty A (n >= 1)",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_32": "max(1.0, max(|A|, 1.0)) == max(1.0, max|A|)",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_34": "`>=` vs `>` at Re λ exactly equal to the round-off tolerance",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_37": "`<` vs `<=` at |Re λ| exactly equal to the round-off tolerance",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_43": "rounding to 10 instead of 9 digits only groups axis eigenvalues "
                                                          "that agree to 1e-9; the multiplicity count uses 1e-6 anyway",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_48": "eig + λ vs eig - λ: for λ on the imaginary axis -λ = conj(λ), and the "
                                                          "spectrum of a real matrix is conjugate-symmetric with equal multiplicities",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_49": "`<` vs `<=` at a distance of exactly 1e-6",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_53": "A is square: shape[1] == shape[0]",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_61": "A is square: shape[1] == shape[0]",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_55": "rank tolerance: matrix_rank's default (σ_max·n·eps) vs 1e-8; they differ "
                                                          "only for a Jordan coupling below 1e-8, which the code treats as round-off",
    "nlobs.design.pebo._gpebo.x__uniform_stability__mutmut_57": "rank tolerance: see mutmut_55",
    "nlobs.design.pebo._gpebo.x_design_gpebo__mutmut_16": "GD's documented default gain γ is 1.0: GD(1.0) == GD(1.0, 1.0)",
    "nlobs.design.pebo._gpebo.x_design_gpebo__mutmut_17": "GD's documented default gain γ is 1.0: GD(1.0, ) == GD(1.0, 1.0)",
    "nlobs.design.pebo._gpebo.x_design_gpebo__mutmut_103": "Regression.names is only checked for its length (θ names are not shown)",
    "nlobs.design.pebo._gpebo.x_design_gpebo__mutmut_104": "Regression.names is only checked for its length (θ names are not shown)",
    # analysis/forms/_conditions.py, box_sup (the sampled suprema of 003 Lemma 2.4, Theorem 2.6): conversions of arrays that
    # are already float, the optimiser scipy picks anyway, iteration caps that are never reached
    "nlobs.analysis.forms._conditions.x_box_sup__mutmut_22": "3^d instead of 2^d corners: the extra indices repeat corners (bits above d unused)",
    "nlobs.analysis.forms._conditions.x_box_sup__mutmut_43": "the function values are already float arrays",
    "nlobs.analysis.forms._conditions.x_box_sup__mutmut_45": "the function values are already float arrays",
    "nlobs.analysis.forms._conditions.x_box_sup__mutmut_85": "maxiter 101 instead of 100: L-BFGS-B converges well before",
    "nlobs.analysis.forms._conditions.x_box_sup__mutmut_94": "res.x is already a float array",
    "nlobs.analysis.forms._conditions.x_box_sup__mutmut_96": "res.x is already a float array",
    "nlobs.analysis.forms._conditions.x_box_sup__mutmut_68": "scipy chooses L-BFGS-B itself for a bounded problem without constraints",
    "nlobs.analysis.forms._conditions.x_box_sup__mutmut_73": "scipy chooses L-BFGS-B itself for a bounded problem without constraints",
    "nlobs.analysis.forms._conditions.x_box_sup__mutmut_69": "maxiter default (15000) instead of 100: L-BFGS-B converges well before",
    "nlobs.analysis.forms._conditions.x_box_sup__mutmut_74": "maxiter default (15000) instead of 100: L-BFGS-B converges well before",
    # algebra/_identity.py: the exact identity test (every PDE (4) / left-inverse check of 004)
    "nlobs.algebra._identity.x__grid_point__mutmut_9": "the fallback grid starts at 0.100001 instead of 0.1: one of its 800,001 "
                                                        "points, which no verdict depends on",
    "nlobs.algebra._identity.x__grid_point__mutmut_10": "the fallback grid ends at 0.900001 instead of 0.9 (see mutmut_9)",
    "nlobs.algebra._identity.x__numeric__mutmut_17": "sympy.N with its default 15 digits instead of 30: evalf targets the relative "
                                                      "accuracy of the result (it raises the working precision through "
                                                      "cancellation), so both decide |e| > 1e-20 × scale alike",
    "nlobs.algebra._identity.x__numeric__mutmut_19": "sympy.N with its default 15 digits (see mutmut_17)",
    "nlobs.algebra._identity.x__numeric__mutmut_26": "the scale (largest |term|) to 15 instead of 30 digits: a scale, not a decision",
    "nlobs.algebra._identity.x__numeric__mutmut_28": "the scale to 15 instead of 30 digits (see mutmut_26)",
    "nlobs.algebra._identity.x__numeric__mutmut_45": "`>=` vs `>` at a relative size of exactly 1e-20",
    "nlobs.algebra._identity.x__rational_test__mutmut_11": "a constant has no symbols: the point is never read ({} or None)",
    "nlobs.algebra._identity.x__short__mutmut_3": "the 256-bit gate only guards str() against huge integers: any value of 200 "
                                                   "or more bits has more than 60 characters and takes the 6-digit form either way",
    "nlobs.algebra._identity.x__short__mutmut_4": "the 256-bit gate (see mutmut_3)",
    "nlobs.algebra._identity.x__short__mutmut_10": "mpmath.nstr(strip_zeros=None) == strip_zeros=False (falsy)",
    "nlobs.algebra._identity.x_decide_identity__mutmut_2": "the default seed 1 instead of 0: any seed draws equally good points",
    "nlobs.algebra._identity.x_exact_generic_rank__mutmut_1": "the default seed 1 instead of 0 (see decide_identity mutmut_2)",
    "nlobs.algebra._identity.x_exact_generic_rank__mutmut_4": "unseeded points: the rank verdict does not depend on the points "
                                                              "(except with the stated probability) and is not reported with them",
    "nlobs.algebra._identity.x_decide_identity__mutmut_63": "count_ops(None) = 0: simplify is tried on any size, a cost the 5 s "
                                                             "time limit bounds; the verdicts are the same",
    "nlobs.algebra._identity.x_decide_identity__mutmut_64": "`<` vs `<=` at exactly 3000 operations: a cost cut-off",
    "nlobs.algebra._identity.x_decide_identity__mutmut_65": "3001 vs 3000 operations: a cost cut-off",
    "nlobs.algebra._identity.xǁ_Rationaliserǁ__call____mutmut_16": "b^(p/q) -> b^m / R^r for every root R: the same as renaming "
                                                                     "the independent variable R to 1/R everywhere, which "
                                                                     "preserves 'identically zero'",
    "nlobs.algebra._identity.xǁ_Rationaliserǁ__call____mutmut_64": "exp(c g) -> E_g^-c for every g: renaming E_g to 1/E_g "
                                                                     "everywhere (see _Rationaliser mutmut_16)",
    "nlobs.algebra._identity.xǁ_Rationaliserǁ__call____mutmut_68": "exp(term) -> 1/E_term for every non-integer multiple: a "
                                                                     "renaming (see _Rationaliser mutmut_16)",
}


def is_equivalent(name: str) -> str | None:
    """The reason a surviving mutant is equivalent, or None."""
    return EQUIVALENT.get(name.split(" ")[0])


_SETUP = r"""
[tool.mutmut]
source_paths = ["src/nlobs"]
only_mutate = ["src/nlobs/{module}"]
pytest_add_cli_args_test_selection = {tests}
pytest_add_cli_args = ["-p", "no:cacheprovider"]
timeout_multiplier = 5.0
timeout_constant = 30.0
use_git_change_detection = false
# error messages and certificate text are not equations: raise statements, Check(...) lines and
# certificate values are left alone (a changed message is not a broken equation)
do_not_mutate_patterns = ['^\s*raise ', 'Check\(|Check\.assumed\(', 'values\[|values\.update|values = \{|values: dict', '__str__']
"""


# mutmut with one operator removed: string literals (error messages, certificate text, labels) are not
# mutated. A changed message is not a broken equation, and those mutants would dominate the count.
_LAUNCH = (
    "import sys; import mutmut.mutation.mutators as m; "
    "m.mutation_operators[:] = [(t, f) for t, f in m.mutation_operators if f.__name__ != 'operator_string']; "
    "from mutmut.__main__ import cli; sys.argv[0] = 'mutmut'; cli()"
)


def _prepare(module: str, tests: list[str]) -> Path:
    work = SCRATCH / module.replace("/", "__").removesuffix(".py")
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    shutil.copytree(ROOT / "src", work / "src", ignore=shutil.ignore_patterns("__pycache__", "*.so"))
    shutil.copytree(ROOT / "tests", work / "tests", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", work / "pyproject.toml")
    text = (work / "pyproject.toml").read_text()
    # pytest options of the project apply (warnings as errors, markers); mutmut's own table is appended
    table = _SETUP.replace("{module}", module).replace("{tests}", json.dumps(tests))
    (work / "pyproject.toml").write_text(text + table)
    # PYTHONPATH points at mutants/src; it must exist before mutmut starts, or Python caches "no such
    # directory" for it and the tests import the unmutated package through the editable install
    (work / "mutants" / "src").mkdir(parents=True)
    return work


def _refresh(module: str, tests: list[str]) -> tuple[Path, list[str]]:
    """For a re-run of the survivors: the previous scratch copy with today's tests, and the mutants that were not
    killed. Refused when the module's source changed since (mutant names and numbers would not match)."""
    work = SCRATCH / module.replace("/", "__").removesuffix(".py")
    old = work / "src" / "nlobs" / module
    if not old.exists() or old.read_text() != (ROOT / "src" / "nlobs" / module).read_text():
        raise SystemExit(f"{module}: no previous run of the same source in {work}; run it in full first")
    shutil.rmtree(work / "tests")
    shutil.copytree(ROOT / "tests", work / "tests", ignore=shutil.ignore_patterns("__pycache__"))
    text = (ROOT / "pyproject.toml").read_text()
    (work / "pyproject.toml").write_text(text + _SETUP.replace("{module}", module).replace("{tests}", json.dumps(tests)))
    from mutmut.stats import status_by_exit_code

    names = [name for meta in (work / "mutants").rglob("*.meta")
             for name, code in json.loads(meta.read_text()).get("exit_code_by_key", {}).items()
             if status_by_exit_code[code] in ("survived", "no tests", "not checked")]
    return work, names


def _codes(work: Path) -> dict[str, int | None]:
    """mutmut's exit code of every mutant (None: not run)."""
    return {name: code for meta in (work / "mutants").rglob("*.meta")
            for name, code in json.loads(meta.read_text()).get("exit_code_by_key", {}).items()}


def _merge_previous(work: Path, previous: dict[str, int | None]) -> None:
    """After a re-run of the survivors, mutmut's .meta files hold codes only for the mutants it ran; the others keep
    their previous result (killed stays killed: the tests were only added to)."""
    for meta in (work / "mutants").rglob("*.meta"):
        data = json.loads(meta.read_text())
        codes = data.get("exit_code_by_key", {})
        for name, code in codes.items():
            if code is None and previous.get(name) is not None:
                codes[name] = previous[name]
        meta.write_text(json.dumps(data))


def _count(work: Path) -> dict[str, object]:
    """Tally mutmut's per-mutant results from its .meta files (mutants/**.meta), with mutmut's own
    exit-code meanings (mutmut.stats.status_by_exit_code)."""
    from mutmut.stats import status_by_exit_code

    counts: dict[str, object] = {}
    survivors: list[str] = []
    for meta in (work / "mutants").rglob("*.meta"):
        data = json.loads(meta.read_text())
        for name, code in data.get("exit_code_by_key", {}).items():
            status = status_by_exit_code[code]
            counts[status] = int(counts.get(status, 0)) + 1  # type: ignore[arg-type]
            if status in ("survived", "no tests"):
                survivors.append(f"{name} ({status})")
    for key in ("killed", "survived", "no tests", "timeout", "segfault", "suspicious", "not checked"):
        counts.setdefault(key, 0)
    counts["survivor_names"] = sorted(survivors)
    return counts


def run_module(module: str, tests: list[str], max_children: int, survivors_only: bool = False) -> dict[str, object]:
    work, names = _refresh(module, tests) if survivors_only else (_prepare(module, tests), [])
    previous = _codes(work) if survivors_only else {}
    env = {**os.environ, "PYTHONPATH": str(work / "mutants" / "src"), "NLOBS_CACHE": str(work / ".cache")}
    t0 = time.time()
    proc = subprocess.run(["nice", "-n", "15", sys.executable, "-c", _LAUNCH, "run", "--max-children", str(max_children),
                           *names], cwd=work, env=env, capture_output=True, text=True)
    elapsed = time.time() - t0
    if survivors_only:
        _merge_previous(work, previous)
    (work / "mutmut.log").write_text(proc.stdout[-200_000:] + "\n--- stderr ---\n" + proc.stderr[-200_000:])
    counts = _count(work)
    caught = int(counts["killed"]) + int(counts["timeout"]) + int(counts["segfault"])   # type: ignore[arg-type]
    decided = caught + int(counts["survived"]) + int(counts["no tests"])                # type: ignore[arg-type]
    rate = caught / decided if decided else float("nan")
    return {"module": module, "tests": tests, "seconds": round(elapsed, 1), "exit_code": proc.returncode,
            "rate": rate, **counts, "scratch": str(work)}


DOCS_PAGE = ROOT / "docs" / "benchmarks.rst"
DOCS_BEGIN = ".. mutation table: generated by ``python benchmarks/mutation.py --docs`` from benchmarks/results/mutation.json"
DOCS_END = ".. end of the mutation table"
HEADER = ("module (paper equations)", "mutants", "killed", "kill rate", "equivalent (listed)", "kill rate of the others",
          "tests")


def table_rows(results: dict[str, dict[str, object]]) -> list[tuple[str, ...]]:
    """The docs table's rows, from the run's JSON (modules in MODULES order)."""
    from nlobs.references import cite

    rows = []
    for module in MODULES:
        r = results.get(module)
        key, eqs = EQUATIONS[module]
        what = f"``{module}`` ({cite(key, eqs)})"
        tests = ", ".join(f"``{t.split('::')[0].removeprefix('tests/')}``" for t in MODULES[module])
        if r is None or not r.get("exit_code", 1) == 0:
            rows.append((what, "–", "–", "not run", "–", "–", tests))
            continue
        caught = int(r["killed"]) + int(r["timeout"]) + int(r["segfault"])                   # type: ignore[arg-type]
        total = caught + int(r["survived"]) + int(r["no tests"])                              # type: ignore[arg-type]
        eq = int(r.get("equivalent", 0))                                                      # type: ignore[arg-type]
        adj = f"{caught / (total - eq):.1%}" if total - eq else "–"
        rows.append((what, str(total), str(caught), f"{caught / total:.1%}", str(eq), adj, tests))
    return rows


def docs_table(results: dict[str, dict[str, object]]) -> str:
    """The reStructuredText list-table of the docs' speed-and-accuracy page."""
    lines = [".. list-table::", "   :header-rows: 1", ""]
    for row in [HEADER, *table_rows(results)]:
        lines += [("   * - " if k == 0 else "     - ") + cell for k, cell in enumerate(row)]
    return "\n".join(lines)


def write_docs(results: dict[str, dict[str, object]]) -> None:
    text = DOCS_PAGE.read_text(encoding="utf-8")
    start, end = text.index(DOCS_BEGIN) + len(DOCS_BEGIN), text.index(DOCS_END)
    DOCS_PAGE.write_text(text[:start] + "\n\n" + docs_table(results) + "\n\n" + text[end:], encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", help="modules to run (keys of MODULES)")
    ap.add_argument("--max-children", type=int, default=2)
    ap.add_argument("--docs", action="store_true", help="only rewrite the table in docs/benchmarks.rst from the JSON")
    ap.add_argument("--survivors", action="store_true",
                    help="re-run only the previous run's survivors against today's tests (the module's source unchanged); "
                         "killed mutants stay killed, since tests were only added")
    args = ap.parse_args(argv)
    out = ROOT / "benchmarks" / "results" / "mutation.json"
    if args.docs:
        write_docs(json.loads(out.read_text()))
        return 0
    try:
        import mutmut  # noqa: F401
    except ImportError:
        print("mutmut is not installed: .venv/bin/pip install -e '.[mutation]'", file=sys.stderr)
        return 2
    chosen = args.only or list(MODULES)
    unknown = [m for m in chosen if m not in MODULES]
    if unknown:
        print(f"unknown module(s) {unknown}; choose from {list(MODULES)}", file=sys.stderr)
        return 2
    results = json.loads(out.read_text()) if out.exists() else {}
    for module in chosen:
        print(f"{module}: mutating, tests {' '.join(MODULES[module])} ...", flush=True)
        res = run_module(module, MODULES[module], args.max_children, args.survivors)
        if args.survivors:
            res["seconds"] = round(float(results.get(module, {}).get("seconds", 0.0)) + float(res["seconds"]), 1)  # type: ignore[arg-type]
            res["survivors_rerun"] = True
        names: list[str] = res["survivor_names"]  # type: ignore[assignment]
        equivalent = [n for n in names if is_equivalent(n)]
        res["equivalent"] = len(equivalent)
        results[module] = {k: v for k, v in res.items() if k != "survivor_names"}
        surv = ROOT / "benchmarks" / "results" / f"mutation_survivors_{module.replace('/', '__').removesuffix('.py')}.txt"
        surv.write_text("".join(f"{n}" + (f"  [equivalent: {is_equivalent(n)}]" if is_equivalent(n) else "") + "\n"
                                for n in names))
        print(f"  killed {res['killed']}, timeout {res['timeout']}, survived {res['survived']}, no tests {res['no tests']}: "
              f"kill rate {res['rate']:.1%} ({res['seconds']:.0f} s)", flush=True)
        out.write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
        write_docs(results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
