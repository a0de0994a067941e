"""Two threads that need the same compiled object build it once (engine._codegen._build): the advisor's early build
of a candidate and the comparison run that loads it."""

from __future__ import annotations

import threading
import time

import pytest

from nlobs.engine import _codegen, find_compiler

pytestmark = pytest.mark.skipif(find_compiler() is None, reason="needs a C compiler")


def test_a_second_thread_waits_for_the_first_build_of_the_same_object(monkeypatch, tmp_path):
    monkeypatch.setenv("NLOBS_CACHE_DIR", str(tmp_path))
    runs: list[str] = []
    orig = _codegen._run_compilers

    def slow(cc, commands, tag, left):   # a compile long enough for the other thread to arrive meanwhile
        runs.append(threading.current_thread().name)
        time.sleep(0.5)
        return orig(cc, commands, tag, left)

    monkeypatch.setattr(_codegen, "_run_compilers", slow)
    code = "double nlobs_twice(double x) { return 2 * x; }\n"
    paths: list[object] = []
    threads = [threading.Thread(target=lambda: paths.append(_codegen._build(code, "once")), name=f"t{i}")
               for i in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert len(runs) == 1, runs
    assert len(paths) == 2 and paths[0] == paths[1] and paths[0].exists()


def test_stopped_compilers_leave_no_open_pipe(monkeypatch):
    """A compiler run stopped because another failed (or the time ran out) is killed, reaped and its pipes closed: an
    open pipe was found later, at some other test's garbage collection, as an unraisable ResourceWarning."""
    import gc
    import sys
    import warnings

    from nlobs.errors import EngineError

    monkeypatch.setattr(_codegen, "UNIT_WORKERS", 2)
    cmds = [[sys.executable, "-c", "import sys; sys.exit(3)"], [sys.executable, "-c", "import time; time.sleep(30)"]]
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        with pytest.raises(EngineError, match="failed"):
            _codegen._run_compilers("cc", cmds, "test", None)
        gc.collect()
    assert not [w for w in seen if issubclass(w.category, ResourceWarning)], [str(w.message) for w in seen]
