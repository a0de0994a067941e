"""Memory the process holds but no longer uses, given back to the system (glibc on Linux; elsewhere a no-op).

glibc keeps freed memory in its arenas, one per thread that allocated, and returns it to the system only from the top
of a heap. Several large observers run side by side on threads (``nlobs design --run`` on a 24-state model) each free
a hundred megabytes or more when they finish; :func:`release_free_memory` (``malloc_trim(0)``) gives the free pages of
every arena back, and runs after each observer of a multi-observer run finishes (:mod:`nlobs.simulate._isolate`).
"""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["release_free_memory"]

_libc: Any = None


def _glibc() -> Any:
    global _libc
    if _libc is None:
        _libc = False
        if sys.platform.startswith("linux"):
            try:
                import ctypes

                lib = ctypes.CDLL(None)
                if hasattr(lib, "malloc_trim"):
                    _libc = lib
            except OSError:
                pass
    return _libc or None


def release_free_memory() -> bool:
    """Give the free pages of the allocator's arenas back to the system; whether it could (glibc only)."""
    lib = _glibc()
    if lib is None:
        return False
    lib.malloc_trim(0)
    return True
