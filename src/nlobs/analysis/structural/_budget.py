"""Two routes to one answer under a time budget: forked child processes, each with its own process group.

The input-output route can spend minutes inside one FLINT factorisation that Python cannot interrupt (MAPK with
five outputs: a 100,000-term resultant in 40 variables), where SIAN answers in a second; on other models (Pharm) it
needs a minute where SIAN does not finish at all. ``route="auto"`` therefore runs the route in a child and gives it
a budget. The route calls :func:`committed` once its hard part is done (the input-output equations are known): from
then on it runs to the end. If the budget runs out first, SIAN starts in a second child beside it and the first
usable answer wins; the other child is killed together with its Gröbner-engine subprocesses. An unusable answer
(a refusal) hands over to SIAN at once.

Where fork is not available (Windows, macOS), the caller is itself a daemonic worker, or JAX is loaded (its threads
make a fork unsafe), the routes run one after
the other in this process, without a limit.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..._process import die_with_parent, guard_group

__all__ = ["Outcome", "committed", "race"]

_CHANNEL: Any = None  # in a child of race(): the pipe to the parent


def committed() -> None:
    """Called by the first route once its hard part is done: the budget no longer applies to it (a no-op outside a
    child of :func:`race`)."""
    if _CHANNEL is not None:
        _CHANNEL.send(("committed", None))


@dataclass(frozen=True)
class Outcome:
    """What :func:`race` returns: the winner ("first" or "second"), its answer, and why the first did not win
    (its unusable answer, or a sentence when the budget ran out and the second answered first; None when it won)."""

    winner: str
    value: Any
    first_lost: Any = None


def _start(ctx: Any, fn: Callable[[], Any]) -> tuple[Any, Any]:
    recv, send = ctx.Pipe(duplex=False)
    parent = os.getpid()

    def child() -> None:
        global _CHANNEL
        os.setsid()  # its own group: killing it takes msolve along
        die_with_parent(parent)  # out of the caller's group: killed when the caller dies, msolve too (nlobs._process)
        guard_group(parent)
        _CHANNEL = send
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
    return proc, recv


def _stop(proc: Any) -> None:
    if proc.is_alive():
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    proc.join()


def _forking() -> bool:
    import multiprocessing as mp

    # a process that has imported JAX (engine="jax") runs its thread pool: a forked child could deadlock on a lock one
    # of those threads held, so the routes run one after another there
    return sys.platform.startswith("linux") and not mp.current_process().daemon and "jax" not in sys.modules


def race(first: Callable[[], Any], seconds: float, second: Callable[[], Any],
         usable: Callable[[Any], bool]) -> Outcome:
    """`first` under a budget of `seconds` (module docstring), `second` beside it once the budget is out or after an
    unusable answer of `first`. Exceptions of either propagate."""
    if not _forking():
        got = first()
        return Outcome("first", got) if usable(got) else Outcome("second", second(), got)
    import multiprocessing as mp
    from multiprocessing.connection import wait

    ctx = mp.get_context("fork")
    running: dict[Any, tuple[str, Any]] = {}
    proc, recv = _start(ctx, first)
    running[recv] = ("first", proc)
    deadline = time.monotonic() + seconds
    committed_, first_lost = False, None
    try:
        while running:
            racing = any(who == "second" for who, _ in running.values())
            timeout = None if committed_ or racing else max(0.0, deadline - time.monotonic())
            ready = wait(list(running), timeout)
            if not ready:  # the budget ran out: the second route starts beside the first
                proc2, recv2 = _start(ctx, second)
                running[recv2] = ("second", proc2)
                first_lost = f"it took more than {seconds:g} s"
                continue
            for conn in ready:
                who, p = running[conn]
                try:
                    kind, value = conn.recv()
                except EOFError:
                    p.join()
                    kind, value = "error", RuntimeError(f"the {who} route ended without an answer "
                                                        f"(exit code {p.exitcode})")
                if kind == "committed":
                    committed_ = True
                    for c, (w, q) in list(running.items()):
                        if w == "second":  # the first route is past its hard part: it finishes alone
                            _stop(q)
                            c.close()
                            del running[c]
                    first_lost = None
                    continue
                del running[conn]
                p.join()
                conn.close()
                if kind == "error":
                    raise value
                if who == "second":
                    return Outcome("second", value, first_lost)
                if usable(value):
                    return Outcome("first", value)
                first_lost = value
                if not any(w == "second" for w, _ in running.values()):
                    proc2, recv2 = _start(ctx, second)
                    running[recv2] = ("second", proc2)
        raise RuntimeError("no route answered")  # not reached: the loop returns or raises
    finally:
        for conn, (_, p) in running.items():
            _stop(p)
            conn.close()

