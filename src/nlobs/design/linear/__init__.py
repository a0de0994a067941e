"""Linear observers: Luenberger's observer for LTI models and the output-injection (error-linearisation) observer
(``_linear``), and the linear observer on a system that mimics the model through w = T(x) (``_augmented``).

The kinds are registered by ``nlobs.design`` importing these modules in the order of ``nlobs kinds``.
"""
