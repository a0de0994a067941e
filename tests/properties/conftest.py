"""Print the hostile suite's counts (total / correct result / clean error / pending) after the run."""

from __future__ import annotations


def pytest_terminal_summary(terminalreporter, exitstatus, config):  # noqa: ARG001 - pytest's hook signature
    mod = __import__("sys").modules.get("test_hostile") or __import__("sys").modules.get("tests.properties.test_hostile")
    if mod is None or not mod.RESULTS:
        return
    H = mod.H
    cases = [c for c in H.CASES if c.id in mod.RESULTS]
    s = H.summary([mod.RESULTS[c.id] for c in cases])
    tr = terminalreporter
    tr.section("hostile inputs")
    tr.write_line(f"{s['total']} cases: {s['correct result']} correct results, {s['clean error']} clean errors, "
                  f"{len(s['pending'])} pending (another branch's fix), {len(s['failing'])} failing")
    for line in s["pending"]:
        tr.write_line(f"  pending: {line}")
    for line in s["pending fixed"]:
        tr.write_line(f"  pending case now passes (trim the pending mark): {line}")
