"""Banks' exponential observer, his conditions (matrix measure, dissipativity) checked over a region (``_banks``).

The kind is registered by ``nlobs.design`` importing this module in the order of ``nlobs kinds``.
"""
