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
