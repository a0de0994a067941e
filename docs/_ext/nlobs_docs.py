"""Sphinx glue for the nlobs documentation (nothing here is copied from the library by hand):

- maths rendered as MathML at build time (latex2mathml, the report's renderer): no script,
  no font download, the site works offline;
- the examples gallery: one sphinx-gallery script per registered example of
  :mod:`nlobs.examples`, written at build time, plus a scraper for the library's matplotlib
  figures (they are not pyplot figures);
- the API reference pages: every public name of every nlobs namespace, listed at build time;
- the references page, from :data:`nlobs.references.REFERENCES`;
- the guides' figures (``.. nlobs-figure::``), drawn at build time from the code the page shows.
"""

from __future__ import annotations

import html
import inspect
import re
from pathlib import Path, PurePosixPath
from typing import Any

from docutils import nodes
from docutils.parsers.rst import directives
from latex2mathml.converter import convert
from sphinx.util.docutils import SphinxDirective

HERE = Path(__file__).resolve().parent.parent   # docs/

# -- maths ----------------------------------------------------------------------------------


# latex2mathml lays out `split` as a table of rows with its columns aligned (right, left), as LaTeX does; it
# reads `aligned` as plain maths (a literal "&", one long line) and numbers the rows of `align`. Sphinx's own
# renderers wrap every displayed equation in `split`; these pages do the same.
_ALIGNED_ENV = re.compile(r"\\(begin|end)\{(?:aligned|align\*?)\}")
_INNERMOST_ENV = re.compile(r"\\begin\{(\w+\*?)\}(?:(?!\\begin\{).)*?\\end\{\1\}", re.S)


def aligned(latex: str) -> str:
    """A displayed equation as latex2mathml lays it out in aligned rows: rows (``\\\\``) or alignment points
    (``&``) outside any environment wrapped in ``split``, ``aligned`` and ``align`` read as ``split``."""
    latex = _ALIGNED_ENV.sub(lambda m: rf"\{m.group(1)}{{split}}", latex.strip())
    top, n = latex, 1
    while n:   # what is outside every environment (the & and \\ of a matrix are its own)
        top, n = _INNERMOST_ENV.subn("", top)
    if "&" in top or "\\\\" in top:
        latex = r"\begin{split}" + latex.removesuffix("\\\\") + r"\end{split}"
    return latex


_TABLE_TAG = re.compile(r"<mtable\b[^>]*>|</mtable>|<mtd columnalign=\"(\w+)\">")


def _core_alignment(mathml: str) -> str:
    """latex2mathml's tables with their alignment as styles: browsers of MathML Core (Chromium) ignore ``columnalign``
    and ``columnspacing``, and would centre every cell. A cell keeps its column's side; the cells of a table
    with no space between its columns (``split``: a right-aligned side, then ``= ...`` left-aligned) lose the
    padding the browser gives cells."""
    tight: list[bool] = []   # the open tables, innermost last: spaced 0em?

    def style(m: re.Match[str]) -> str:
        tag = m.group(0)
        if tag.startswith("<mtable"):
            tight.append('columnspacing="0em"' in tag)
            return tag
        if tag == "</mtable>":
            tight.pop()
            return tag
        pad = "; padding-inline: 0" if tight and tight[-1] else ""
        return f'<mtd columnalign="{m.group(1)}" style="text-align: {m.group(1)}{pad}">'

    return _TABLE_TAG.sub(style, mathml)


def _mathml(latex: str, display: bool) -> str:
    try:
        return _core_alignment(convert(aligned(latex) if display else latex.strip(), display="block" if display else "inline"))
    except Exception:  # noqa: BLE001 - an expression latex2mathml does not know: show its source
        return f"<code class='latex'>{html.escape(latex)}</code>"


def _visit_math(self: Any, node: nodes.Element) -> None:
    self.body.append(_mathml(node.astext(), False))
    raise nodes.SkipNode


def _visit_displaymath(self: Any, node: nodes.Element) -> None:
    latex = node.astext()
    parts = [p for p in re.split(r"\n\s*\n", latex) if p.strip()] if not node.get("nowrap") else [latex]
    self.body.append("<div class='math-block'>" + "".join(_mathml(p, True) for p in parts) + "</div>")
    raise nodes.SkipNode


# -- the gallery ----------------------------------------------------------------------------

