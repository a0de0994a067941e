"""Child processes that do not outlive their parent (Linux; elsewhere a no-op).

``route="auto"`` runs the global check in forked children with their own process groups (so that a child and its
msolve can be killed together), and the Gröbner engines run as subprocesses. A caller that kills the parent (a time
limit of its own, Ctrl-C) must not leave them running for minutes with gigabytes: such a child asks the kernel to
send it SIGKILL when its parent dies (``prctl(PR_SET_PDEATHSIG)``), and a watcher process kills its whole group
(the engine runs included) then.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from typing import Any

__all__ = ["die_with_parent", "guard_group"]

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


def _gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    try:  # killed but not yet reaped by its own parent
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


def guard_group(caller: int) -> None:
    """In a process that leads its own process group (after ``os.setsid``): fork a small watcher that kills the whole
    group, this process and its engine subprocesses, when `caller` dies; it leaves quietly when this process ends
    while `caller` lives. (The engines are spawned without a ``preexec_fn``: that would make every spawn a full fork
    of a large process.)"""
    if _prctl() is None:
        return
    me = os.getpid()
    if os.fork() != 0:
        return
    try:  # the watcher: holds no inherited descriptor (a pipe's reader would otherwise wait for it to end)
        for fd in os.listdir("/proc/self/fd"):
            try:
                os.close(int(fd))
            except OSError:
                pass
        while os.getppid() == me and not _gone(caller):
            time.sleep(0.2)
        # this process ended: normally, or killed because the caller is dying (the kernel signals it before the
        # caller is a zombie), so give the caller a moment to be seen gone
        for _ in range(20):
            if _gone(caller):
                os.killpg(os.getpgrp(), signal.SIGKILL)
            time.sleep(0.05)
    finally:
        os._exit(0)


def die_with_parent(parent: int | None = None) -> None:
    """Have this process killed when its parent dies; `parent` is the pid expected as the parent (if it already
    died, exit now). Usable as ``preexec_fn`` of :func:`subprocess.run`."""
    libc = _prctl()
    if libc is None:
        return
    libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if parent is not None and os.getppid() != parent:
        os._exit(1)
