"""nlobs._memory and evaluate_many's chunks: freed memory given back, wide arguments copied in small chunks."""

from __future__ import annotations

import sys

import casadi as ca
import numpy as np
import pytest

from nlobs import _memory
from nlobs.engine import _batch


def _rss_mb() -> float:
    with open("/proc/self/status") as fh:
        return next(int(ln.split()[1]) for ln in fh if ln.startswith("VmRSS")) / 1024


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim (a no-op elsewhere)")
def test_memory_freed_in_a_thread_is_given_back():
    import threading

    def churn():   # many blocks below the mmap threshold, then all but a few freed: they stay in the arena
        blocks = [bytearray(64 * 1024) for _ in range(3000)]
        keep = blocks[::500]
        del blocks
        churn.keep = keep

    th = threading.Thread(target=churn)
    th.start()
    th.join()
    before = _rss_mb()
    assert _memory.release_free_memory()
    assert _rss_mb() < before - 50   # ~190 MB were freed in the thread's arena


def test_evaluate_many_copies_wide_arguments_in_small_chunks(monkeypatch):
    x = ca.SX.sym("x", 1000)
    fn = ca.Function("f", [x], [ca.sum1(x), ])
    seen = []
    real = _batch._mapped

    def mapped(f, K):
        seen.append(K)
        return real(f, K)

    monkeypatch.setattr(_batch, "_mapped", mapped)
    Z = np.random.default_rng(0).normal(size=(3000, 1000))
    out = _batch.evaluate_many(fn, Z)
    np.testing.assert_allclose(out[:, 0], Z.sum(axis=1), rtol=0, atol=1e-11)   # sums of 1000 terms of order 1
    assert max(seen) * 1000 * 8 <= _batch.CHUNK_BYTES and sum(seen) == 3000
