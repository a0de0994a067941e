"""The README's Python blocks run as written, in order, in an empty folder; its papers come from the one table."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from nlobs.references import full_citation

README = Path(__file__).resolve().parents[1] / "README.md"


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_every_python_block_runs_in_order_in_an_empty_folder(tmp_path):
    blocks = python_blocks(README.read_text(encoding="utf-8"))
    assert len(blocks) >= 5, "the README lost its Python examples"
    # one script, one block after another, as a reader pastes them into one session; no display
    script = "import matplotlib\nmatplotlib.use('Agg')\n" + "\n".join(
        f"print('--- block {i}', flush=True)\n{b}" for i, b in enumerate(blocks))
    (tmp_path / "readme.py").write_text(script, encoding="utf-8")
    out = subprocess.run([sys.executable, "-W", "error::DeprecationWarning:nlobs", "readme.py"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, f"a README block failed:\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}"
    assert {"pendulum.png", "bands.png", "data.csv"} <= {p.name for p in tmp_path.iterdir()}
    assert "Ljung-Box" in out.stdout  # the estimate on the recording (no true state) prints its innovations table


def test_readme_names_the_papers_by_the_table_and_points_to_nothing_outside_the_project():
    text = README.read_text(encoding="utf-8")
    for key in ("000", "001", "002", "003", "004"):
        assert full_citation(key) in text
    assert "shared/papers" not in text and not re.search(r"\d{3}_[0-9a-f]{16}\.txt", text)


def test_readme_says_how_to_reach_the_cli():
    text = README.read_text(encoding="utf-8")
    assert "./dev.sh nlobs" in text and "source .venv/bin/activate" in text and "./dev.sh docs" in text
