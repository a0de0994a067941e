"""The documentation site builds with warnings as errors (what `./dev.sh docs` runs), its links and their
anchors resolve, it covers every public function and every paper example, cites no internal file, and its
guides' code runs."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FILE_NAME = re.compile(r"\d{3}_[0-9a-f]{16}\.txt")


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    # built once per test run: the workers of pytest-xdist (dev.sh runs the suite on several) share the run's temporary
    # folder, and the first to take the lock builds there (the build also writes the gallery's sources into docs/, so
    # two at a time would race); the others read its site, or its failure
    import fcntl

    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent
    out, failed = root / "docs-site", root / "docs-site.failed"
    with open(root / "docs-site.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not out.exists() and not failed.exists():
            partial = root / "docs-site.partial"  # renamed once complete: a crashed build leaves no half site behind
            try:
                proc = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-E", "-q", "-b", "html",
                                       "-d", str(root / "docs-doctrees"), str(DOCS), str(partial)],
                                      capture_output=True, text=True, timeout=900, check=False)
                error = proc.stderr[-5000:] if proc.returncode else ""
            except subprocess.TimeoutExpired:
                error = "sphinx did not finish in 900 s"
            if error:
                failed.write_text(error, encoding="utf-8")
            else:
                os.replace(partial, out)
    assert not failed.exists(), f"the documentation does not build cleanly:\n{failed.read_text(encoding='utf-8')}"
    return out


class _Links(HTMLParser):
    """The ids a page defines (``id=``, and ``name=`` of ``<a>``) and the links it holds (``href``, ``src``)."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.ids: set[str] = set()
        self.links: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if a.get("id"):
            self.ids.add(a["id"])
        if tag == "a" and a.get("name"):
            self.ids.add(a["name"])
        for key in ("href", "src"):
            if a.get(key) is not None and tag in ("a", "link", "img", "script", "source", "area"):
                self.links.append(a[key])


class _Text(HTMLParser):
    """The text a reader sees (MathML's tokens included), without code, scripts and styles."""

    SKIP = {"script", "style", "pre", "code", "textarea"}

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.parts: list[str] = []
        self.depth = 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.depth += tag in self.SKIP

    def handle_endtag(self, tag: str) -> None:
        self.depth -= tag in self.SKIP and self.depth > 0

    def handle_data(self, data: str) -> None:
        if not self.depth:
            self.parts.append(data)


def _visible_text(page: str) -> str:
    parser = _Text()
    parser.feed(page)
    return "".join(parser.parts)


def dead_links(site: Path) -> list[str]:
    """Every relative link of the built site whose file does not exist, or whose ``#anchor`` is no id of its page."""
    pages: dict[Path, _Links] = {}

    def parsed(page: Path) -> _Links:
        if page not in pages:
            parser = _Links()
            parser.feed(page.read_text(encoding="utf-8"))
            pages[page] = parser
        return pages[page]

    dead = []
    for page in sorted(site.rglob("*.html")):
        if page.relative_to(site).parts[0] == "_static":
            continue   # the theme's assets (a Jinja macro file among them), not pages
        for link in parsed(page).links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc or link.startswith("//"):
                continue   # another site (the tests check no page loads anything from one)
            target = (page.parent / unquote(parts.path)).resolve() if parts.path else page
            if not target.exists():
                dead.append(f"{page.relative_to(site)}: {link} (no such file)")
            elif parts.fragment and target.suffix == ".html" and unquote(parts.fragment) not in parsed(target).ids:
                dead.append(f"{page.relative_to(site)}: {link} (no anchor #{parts.fragment} in {target.name})")
    return dead


def test_every_link_of_the_site_reaches_its_page_and_anchor(site):
    dead = dead_links(site)
    assert not dead, f"{len(dead)} dead link(s):\n" + "\n".join(dead[:40])


def test_the_link_check_finds_a_missing_anchor_and_a_missing_file(tmp_path):
    (tmp_path / "a.html").write_text("<p id='here'><a href='#here'>ok</a> <a href='b.html#there'>ok</a>"
                                     "<a href='b.html#ref-x'>gone</a> <a href='c.html'>gone</a>"
                                     "<a href='https://example.org/#nowhere'>elsewhere</a></p>", encoding="utf-8")
    (tmp_path / "b.html").write_text("<span id='there'></span>", encoding="utf-8")
    assert dead_links(tmp_path) == ["a.html: b.html#ref-x (no anchor #ref-x in b.html)", "a.html: c.html (no such file)"]


