"""Print the speed table of docs/benchmarks.rst from the benchmark results (benchmarks/results/*.json).

``--rst`` prints it as the docs page holds it (a list-table); without it, as Markdown.

Each row: what was run, nlobs' time (min / median) with its error against the reference, the peer
and its time and error, the ratio (min / median) and the target with whether the min met it.
Rows come from every results file written in the format of ``_common.py``.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _common import RESULTS, fmt_time  # noqa: E402

ORDER = ["P1", "P2", "P3", "P3b", "P4", "P5", "P6", "P7", "P8"]


def _public(text: str) -> str:
    """A result's wording for the docs: a budget is the target's, not an issue's (no issue numbers on user pages)."""
    return re.sub(r"\bissue \d+ ", "", text)


def main(argv: list[str] | None = None) -> int:
    rst = "--rst" in (sys.argv[1:] if argv is None else argv)
    rows, machines = [], []
    for path in sorted(RESULTS.glob("*.json")):
        try:
            data = json.loads(path.read_text())
        except ValueError:
            continue
        if not isinstance(data, dict) or not isinstance(data.get("rows"), list):
            continue
        rows += [r for r in data["rows"] if isinstance(r, dict) and "id" in r]
        if "machine" in data:
            machines.append(f"{path.stem}: {data['machine'].get('date', '?')}, load {data['machine'].get('load_1min_at_start', float('nan')):.1f}")
    rows.sort(key=lambda r: (ORDER.index(r["id"]) if r["id"] in ORDER else len(ORDER), r["id"]))
    header = ["row", "nlobs (min / median)", "peer (min / median)", "ratio (min / median)", "target"]
    if rst:
        print(".. list-table::\n   :header-rows: 1\n")
        print("\n".join(("   * - " if k == 0 else "     - ") + c for k, c in enumerate(header)))
    else:
        print("| " + " | ".join(header) + " |")
        print("|---|---|---|---|---|")
    for r in rows:
        ratio = "—" if r["ratio_min"] is None else (  # a peer that failed has no time to compare
            f"{r['ratio_min']:.3g}× / {r['ratio_median']:.3g}×" + (" (peer/nlobs)" if r["ratio_kind"] == "peer/nlobs" else " (nlobs/peer)"))
        peer_t = "" if r["peer_min"] is None else f": {fmt_time(r['peer_min'])} / {fmt_time(r['peer_median'])}"
        mark = {True: " ✔", False: " ✘", None: ""}[r.get("met")]
        cells = [f"{r['id']} {r['what']}", f"{r['nlobs']}: {fmt_time(r['nlobs_min'])} / {fmt_time(r['nlobs_median'])}; {r['nlobs_error']}",
                 f"{_public(r['peer'])}{peer_t}; {r['peer_error']}", ratio, f"{r['target']}{mark}"]
        cells = [c.replace("|", "\\|") for c in cells]  # a | would split a Markdown cell, or start an RST substitution
        if rst:
            print("\n".join(("   * - " if k == 0 else "     - ") + c for k, c in enumerate(cells)))
        else:
            print("| " + " | ".join(cells) + " |")
    if machines:
        print("\nMeasured: " + "; ".join(machines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