GALLERY_SRC = HERE / "_gallery_src"


def _script(ex: Any, practice: bool = False) -> str:
    from nlobs.report import plain

    title = plain(ex.title)
    if practice:
        intro = (f"The practitioner's model registered as ``{ex.key}`` in ``nlobs.examples.PRACTICE``, run while these pages\n"
                 "were built; its model file comes first: copy it to start your own.")
        load = (f'from nlobs.examples import PRACTICE\nfrom nlobs.report import HTML, example_section\n\nresult = PRACTICE["{ex.key}"].run()'
                "\n\n# %%\n# The model file.\nprint(result.model)")
    else:
        intro = (f"The example registered as ``{ex.key}`` in :mod:`nlobs.examples`, run while these pages were\n"
                 f"built. ``nlobs demo --only {ex.key}`` runs the same function; so do the acceptance tests.")
        load = f'from nlobs.examples import find_example\nfrom nlobs.report import HTML, example_section\n\nresult = find_example("{ex.key}").run()'
    up = "../../" if practice else "../"   # the page's way back to the site's root, where references.html is
    return f'''"""
{title}
{"=" * len(title)}

{intro}
"""

# %%
# Run the example: it builds the models, checks the claims with numbers and simulates the observers.
{load}

# %%
# What is shown, the claims checked, the observability verdicts, the numbers, the model, the
# evidence and the notes (the demo report's section, here without its plots, which follow).
HTML(example_section(result, plots=False, level=3, references="{up}references.html"))

# %%
# The simulations — true states (grey) against each observer's estimate, and the error norms —
# then the example's own figures, if it has any.
figures = [run.plot(width=5.1, title=label) for label, run in result.runs.items()]
figures += list(result.figures.values())
'''


def write_gallery_sources(app: Any = None) -> None:
    """One script per registered example (the examples' order), and the gallery's header; the practitioners' models
    (:data:`nlobs.examples.PRACTICE`) in a second section, ``practice/``."""
    from nlobs.examples import EXAMPLES, PRACTICE

    GALLERY_SRC.mkdir(exist_ok=True)
    for old in GALLERY_SRC.glob("*.py"):
        old.unlink()
    (GALLERY_SRC / "GALLERY_HEADER.rst").write_text(
        "The papers' examples\n====================\n\n"
        "Each page runs one example of :mod:`nlobs.examples` while the documentation is built, so the\n"
        "numbers, claims and plots here are those of the code you install. ``nlobs demo`` runs them all\n"
        "and writes the same content as one self-contained report.\n", encoding="utf-8")
    for i, ex in enumerate(sorted(EXAMPLES.values(), key=lambda e: e.order)):
        name = f"plot_{i:02d}_{ex.key.replace('-', '_')}.py"
        (GALLERY_SRC / name).write_text(_script(ex), encoding="utf-8")
    section = GALLERY_SRC / "practice"
    section.mkdir(exist_ok=True)
    for old in section.glob("*.py"):
        old.unlink()
    (section / "GALLERY_HEADER.rst").write_text(
        "Practitioners' models\n---------------------\n\n"
        "Models of the kind an engineer brings — a battery with its OCV table, a building logged every few minutes as a\n"
        "discrete-time model, a vehicle whose sensors run on clocks of their own, one of them late — each with its\n"
        "model file, the claims checked with numbers while these pages were built, and its plots.\n", encoding="utf-8")
    for i, ex in enumerate(sorted(PRACTICE.values(), key=lambda e: e.order)):
        (section / f"plot_{i:02d}_{ex.key}.py").write_text(_script(ex, practice=True), encoding="utf-8")


class FigureScraper:
    """Save every matplotlib Figure a gallery block created (the library draws on Figure objects,
    not through pyplot, so sphinx-gallery's own scraper does not see them)."""

    def __repr__(self) -> str:  # a stable repr keeps Sphinx's environment cache valid
        return "FigureScraper"

    def __call__(self, block: Any, block_vars: dict[str, Any], gallery_conf: dict[str, Any]) -> str:
        from matplotlib.figure import Figure
        from sphinx_gallery.scrapers import figure_rst

        seen = block_vars.setdefault("_nlobs_seen", set())
        figs = []
        for value in list(block_vars["example_globals"].values()):
            for item in value if isinstance(value, (list, tuple)) else [value]:
                if isinstance(item, Figure) and id(item) not in seen:
                    figs.append(item)
        narrow, wide = [], []
        for fig, path in zip(figs, block_vars["image_path_iterator"]):
            seen.add(id(fig))
            fig.savefig(path, dpi=110)
            (wide if fig.get_size_inches()[0] > 6 else narrow).append(PurePosixPath(path))
        # side-by-side figures two per row; a wide figure alone, at full width
        parts = [figure_rst(narrow, gallery_conf["src_dir"])] if narrow else []
        parts += [figure_rst([p], gallery_conf["src_dir"]) for p in wide]
        return "\n".join(parts)