def test_aligned_equations_render_as_aligned_rows(site):
    sys.path.insert(0, str(DOCS / "_ext"))
    import nlobs_docs

    # the same renderer the site uses: `&=` rows become a MathML table, one row per line, no literal "&"
    html = nlobs_docs._mathml("a &= b + c \\\\\n d &= e", True)
    assert html.count("<mtr>") == 2 and html.count("<mtd") == 4 and ">&<" not in html and "&amp;" not in html
    assert nlobs_docs._mathml(r"\begin{aligned} a &= b \\ d &= e \end{aligned}", True).count("<mtr>") == 2
    assert nlobs_docs.aligned(r"A = \begin{bmatrix} 1 & 2 \\ 3 & 4 \end{bmatrix}").startswith("A = ")  # a matrix only
    # Chromium renders MathML Core, which ignores `columnalign` and `columnspacing`: each cell carries its alignment as
    # a style (else every cell is centred and the `=` of the rows do not line up), and split's cells no padding
    cells = re.findall(r"<mtd[^>]*>", html)
    assert cells == ['<mtd columnalign="right" style="text-align: right; padding-inline: 0">',
                     '<mtd columnalign="left" style="text-align: left; padding-inline: 0">'] * 2, cells
    cases = nlobs_docs._mathml(r"|x| = \begin{cases} x & x > 0 \\ -x & x \le 0 \end{cases}", True)
    assert re.findall(r"<mtd[^>]*>", cases) == ['<mtd columnalign="left" style="text-align: left">'] * 4
    # on the built pages: the grey-box model of the learning guide, the design_gpebo equations of the API
    for page, rows in (("guide/learning.html", 3), ("api/generated/nlobs.design.design_gpebo.html", 2)):
        text = (site / page).read_text(encoding="utf-8")
        tables = re.findall(r"<div class='math-block'>(.*?)</div>", text, flags=re.S)
        aligned = [t for t in tables if 'columnalign="right" style="text-align: right' in t and t.count("<mtr>") == rows]
        assert aligned, f"{page}: no displayed equation with {rows} aligned rows"
        assert not any(">&<" in t for t in tables), f"{page}: a literal & in displayed maths"


def test_guides_write_their_maths_as_maths(site):
    for page in ("guide/recorded.html", "guide/learning.html"):
        text = _visible_text((site / page).read_text(encoding="utf-8"))
        for plain in ("ν_k", "ŷ_k⁻", "e^ρ", "Σ_k −½"):
            assert plain not in text, f"{page}: {plain!r} as plain text"


def test_the_sensors_guide_names_public_functions_only_and_draws_its_figure_at_build_time(site):
    sensors = (site / "guide" / "sensors.html").read_text(encoding="utf-8")
    assert "_sensors" not in _visible_text(sensors) and "nlobs.report._" not in sensors
    assert re.search(r'<img[^>]+src="\.\./_images/sensors-enzyme-0\.png"', sensors)
    assert (site / "_images" / "sensors-enzyme-0.png").stat().st_size > 10_000
    assert not (DOCS / "_static" / "sensors_enzyme.png").exists()     # drawn by the build, not a committed picture


def test_no_page_has_an_empty_sidebar(site):
    empty = [str(p.relative_to(site)) for p in site.rglob("*.html") if p.relative_to(site).parts[0] != "_static"
             and re.search(r'<div class="bd-toc-item navbar-nav">\s*</div>', p.read_text(encoding="utf-8"))]
    assert not empty, f"empty 'Section Navigation' on {empty[:10]}"


def test_long_code_lines_wrap_instead_of_scrolling_sideways(site):
    # a guide's code is about 105 characters wide at most, the column beside both sidebars of a 1400 px window; in a
    # narrower window, and for a program's output or a generated file, lines wrap: none hides its end off the column
    css = (site / "_static" / "nlobs.css").read_text(encoding="utf-8")
    rules = dict(re.findall(r"([^{}]+)\{([^{}]*)\}", re.sub(r"/\*.*?\*/", "", css, flags=re.S)))
    wrapping = [sel for sel, body in rules.items() if "white-space: pre-wrap" in body]
    assert any('.bd-article div[class*="highlight-"] pre' in sel for sel in wrapping), wrapping
    assert 'href="../_static/nlobs.css' in (site / "guide" / "simulation.html").read_text(encoding="utf-8")


def test_api_reference_has_a_page_for_every_public_function_and_class(site):
    sys.path.insert(0, str(DOCS / "_ext"))
    import nlobs_docs

    missing = []
    for modname, _ in nlobs_docs.NAMESPACES:
        for name in nlobs_docs.public_names(modname):
            pages = list((site / "api" / "generated").glob(f"nlobs.*.{name}.html"))
            if not pages:
                missing.append(f"{modname}.{name}")
    assert not missing, missing
    index = (site / "api" / "index.html").read_text(encoding="utf-8")
    assert "design_ekf" in index and "simulate" in index


