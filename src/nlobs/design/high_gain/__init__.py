"""High-gain observers for the triangular (observability) form: Gauthier-Hammouri-Kupka's observer of the state and
Khalil-Esfandiari's observer of the output derivatives (``_high_gain``). The LTV-based high-gain Kalman observer is a
Riccati observer, in ``nlobs.design.kalman``.

The kinds are registered by ``nlobs.design`` importing this module in the order of ``nlobs kinds``.
"""
