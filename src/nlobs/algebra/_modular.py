"""Arithmetic in the prime field GF(p) on NumPy int64 arrays: primes, inverses, roots, row reduction, polynomials mod p.

The generic-rank test (``analysis/structural/_lie.py``) evaluates truncated power series at a random point of
GF(p)^M. Every value is kept in ``[0, p)``; a product of two values is below p² < 2⁵⁴ and a dot
product of at most :data:`MAX_TERMS` such products stays below 2⁶³, so int64 never overflows.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import sympy as sp

if TYPE_CHECKING:
    from ._groebner import Poly

__all__ = ["PRIME_BITS", "MAX_TERMS", "random_prime", "inv", "modsqrt", "root", "RowEchelon", "COEFF_BOUND", "monomial_exponents", "ratrec", "kernel_mod_p", "monomial_value", "monomial_values",
           "sparse_mod_p", "sparse_value", "sparse_gradient", "poly_mul", "poly_value", "var_power", "minimal_polynomial",
           "distinct_roots"]

#: Primes are drawn from [2**(PRIME_BITS-1), 2**PRIME_BITS).
PRIME_BITS = 27
#: Longest dot product of reduced values that cannot overflow int64: 512 * (2**27)**2 = 2**63.
MAX_TERMS = 511


def _is_prime(n: int) -> bool:
    """Deterministic Miller-Rabin for n < 3.3e24 (bases 2..41)."""
    if n < 2:
        return False
    small = (2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41)
    for q in small:
        if n % q == 0:
            return n == q
    d, s = n - 1, 0
    while d % 2 == 0:
        d, s = d // 2, s + 1
    for a in small:
        x = pow(a, d, n)
        if x in (1, n - 1):
            continue
        for _ in range(s - 1):
            x = x * x % n
            if x == n - 1:
                break
        else:
            return False
    return True


def random_prime(rng: np.random.Generator, odd_roots: frozenset[int] = frozenset(), *,
                 interval: tuple[int, int] | None = None, three_mod_four: bool = True) -> int:
    """A random prime p in `interval` (default [2^26, 2^27)), p ≡ 3 (mod 4) unless `three_mod_four` is False
    (then any odd prime), with gcd(r, p - 1) = 1 for every r in `odd_roots`.

    p ≡ 3 (mod 4) makes square roots a single power, and gcd(r, p - 1) = 1 makes every element an
    r-th power with the unique root ``a ** (r⁻¹ mod p-1)``.
    """
    lo, hi = interval if interval is not None else (1 << (PRIME_BITS - 1), 1 << PRIME_BITS)
    low_bits = 3 if three_mod_four else 1
    while True:
        c = int(rng.integers(lo, hi)) | low_bits
        if c < hi and _is_prime(c) and all(np.gcd(r, c - 1) == 1 for r in odd_roots):
            return c


def inv(a: int, p: int) -> int:
    """The inverse of a nonzero a modulo p (raises ZeroDivisionError for a ≡ 0)."""
    a = int(a) % p
    if a == 0:
        raise ZeroDivisionError("division by zero modulo p")
    return pow(a, p - 2, p)


def modsqrt(a: int, p: int) -> int | None:
    """A square root of a modulo p ≡ 3 (mod 4) that is itself a square (so roots can be nested), or None."""
    a = int(a) % p
    if a == 0:
        return 0
    s = pow(a, (p + 1) // 4, p)
    if s * s % p != a:
        return None
    # exactly one of ±s is a square when p ≡ 3 (mod 4); prefer it so that 4th, 8th... roots exist
    return s if pow(s, (p - 1) // 2, p) == 1 else p - s


def root(a: int, r: int, p: int) -> int | None:
    """An r-th root of a modulo p, or None when there is none (p from :func:`random_prime` with r's odd part)."""
    a = int(a) % p
    e = 0
    while r % 2 == 0:
        r, e = r // 2, e + 1
    out = pow(a, pow(r, -1, p - 1), p) if r > 1 else a
    for _ in range(e):
        s = modsqrt(out, p)
        if s is None:
            return None
        out = s
    return out


def _terms_for(p: int) -> int:
    """Longest dot product of values reduced modulo `p` that cannot overflow int64 (MAX_TERMS for the primes of
    PRIME_BITS bits; 1 for a prime near 2^31, whose products alone reach 2^62)."""
    return MAX_TERMS if p <= 2**PRIME_BITS else max(1, (2**63 - 1 - p) // (p - 1) ** 2)


def _int_matmul(C: np.ndarray, B: np.ndarray, p: int) -> np.ndarray:
    """(C @ B) mod p for reduced C (m x r, or a vector of length r) and B (r x n) in int64, in chunks of the inner
    dimension that cannot overflow."""
    out = np.zeros(C.shape[:-1] + B.shape[1:], dtype=np.int64)
    step = _terms_for(p)
    for i in range(0, C.shape[-1], step):
        out = (out + (C[..., i:i + step] @ B[i:i + step]) % p) % p
    return out


#: Half of a value of PRIME_BITS bits, in :func:`matmul_mod`'s floating-point products.
_LOW_BITS = 14
#: Longest exact floating-point dot product there: 2^12 terms below 2^27 * 2^14 sum below 2^53.
_FLOAT_TERMS = 2**(53 - PRIME_BITS - _LOW_BITS)
#: Smallest product (m * r * n multiplications) given to BLAS: below, numpy's integer product costs less than the
#: conversions.
_FLOAT_WORK = 200_000


@functools.lru_cache(maxsize=1)
def _blas() -> Any:
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


def _one_blas_thread() -> Any:
    """BLAS on one thread for the duration (threadpoolctl): its idle threads spin between the many small products of
    the search (hiv2: 4.4 s of CPU for 2.9 s of wall), and two routes racing would oversubscribe the cores."""
    return _blas().limit(limits=1, user_api="blas")


def matmul_mod(C: np.ndarray, B: np.ndarray, p: int) -> np.ndarray:
    """(C @ B) mod p for reduced C (m x r) and B (r x n), exactly.

    Large products run in double precision through BLAS (numpy's integer product has no BLAS: 0.8 GFLOP/s, most of a
    10-state model's search): B is split into its low 14 bits and the rest, so each partial sum of C @ B_low (at most
    2^12 products below 2^27 * 2^14) and of C @ B_high stays below 2^53, where doubles are exact integers, whatever
    the order in which BLAS adds them. Small products and primes above PRIME_BITS bits use int64, in chunks of the
    inner dimension that cannot overflow.
    """
    m, r = C.shape
    n = B.shape[1]
    if p <= 2**PRIME_BITS and m * r * n >= _FLOAT_WORK:
        out = np.zeros((m, n), dtype=np.int64)
        mask = (1 << _LOW_BITS) - 1
        with _one_blas_thread():
            for i in range(0, r, _FLOAT_TERMS):
                Cf = C[:, i:i + _FLOAT_TERMS].astype(np.float64)
                Bi = B[i:i + _FLOAT_TERMS]
                low = (Cf @ (Bi & mask).astype(np.float64)).astype(np.int64) % p
                high = (Cf @ (Bi >> _LOW_BITS).astype(np.float64)).astype(np.int64) % p
                out = (out + low + (high << _LOW_BITS) % p) % p
        return out
    return _int_matmul(C, B, p)


#: Rows added at once from which :meth:`RowEchelon.add_many` hands the elimination to FLINT.
FLINT_BATCH = 24
#: ... and columns: below, the row-by-row updates (at most `ncols` of them, each over the rows left) cost less than
#: the conversion to and from FLINT (the tangent spaces of the identifiable-function search, 15-30 columns: CGV1990
#: 7.7 s -> 5.2 s with 48; 32 to 128 measured alike)
FLINT_COLUMNS = 48


class RowEchelon:
    """Incremental row reduction over GF(p): add rows one at a time, keep a fully reduced basis.

    The basis is stored as one matrix whose rows each have a leading 1 at their pivot column and
    zeros in every other pivot column, so reducing a row is one product ``v - v[pivots] @ B`` and
    adding a row one rank-1 update: O(rank · ncols) vectorised work per row.

    Attributes
    ----------
    pivots : list of int
        Pivot column of each basis row.
    """

    def __init__(self, ncols: int, p: int):
        self.ncols = ncols
        self.p = p
        self._B = np.zeros((min(ncols, 8), ncols), dtype=np.int64)
        self.pivots: list[int] = []

    @property
    def rank(self) -> int:
        return len(self.pivots)

    @property
    def basis(self) -> np.ndarray:
        """The reduced rows, shape (rank, ncols)."""
        return self._B[: self.rank]

    def reduce(self, row: np.ndarray) -> np.ndarray:
        """`row` minus its projection on the basis (zero iff `row` is in the row space)."""
        p = self.p
        v = np.asarray(row, dtype=np.int64) % p
        if not self.pivots:
            return v
        c = v[self.pivots]
        if not c.any():
            return v
        return (v - _int_matmul(c, self.basis, p)) % p

    def contains(self, row: np.ndarray) -> bool:
        return not np.any(self.reduce(row))

    def reduce_many(self, rows: np.ndarray) -> np.ndarray:
        """Every row of `rows` (m x ncols) minus its projection on the basis: :meth:`reduce` row by row, as one product."""
        p = self.p
        V = np.asarray(rows, dtype=np.int64).reshape(-1, self.ncols) % p
        if not self.pivots or V.shape[0] == 0:
            return V
        C = V[:, self.pivots]
        if not C.any():
            return V
        return (V - matmul_mod(C, self.basis, p)) % p

    def add(self, row: np.ndarray) -> bool:
        """Add `row`; return True if it increased the rank."""
        v = self.reduce(row)
        nz = np.flatnonzero(v)
        if nz.size == 0:
            return False
        self._push(v, int(nz[0]))
        return True

    def add_many(self, rows: np.ndarray) -> int:
        """Add the rows of `rows` in order, stopping at full rank; return how many increased the rank.

        The basis and pivots are exactly those of :meth:`add` called row by row: every later row is
        kept reduced against each new basis row as it comes (one vectorised update per new pivot,
        none per dependent row), so each row meets the same basis it would have met alone. From
        FLINT_BATCH rows and FLINT_COLUMNS columns on, FLINT eliminates them (:meth:`_add_rref`): the same basis
        rows, the new ones in the order of their pivots.
        """
        p = self.p
        V = self.reduce_many(rows)
        if V.shape[0] >= FLINT_BATCH and self.ncols >= FLINT_COLUMNS:
            return self._add_rref(V[V.any(axis=1)])
        added, i = 0, 0
        while i < V.shape[0] and self.rank < self.ncols:
            nzr = np.flatnonzero(V[i:].any(axis=1))
            if nzr.size == 0:
                break
            i += int(nzr[0])
            v = V[i]
            j = int(np.flatnonzero(v)[0])
            v = self._push(v, j)
            added += 1
            i += 1
            rest = V[i:]
            col = rest[:, j].copy()
            rr = np.flatnonzero(col)
            if rr.size:
                rest[rr] = (rest[rr] - (col[rr, None] * v[None, :]) % p) % p
        return added

    def _add_rref(self, V: np.ndarray) -> int:
        """Add rows already reduced against the basis, all at once: FLINT's ``nmod_mat.rref`` of them, then the new
        pivot columns cleared in the old basis (one product). The basis ends as the same reduced row echelon
        form (it is unique) as row-by-row addition gives, its rows in another order."""
        import flint

        p, n = self.p, self.ncols
        m = V.shape[0]
        if m == 0:
            return 0
        E, rank = flint.nmod_mat(m, n, V.ravel().tolist(), p).rref()
        if rank == 0:
            return 0
        W = np.fromiter(map(int, E.entries()), dtype=np.int64, count=m * n).reshape(m, n)[:rank]
        piv = np.argmax(W != 0, axis=1)
        r = self.rank
        if r:
            B = self._B[:r]
            C = B[:, piv]
            if C.any():
                B[:] = (B - matmul_mod(C, W, p)) % p
        if r + rank > self._B.shape[0]:
            grown = np.zeros((min(n, max(2 * self._B.shape[0], r + rank)), n), dtype=np.int64)
            grown[:r] = self._B[:r]
            self._B = grown
        self._B[r:r + rank] = W
        self.pivots.extend(int(j) for j in piv)
        return rank

    def _push(self, v: np.ndarray, j: int) -> np.ndarray:
        """Append the reduced row `v` with pivot `j` (normalised to a leading 1); clear column j in the other rows."""
        p = self.p
        v = v * inv(int(v[j]), p) % p
        r = self.rank
        if r:  # keep the basis fully reduced: clear column j in the other rows
            B = self._B[:r]
            col = B[:, j].copy()
            rows = np.flatnonzero(col)
            if rows.size:
                B[rows] = (B[rows] - (col[rows, None] * v[None, :]) % p) % p
        if r == self._B.shape[0]:
            grown = np.zeros((min(self.ncols, 2 * r), self.ncols), dtype=np.int64)
            grown[:r] = self._B[:r]
            self._B = grown
        self._B[r] = v
        self.pivots.append(j)
        return v

    def widened(self, extra: int) -> RowEchelon:
        """A copy with `extra` zero columns appended (the basis stays fully reduced: no elimination)."""
        out = RowEchelon(self.ncols + extra, self.p)
        if self.rank:
            out._B = np.zeros((max(self.rank, min(out.ncols, 8)), out.ncols), dtype=np.int64)
            out._B[: self.rank, : self.ncols] = self.basis
            out.pivots = list(self.pivots)
        return out

    def kernel(self) -> np.ndarray:
        """A basis of the right kernel {z : row·z = 0 for every row}, one vector per free column."""
        p = self.p
        piv = set(self.pivots)
        free = [j for j in range(self.ncols) if j not in piv]
        out = np.zeros((len(free), self.ncols), dtype=np.int64)
        if not free:
            return out
        out[np.arange(len(free)), free] = 1
        if self.pivots:
            out[:, self.pivots] = (-self.basis[:, free].T) % p
        return out


# -- helpers of the identifiable-function search and the reparametrisation (exponents, GF(p) kernels, rational
#    reconstruction): algebra tools, no verdicts
def monomial_exponents(n: int, deg: int) -> list[tuple[int, ...]]:
    """Exponent tuples of all monomials in n variables of total degree ≤ `deg` (the constant first)."""
    out = []
    for d in range(deg + 1):
        for combo in itertools.combinations_with_replacement(range(n), d):
            e = [0] * n
            for i in combo:
                e[i] += 1
            out.append(tuple(e))
    return out


#: Largest numerator and denominator accepted for a coefficient recovered from GF(p): identifiable
#: combinations of published models have small coefficients; a large one means a vector that only
#: happens to fit the points drawn (it is dropped, and the completeness check tells if anything is missing).
COEFF_BOUND = 10**4


def ratrec(a: int, p: int, bound: int = COEFF_BOUND) -> tuple[int, int] | None:
    """Rational reconstruction: n/d = a mod p with |n|, d <= bound (< sqrt(p/2)), or None."""
    a %= p
    r0, r1, s0, s1 = p, a, 0, 1
    while r1 > bound:
        if r1 == 0:
            break
        q = r0 // r1
        r0, r1 = r1, r0 - q * r1
        s0, s1 = s1, s0 - q * s1
    if s1 == 0 or abs(s1) > bound:
        return None
    if s1 < 0:
        r1, s1 = -r1, -s1
    return r1, s1


def kernel_mod_p(rows: list[np.ndarray], ncols: int, p: int) -> np.ndarray:
    """A basis of the kernel over GF(p) of the matrix whose rows are `rows`, one vector per free column of the
    reduced row echelon form (1 there, 0 at the other free columns), as :meth:`RowEchelon.kernel` gives it.
    FLINT's ``nmod_mat.rref`` does the elimination (about ten times faster than :class:`RowEchelon` on the
    700-column systems of the reparametrisation)."""
    import flint

    A = np.asarray(rows, dtype=np.int64).reshape(-1, ncols) % p if len(rows) else np.zeros((0, ncols), np.int64)
    if A.shape[0] == 0:
        return np.eye(ncols, dtype=np.int64)
    R, rank = flint.nmod_mat(A.shape[0], ncols, A.ravel().tolist(), p).rref()
    B = np.fromiter(map(int, R.entries()), dtype=np.int64, count=A.shape[0] * ncols).reshape(A.shape[0], ncols)[:rank]
    pivots = [int(np.flatnonzero(row)[0]) for row in B]
    piv = set(pivots)
    free = [j for j in range(ncols) if j not in piv]
    out = np.zeros((len(free), ncols), dtype=np.int64)
    if free:
        out[np.arange(len(free)), free] = 1
        if pivots:
            out[:, pivots] = (-B[:, free].T) % p
    return out


def monomial_value(e: Sequence[int], vals: Sequence[int], p: int) -> int:
    """The monomial with exponents `e` at the point `vals`, mod p."""
    t = 1
    for v, k in zip(vals, e):
        if k:
            t = t * pow(v, k, p) % p
    return t


def monomial_values(E: np.ndarray, vals: Sequence[int], p: int) -> tuple[np.ndarray, np.ndarray]:
    """Values (k,) and gradients (k x n) mod p at `vals` of the monomials with exponent rows `E` (k x n)."""
    k, n = E.shape
    v = np.asarray([int(x) % p for x in vals], dtype=np.int64)
    top = int(E.max()) if E.size else 0
    table = np.ones((n, top + 1), dtype=np.int64)  # table[i, d] = v_i^d mod p
    for d in range(1, top + 1):
        table[:, d] = table[:, d - 1] * v % p
    cols = table[np.arange(n)[None, :], E]  # v_i^E[m, i]
    mv = np.ones(k, dtype=np.int64)
    for i in range(n):
        mv = mv * cols[:, i] % p
    mg = np.zeros((k, n), dtype=np.int64)
    for i in range(n):
        if v[i]:  # d/dv_i m = E_i m / v_i
            mg[:, i] = E[:, i] % p * mv % p * inv(int(v[i]), p) % p
        else:  # only the monomials with E_i = 1 survive: the product of the other factors
            g = (E[:, i] == 1).astype(np.int64)
            for i2 in range(n):
                if i2 != i:
                    g = g * cols[:, i2] % p
            mg[:, i] = g
    return mv, mg


# polynomials mod p: sparse [(coefficient, ((var, exp), ...)), ...] and dense {exponent tuple: coefficient}
def sparse_mod_p(P: Any, p: int) -> list[tuple[int, tuple[tuple[int, int], ...]]]:
    """A polynomial over QQ as [(coefficient mod p, ((var, exp), ...)), ...]."""
    out = []
    for mono, c in P.items():
        num, den = int(c.numerator), int(c.denominator)
        if den % p == 0:
            raise ZeroDivisionError("a coefficient's denominator is divisible by the prime")
        cc = num % p * inv(den, p) % p
        out.append((cc, tuple((i, e) for i, e in enumerate(mono) if e)))
    return out


def sparse_value(sp_poly: list, vals: Sequence[int], p: int) -> int:
    """The value mod p of a polynomial in the form of :func:`sparse_mod_p` at the point `vals`."""
    acc = 0
    for c, mono in sp_poly:
        t = c
        for i, e in mono:
            t = t * pow(vals[i], e, p) % p
        acc += t
    return acc % p


def sparse_gradient(sp_poly: list, vals: Sequence[int], p: int, cols: Mapping[int, int], ncols: int) -> np.ndarray:
    """Its gradient mod p at `vals` with respect to the variables in `cols` (variable -> column of `ncols`)."""
    g = np.zeros(ncols, dtype=np.int64)
    acc: dict[int, int] = {}
    for c, mono in sp_poly:
        pw = [pow(vals[i], e, p) for i, e in mono]
        for a, (i, e) in enumerate(mono):
            if i not in cols:
                continue
            t = c * e % p * pow(vals[i], e - 1, p) % p
            for b, v in enumerate(pw):
                if b != a:
                    t = t * v % p
            acc[i] = (acc.get(i, 0) + t) % p
    for i, v in acc.items():
        g[cols[i]] = v
    return g


def poly_mul(a: Poly, b: Poly, p: int) -> Poly:
    """The product mod p of two polynomials {exponent tuple: coefficient}."""
    out: Poly = {}
    for ma, ca in a.items():
        for mb, cb in b.items():
            m = tuple(x + y for x, y in zip(ma, mb))
            out[m] = (out.get(m, 0) + ca * cb) % p
    return {k: c for k, c in out.items() if c}


def poly_value(P: Poly, vec: Sequence[int], p: int) -> int:
    """The value mod p of a polynomial {exponent tuple: coefficient} at the point `vec`."""
    acc = 0
    for m, c in P.items():
        t = c
        for v, e in zip(vec, m):
            if e:
                t = t * pow(v, e, p) % p
        acc += t
    return acc % p


def var_power(names: Sequence[str], v: str, k: int) -> Poly:
    """The monomial v**k in the variables `names`."""
    m = [0] * len(names)
    m[names.index(v)] = k
    return {tuple(m): 1}


def minimal_polynomial(nfs: Sequence[Poly], p: int) -> list[int] | None:
    """The first linear relation sum c_k NF(v^k) = 0 (k = 0..), as coefficients c_0..c_d, or None."""
    monos: dict[tuple[int, ...], int] = {}
    for g in nfs:
        for m in g:
            monos.setdefault(m, len(monos))
    width = len(monos) + len(nfs)
    ech = RowEchelon(width, p)
    for k, g in enumerate(nfs):
        row = np.zeros(width, dtype=np.int64)
        for m, c in g.items():
            row[monos[m]] = c % p
        row[len(monos) + k] = 1
        red = ech.reduce(row)
        if not np.any(red[: len(monos)]):
            return [int(c) for c in red[len(monos): len(monos) + k + 1]]
        ech.add(row)
    return None


def distinct_roots(coeffs: Sequence[int], p: int) -> int:
    """How many distinct roots c_0 + c_1 T + ... has over the algebraic closure of GF(p)."""
    T = sp.Symbol("T")
    P = sp.Poly([c % p for c in reversed(coeffs)], T, modulus=p)
    return int(P.degree() - P.gcd(P.diff(T)).degree())