def test_gallery_has_a_page_per_example_with_its_plots_and_rendered_maths(site):
    from nlobs.examples import EXAMPLES

    for key in EXAMPLES:
        pages = list((site / "gallery").glob(f"plot_*_{key.replace('-', '_')}.html"))
        assert len(pages) == 1, key
        text = pages[0].read_text(encoding="utf-8")
        assert "<math" in text, f"{key}: no rendered maths"
        assert "Claims checked" in text and ("sphx-glr-single-img" in text or "sphx-glr-multi-img" in text), key
        assert "FAILS" not in text, f"{key}: a claim fails in the docs build"


def test_gallery_has_a_page_per_practitioners_model_with_its_file_and_plots(site):
    from nlobs.examples import PRACTICE

    assert {"battery", "building", "vehicle"} <= set(PRACTICE)
    for key in PRACTICE:
        pages = list((site / "gallery" / "practice").glob(f"plot_*_{key}.html"))
        assert len(pages) == 1, key
        text = pages[0].read_text(encoding="utf-8")
        assert "Claims checked" in text and "FAILS" not in text and "not checked" not in text, key
        assert "sphx-glr-single-img" in text or "sphx-glr-multi-img" in text, key
        assert "[simulation]" in text, f"{key}: the model file is not on its page"
        assert "`" not in _visible_text(text), f"{key}: Markdown backticks left in the text"
        assert "_table_" not in text, f"{key}: a lookup table shown by its internal name"
    building = _visible_text(next((site / "gallery" / "practice").glob("plot_*_building.html")).read_text(encoding="utf-8"))
    assert "[k+1]" in building.replace("\n", "") and "cop(" in building.replace("\n", "")   # a map, and its table by name
    index = (site / "gallery" / "index.html").read_text(encoding="utf-8")
    assert "Practitioners" in index


def test_no_page_names_an_internal_file_or_loads_anything_from_elsewhere(site):
    for page in site.rglob("*.html"):
        text = page.read_text(encoding="utf-8")
        if "_modules" not in page.parts:  # highlighted source code, whose comments cite papers by file (house rule)
            assert not FILE_NAME.search(text), page
        assert "shared/papers" not in text and "papers README" not in text, page
        assert not re.search(r"<script[^>]+src=['\"]https?://", text), f"{page} loads a script from the network"


def test_no_page_speaks_of_the_projects_issues(site):
    # the API pages come from the docstrings, which the README test does not read: no "issue 39", no "the core
    # issue" (another project's issue, e.g. "SI.jl issue #144", names whose it is)
    said = []
    for page in site.rglob("*.html"):
        if page.relative_to(site).parts[0] in ("_modules", "_static", "_sources"):
            continue
        text = " ".join(_visible_text(page.read_text(encoding="utf-8")).split())
        said += [f"{page.relative_to(site)}: {m.group(0)}" for m in
                 re.finditer(r"(?<!\.jl )\bissues? #?\d+|issue_?\d+|\bthe (?:core |same )?issue(?:'s)?\b", text, flags=re.I)]
    assert not said, said


def test_references_page_lists_the_table(site):
    from nlobs.references import REFERENCES

    text = (site / "references.html").read_text(encoding="utf-8")
    for r in REFERENCES.values():
        assert r.title.split(":")[0][:40].replace("&", "&amp;") in text, r.key


#: files a guide's code must leave behind (the Monte Carlo bands were the README's check before they moved here)
GUIDE_WRITES = {"simulation.rst": {"pendulum.png", "bands.png"}}


@pytest.mark.parametrize("guide", sorted(p.name for p in (DOCS / "guide").glob("*.rst") if p.name != "index.rst"))
def test_guide_code_runs_as_written(guide, tmp_path):
    text = (DOCS / "guide" / guide).read_text(encoding="utf-8")
    blocks = re.findall(r"^\.\. code-block:: python\n\n((?:(?:   .*)?\n)+)", text, flags=re.M)
    assert blocks, f"{guide} has no Python example"
    code = "\n".join("\n".join(line[3:] for line in b.splitlines()) for b in blocks)
    (tmp_path / "guide.py").write_text("import matplotlib\nmatplotlib.use('Agg')\n" + code, encoding="utf-8")
    proc = subprocess.run([sys.executable, "guide.py"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"{guide}:\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    assert GUIDE_WRITES.get(guide, set()) <= {p.name for p in tmp_path.iterdir()}, f"{guide}: a figure was not written"
