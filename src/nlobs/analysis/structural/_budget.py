"""A computation under a time limit: in a forked child process with its own process group.

The input-output route can spend minutes inside one FLINT factorisation that Python cannot interrupt (MAPK with
five outputs: a 100,000-term resultant in 40 variables), where SIAN answers in a second. ``route="auto"`` therefore
gives it a budget: the child is killed with its Gröbner-engine subprocesses when the budget runs out, and SIAN
decides. Where fork is not available (Windows, macOS), or the caller is itself a daemonic worker, the function runs
in this process without a limit.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable
from typing import Any

__all__ = ["run_with_budget"]


def run_with_budget(fn: Callable[[], Any], seconds: float) -> tuple[bool, Any]:
    """``(True, fn())``, or ``(False, reason)`` when it took longer than `seconds`; exceptions of fn propagate."""
    import multiprocessing as mp

    if not sys.platform.startswith("linux") or mp.current_process().daemon:
        return True, fn()
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)

    def child() -> None:
        os.setsid()  # its own group: killing it takes msolve along
        try:
            send.send(("ok", fn()))
        except BaseException as e:  # noqa: BLE001 - handed to the parent, which re-raises it
            try:
                send.send(("error", e))
            except Exception:  # an exception that cannot be pickled
                send.send(("error", RuntimeError(f"{type(e).__name__}: {e}")))
        finally:
            send.close()

    proc = ctx.Process(target=child)
    proc.start()
    send.close()
    try:
        if recv.poll(seconds):
            try:
                kind, value = recv.recv()
            except EOFError:
                kind, value = "error", RuntimeError("the time-limited computation ended without an answer "
                                                    f"(exit code {proc.exitcode})")
            proc.join()
            if kind == "error":
                raise value
            return True, value
        return False, f"it took more than {seconds:g} s"
    finally:
        if proc.is_alive():
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.join()
        recv.close()
