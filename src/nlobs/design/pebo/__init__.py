"""The PEBO family: linear-regression estimators (gradient, least squares, DREM, G+D), the parameter-estimation-based
observer and its generalisation GPEBO (and 2G+D), KKL observers (from a PDE solution, learned, KKL+PEBO and the
cascade), and immersion and invariance.

- ``_regression``: the regression objects and the estimators of θ in Y = ψᵀθ + d (one kind each);
- ``_pebo``: PEBO, KKL and KKL+PEBO; ``_gpebo``: GPEBO and 2G+D for state-affine systems; ``_cascade``: KKL+PEBO for
  the cascade class; ``_kkl``: KKL with a learned left inverse; ``_iandi``: the I&I observer.

The kinds are registered by ``nlobs.design`` importing these modules in the order of ``nlobs kinds``.
"""
