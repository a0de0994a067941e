"""Algebra: the exact and modular tools the analysis and the designs compute with; they return no verdicts.

- ``_modular``: arithmetic modulo a prime (row echelon, rational reconstruction, kernels, random primes) and
  polynomials mod p (values, gradients, products, minimal polynomials, distinct roots);
- ``_series``: truncated power series of the outputs (the generic-rank engine's Taylor jets, over floats or GF(p));
- ``_groebner``: Gröbner-basis engines (SymPy, msolve when installed) behind one interface;
- ``_identity``: exact identity and rank decisions (Schwartz-Zippel with exact rational arithmetic).
"""
