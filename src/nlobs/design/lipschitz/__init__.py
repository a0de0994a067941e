"""Thau's observer for a Lipschitz nonlinearity, its gain found by a Riccati-based search, and the region's Lipschitz
constant (``_lipschitz``).

The kind is registered by ``nlobs.design`` importing this module in the order of ``nlobs kinds``.
"""
