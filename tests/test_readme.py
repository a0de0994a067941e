"""The README's Python blocks run as written, in order, in an empty folder; its papers come from the one table; its
speed table dates each figure and points into the docs; no user-facing page names an issue."""

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
    assert len(blocks) >= 3, "the README lost its worked example"
    # one script, one block after another, as a reader pastes them into one session; no display
    script = "import matplotlib\nmatplotlib.use('Agg')\n" + "\n".join(
        f"print('--- block {i}', flush=True)\n{b}" for i, b in enumerate(blocks))
    (tmp_path / "readme.py").write_text(script, encoding="utf-8")
    out = subprocess.run([sys.executable, "-W", "error::DeprecationWarning:nlobs", "readme.py"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, f"a README block failed:\n{out.stdout[-3000:]}\n{out.stderr[-3000:]}"
    assert {"pendulum.png", "data.csv"} <= {p.name for p in tmp_path.iterdir()}   # bands.png: the simulation guide
    assert "Ljung-Box" in out.stdout  # the estimate on the recording (no true state) prints its innovations table


def test_the_readme_needs_nothing_the_demo_does_not_install():
    # the README sends a newcomer from `./dev.sh demo` to its example, in that environment (`source .venv/bin/activate`);
    # the test above runs in the test environment, which has more: every package the blocks use must be one the demo's
    # install brings (pyproject's dependencies and the extras of dev.sh's demo spec)
    import tomllib

    root = README.parent
    spec = re.search(r"need=demo; spec='([^']*)'", (root / "dev.sh").read_text(encoding="utf-8")).group(1)
    project = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    extras = re.findall(r"\w+", spec.partition("[")[2])
    deps = project["dependencies"] + [d for e in extras for d in project["optional-dependencies"][e]]
    installed = {re.match(r"[A-Za-z0-9_.-]+", d).group(0).lower() for d in deps} | {"nlobs"}
    code = "\n".join(python_blocks(README.read_text(encoding="utf-8")))
    used = set(re.findall(r"^\s*(?:import|from) (\w+)", code, flags=re.M)) - set(sys.stdlib_module_names)
    used |= {"pandas"} if re.search(r"\.to_pandas\(|\bdf\b", code) else set()
    assert used <= installed, f"the README uses {sorted(used - installed)}, which `./dev.sh demo` ({spec}) does not install"


def test_readme_names_the_papers_by_the_table_and_points_to_nothing_outside_the_project():
    text = README.read_text(encoding="utf-8")
    for key in ("000", "001", "002", "003", "004"):
        assert full_citation(key) in text
    assert "shared/papers" not in text and not re.search(r"\d{3}_[0-9a-f]{16}\.txt", text)


def test_readme_says_how_to_reach_the_cli():
    text = README.read_text(encoding="utf-8")
    assert "./dev.sh nlobs" in text and "source .venv/bin/activate" in text and "./dev.sh docs" in text


def _glance_rows(text: str) -> list[list[str]]:
    section = text[text.index("## Speed and accuracy at a glance"):]
    section = section[:section.index("\n## ", 1)]
    rows = [r for r in section.splitlines() if r.startswith("| ") and not r.startswith("| what ")]
    return [[c.strip() for c in r.strip("|").split(" | ")] for r in rows]


def _rst_anchors(page: Path) -> set[str]:
    """The ids Sphinx and GitHub give the page's section titles (lower case, words joined by hyphens)."""
    lines = page.read_text(encoding="utf-8").splitlines()
    titles = [a for a, b in zip(lines, lines[1:]) if a.strip() and re.fullmatch(r"([=~^-])\1{3,}", b) and len(b) >= len(a)]
    return {re.sub(r"[^a-z0-9]+", "-", t.replace("`", "").lower()).strip("-") for t in titles}


def test_the_speed_table_dates_each_figure_and_links_to_the_page_with_the_full_tables():
    rows = _glance_rows(README.read_text(encoding="utf-8"))
    assert len(rows) >= 5, "the README's speed table lost its rows"
    for what, figure, measured, page in rows:
        assert re.search(r"\b20\d\d-\d\d-\d\d, `[0-9a-f]{7,40}` \(`[\w.]+`\)", measured), f"{what}: no date, commit, source"
        assert (README.parent / "benchmarks" / "results" / re.search(r"\(`([\w.]+)`\)", measured).group(1)).exists(), what
        link = re.fullmatch(r"\[[^\]]+\]\(([^)#]+)#([^)]+)\)", page)
        assert link, f"{what}: the page cell is not a link to a section"
        target = README.parent / link.group(1)
        assert target.exists() and link.group(2) in _rst_anchors(target), f"{what}: {page} leads nowhere"


def test_no_user_facing_page_names_an_issue():
    """Issue numbers are the project's bookkeeping: the README, the docs, the CLI's and report's text and the model files
    the docs send a user to do not show them, in words or in a file name (``cascaded_tanks_issue39.toml``)."""
    root = README.parent
    pages = [README, *(root / "docs").rglob("*.rst"), *(root / "src" / "nlobs" / "cli").rglob("*.py"),
             *(root / "src" / "nlobs" / "report").rglob("*.py"), *(root / "benchmarks" / "models").glob("*.toml"),
             *(root / "src" / "nlobs" / "models").glob("*.toml")]
    found = [f"{p.relative_to(root)}: {m.group(0)}" for p in pages
             for m in re.finditer(r"\bissues? #?\d+|\(issue \d+|\bthe issue's\b|issue_?\d+", p.read_text(encoding="utf-8"),
                                  flags=re.I)]
    found += [str(p.relative_to(root)) for p in pages if re.search(r"issue_?\d+", p.name, flags=re.I)]
    assert not found, found
