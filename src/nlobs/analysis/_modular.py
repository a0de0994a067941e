"""Arithmetic in the prime field GF(p) on NumPy int64 arrays: primes, inverses, roots, row reduction.

The generic-rank test (``_lie.py``) evaluates truncated power series at a random point of
GF(p)^M. Every value is kept in ``[0, p)``; a product of two values is below p² < 2⁵⁴ and a dot
product of at most :data:`MAX_TERMS` such products stays below 2⁶³, so int64 never overflows.
"""

from __future__ import annotations

import numpy as np

__all__ = ["PRIME_BITS", "MAX_TERMS", "random_prime", "inv", "modsqrt", "root", "RowEchelon"]

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


def random_prime(rng: np.random.Generator, odd_roots: frozenset[int] = frozenset()) -> int:
    """A random prime p ≡ 3 (mod 4) in [2^26, 2^27) with gcd(r, p - 1) = 1 for every r in `odd_roots`.

    p ≡ 3 (mod 4) makes square roots a single power, and gcd(r, p - 1) = 1 makes every element an
    r-th power with the unique root ``a ** (r⁻¹ mod p-1)``.
    """
    lo = 1 << (PRIME_BITS - 1)
    while True:
        c = int(rng.integers(lo, 2 * lo)) | 3
        if c < 2 * lo and _is_prime(c) and all(np.gcd(r, c - 1) == 1 for r in odd_roots):
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


class RowEchelon:
    """Incremental row reduction over GF(p): add rows one at a time, keep a reduced basis.

    Attributes
    ----------
    basis : list of numpy.ndarray
        Reduced rows, each with a leading 1 at its pivot column, zero in every other pivot column.
    pivots : list of int
        Pivot column of each basis row.
    """

    def __init__(self, ncols: int, p: int):
        self.ncols = ncols
        self.p = p
        self.basis: list[np.ndarray] = []
        self.pivots: list[int] = []

    @property
    def rank(self) -> int:
        return len(self.pivots)

    def reduce(self, row: np.ndarray) -> np.ndarray:
        """`row` minus its projection on the basis (zero iff `row` is in the row space)."""
        p = self.p
        v = np.asarray(row, dtype=np.int64) % p
        for b, j in zip(self.basis, self.pivots):
            c = int(v[j])
            if c:
                v = (v - c * b) % p
        return v

    def contains(self, row: np.ndarray) -> bool:
        return not np.any(self.reduce(row))

    def add(self, row: np.ndarray) -> bool:
        """Add `row`; return True if it increased the rank."""
        p = self.p
        v = self.reduce(row)
        nz = np.flatnonzero(v)
        if nz.size == 0:
            return False
        j = int(nz[0])
        v = v * inv(int(v[j]), p) % p
        for k, b in enumerate(self.basis):  # keep the basis fully reduced
            c = int(b[j])
            if c:
                self.basis[k] = (b - c * v) % p
        self.basis.append(v)
        self.pivots.append(j)
        return True

    def kernel(self) -> np.ndarray:
        """A basis of the right kernel {z : row·z = 0 for every row}, one vector per free column."""
        p = self.p
        free = [j for j in range(self.ncols) if j not in self.pivots]
        out = np.zeros((len(free), self.ncols), dtype=np.int64)
        for i, j in enumerate(free):
            out[i, j] = 1
            for b, piv in zip(self.basis, self.pivots):
                out[i, piv] = (-int(b[j])) % p
        return out
