"""Child processes that do not outlive their parent (Linux; elsewhere a no-op).

``route="auto"`` runs the global check in forked children with their own process groups (so that a child and its
msolve can be killed together), and the Gröbner engines run as subprocesses. A caller that kills the parent (a time
limit of its own, Ctrl-C) must not leave them running for minutes with gigabytes: each asks the kernel to send it
SIGKILL when its parent dies (``prctl(PR_SET_PDEATHSIG)``).
"""

from __future__ import annotations

import os
import signal
import sys
from typing import Any

__all__ = ["die_with_parent"]

_PR_SET_PDEATHSIG = 1
_libc: Any = None


def _prctl() -> Any:
    global _libc
    if _libc is None and sys.platform.startswith("linux"):
        try:
            import ctypes

            _libc = ctypes.CDLL(None, use_errno=True)
        except OSError:
            _libc = False
    return _libc or None


_prctl()  # loaded here, not in a forked child


def die_with_parent(parent: int | None = None) -> None:
    """Have this process killed when its parent dies; `parent` is the pid expected as the parent (if it already
    died, exit now). Usable as ``preexec_fn`` of :func:`subprocess.run`."""
    libc = _prctl()
    if libc is None:
        return
    libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if parent is not None and os.getppid() != parent:
        os._exit(1)
