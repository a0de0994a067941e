"""Moving-horizon estimation: Besançon (2010)'s corrected trajectory-based observer as a compiled NLP (``_mhe``).

The kind is registered by ``nlobs.design`` importing this module in the order of ``nlobs kinds``.
"""
