"""Test configuration: a private cache for compiled models, and a headless matplotlib."""

from __future__ import annotations

import os
import tempfile

import matplotlib

matplotlib.use("Agg")

# compiled models go to a throw-away cache so a test run never depends on a previous one
os.environ.setdefault("NLOBS_CACHE_DIR", tempfile.mkdtemp(prefix="nlobs-test-cache-"))