# -- figures of the guides, drawn at build time ------------------------------------------------

GENERATED = HERE / "_generated"   # the figures drawn while the site is built (not in git)
_PYTHON_BLOCK = re.compile(r"^\.\. code-block:: python\n\n((?:(?:   .*)?\n)+)", re.M)


class FigureDirective(SphinxDirective):
    """``.. nlobs-figure:: NAME`` draws a guide's figure while the site is built, from the code the page shows: it
    runs the page's Python code blocks above it (in a scratch folder), then its own content (not shown, e.g. what a
    command-line option adds), and puts each matplotlib Figure the content leaves in its names on the page, as
    ``_generated/NAME-i.png``. Options: ``:alt:`` (the text of each image)."""

    has_content = True
    required_arguments = 1
    option_spec = {"alt": directives.unchanged}

    def run(self) -> list[nodes.Node]:
        import contextlib
        import io
        import tempfile

        from matplotlib.figure import Figure

        source = Path(self.env.doc2path(self.env.docname)).read_text(encoding="utf-8")
        above = "\n".join(source.splitlines()[: self.lineno - 1]) + "\n"
        shown = "\n".join("\n".join(line[3:] for line in b.splitlines()) for b in _PYTHON_BLOCK.findall(above))
        namespace: dict[str, Any] = {"__name__": "__nlobs_figure__"}
        with tempfile.TemporaryDirectory() as scratch, contextlib.chdir(scratch), \
                contextlib.redirect_stdout(io.StringIO()):   # what the page's code prints is on the page already
            exec(compile(shown, f"{self.env.docname} (its code blocks)", "exec"), namespace)   # noqa: S102 - our own pages
            before = {id(v) for v in namespace.values()}
            exec(compile("\n".join(self.content), f"{self.env.docname} (nlobs-figure)", "exec"), namespace)  # noqa: S102
        figures = [v for v in namespace.values() if isinstance(v, Figure) and id(v) not in before]
        if not figures:
            raise self.error(f"nlobs-figure {self.arguments[0]}: its code leaves no matplotlib Figure in its names")
        GENERATED.mkdir(exist_ok=True)
        out = []
        for i, fig in enumerate(figures):
            name = f"{self.arguments[0]}-{i}.png"
            fig.savefig(GENERATED / name, dpi=110)
            out.append(nodes.image(uri=f"/_generated/{name}", alt=self.options.get("alt", "")))
        return out


# -- the API reference -----------------------------------------------------------------------

NAMESPACES = [
    ("nlobs.model", "Models: System, structured forms, model files, input signals"),
    ("nlobs.analysis", "Observability analysis"),
    ("nlobs.design", "Observer designs and their certificates"),
    ("nlobs.observer", "Running observers: offline, online, C export"),
    ("nlobs.simulate", "Simulation, noise, Monte Carlo, results"),
    ("nlobs.estimation", "Estimation on recordings: filtering, smoothing, the sensor check"),
    ("nlobs.learning", "Learning from recordings: parameters and noise levels"),
    ("nlobs.advise", "Which observer fits a model: candidates, tuning and ranking"),
    ("nlobs.interop", "python-control"),
    ("nlobs.examples", "The papers' examples"),
    ("nlobs.report", "Report building blocks"),
    ("nlobs.references", "The works nlobs cites"),
    ("nlobs.errors", "Errors"),
]


def public_names(modname: str) -> list[str]:
    """Public classes and functions a namespace offers (its own or re-exported from nlobs)."""
    import importlib

    mod = importlib.import_module(modname)
    names = getattr(mod, "__all__", None) or [n for n in dir(mod) if not n.startswith("_")]
    out = []
    for n in names:
        obj = getattr(mod, n, None)
        if (inspect.isclass(obj) or inspect.isfunction(obj)) and getattr(obj, "__module__", "").startswith("nlobs"):
            out.append(n)
    return sorted(set(out), key=str.lower)


def write_api_pages(app: Any = None) -> None:
    """docs/api/index.rst: one autosummary table per namespace, each object documented once (where
    its stage defines it); then the names the top level ``nlobs`` re-exports, linked there."""
    import importlib

    lines = ["API reference", "=============", "",
             "Every public class and function, generated from the docstrings (NumPy style), grouped by",
             "the stage that defines it. The top level ``nlobs`` re-exports the names most scripts need",
             "(listed at the end).", ""]
    home: dict[int, str] = {}
    for modname, title in NAMESPACES:
        mod = importlib.import_module(modname)
        names = [n for n in public_names(modname) if id(getattr(mod, n)) not in home]
        if not names:
            continue
        lines += [title, "-" * len(title), "", f".. currentmodule:: {modname}", "", ".. autosummary::",
                  "   :toctree: generated", "   :nosignatures:", ""]
        for n in names:
            home[id(getattr(mod, n))] = f"{modname}.{n}"
            lines.append(f"   {n}")
        lines.append("")
    top = importlib.import_module("nlobs")
    reexported = [n for n in public_names("nlobs") if id(getattr(top, n)) in home]
    lines += ["Re-exported by ``nlobs``", "------------------------", "",
              ", ".join(f":{'class' if inspect.isclass(getattr(top, n)) else 'func'}:`nlobs.{n} <{home[id(getattr(top, n))]}>`"
                        for n in reexported), ""]
    (HERE / "api").mkdir(exist_ok=True)
    target = HERE / "api" / "index.rst"
    text = "\n".join(lines)
    if not target.exists() or target.read_text(encoding="utf-8") != text:
        target.write_text(text, encoding="utf-8")
    # autosummary's pages of names that have moved (nlobs.simulate.tune -> nlobs.learning.tune) would fail to import
    for stub in (HERE / "api" / "generated").glob("nlobs.*.rst"):
        if stub.stem not in set(home.values()):
            stub.unlink()


def write_references_page(app: Any = None) -> None:
    from nlobs.references import REFERENCES, full_citation

    lines = ["References", "==========", "",
             "Every work nlobs implements or cites, from the one table in :mod:`nlobs.references`; the",
             "library and these pages cite them by author and year.", ""]
    for k, r in REFERENCES.items():
        lines += [f".. _ref-{k}:", "", f"**{r.label}** — {full_citation(k)}", ""]
    target = HERE / "references.rst"
    text = "\n".join(lines)
    if not target.exists() or target.read_text(encoding="utf-8") != text:
        target.write_text(text, encoding="utf-8")


def write_kinds_page(app: Any = None) -> None:
    """docs/kinds.rst: every observer kind, read from the registry (nlobs.design.KINDS), as ``nlobs kinds`` lists them."""
    from nlobs.design import KINDS

    lines = ["Observer kinds", "==============", "",
             "Every kind a model file can configure (``[observers.NAME] kind = \"...\"``), read from the registry",
             ":data:`nlobs.design.KINDS`: what it is, the models it runs on, its design function and the works it",
             "implements. ``nlobs kinds KIND`` prints its options and defaults. *Tuned* kinds are tuned by",
             "``nlobs design`` (the advisor) by itself; the others need options only you can give.", "",
             ".. list-table::", "   :header-rows: 1", "   :widths: 14 44 10 8 24", "",
             "   * - kind", "     - what it is", "     - time base", "     - tuned", "     - implements"]
    for name, k in KINDS.items():
        fn = k.design.__name__
        lines += [f"   * - ``{name}``", f"     - {k.summary} (:func:`nlobs.{fn} <nlobs.design.{fn}>`)",
                  f"     - {k.time_base}", f"     - {'yes' if k.tune is not None else 'no'}",
                  f"     - {k.citation or '—'}"]
    lines.append("")
    target = HERE / "kinds.rst"
    text = "\n".join(lines)
    if not target.exists() or target.read_text(encoding="utf-8") != text:
        target.write_text(text, encoding="utf-8")


def setup(app: Any) -> dict[str, Any]:
    app.add_html_math_renderer("mathml", (_visit_math, None), (_visit_displaymath, None))
    app.add_directive("nlobs-figure", FigureDirective)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
