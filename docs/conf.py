"""Sphinx configuration of the nlobs documentation (``./dev.sh docs`` builds it into site/)."""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

import nlobs  # noqa: E402
import nlobs_docs  # noqa: E402

project = "nlobs"
author = "the nlobs developers"
copyright = "the nlobs developers"  # noqa: A001
release = version = nlobs.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
    "sphinx_gallery.gen_gallery",
    "nlobs_docs",
]

# The gallery's scripts, the API index and the references page are written from the code at
# every build, so the site cannot drift from the library.
nlobs_docs.write_gallery_sources()
nlobs_docs.write_api_pages()
nlobs_docs.write_references_page()
nlobs_docs.write_kinds_page()

html_math_renderer = "mathml"
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autodoc_preserve_defaults = True
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True
add_module_names = False
# Type fields such as "array_like of shape (n,)" make the Python domain look up "n"; where several
# objects have such an attribute it warns about the ambiguity (the link still resolves). Those
# lookups are noise, not errors of the docs, so that one category is not an error.
suppress_warnings = ["autosummary.import_cycle", "ref.python"]

sphinx_gallery_conf = {
    "examples_dirs": "_gallery_src",
    "gallery_dirs": "gallery",
    "filename_pattern": r"plot_",
    "capture_repr": ("_repr_html_",),
    "image_scrapers": (nlobs_docs.FigureScraper(),),
    "download_all_examples": False,
    "remove_config_comments": True,
    "show_memory": False,
    "show_signature": False,
    "min_reported_time": 10_000,
    "within_subsection_order": "FileNameSortKey",
    "first_notebook_cell": None,
    "write_computation_times": False,  # its page loads a table script from the network
}

templates_path = []
exclude_patterns = ["_build", "_gallery_src", "**.ipynb_checkpoints", "sg_execution_times.rst"]  # it loads a script from a CDN
html_theme = "pydata_sphinx_theme"
html_title = f"nlobs {release}"
html_static_path = ["_static"]
html_css_files = ["nlobs.css"]
html_show_sourcelink = False
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
}
# The left sidebar lists the pages of a section (the guides, the gallery, the API); a page with none below it
# (the home page, the kinds, the references, the developers' page, the command and model-file references, the
# measurements) has no left sidebar rather than an empty one.
html_sidebars = {"**": ["sidebar-nav-bs"], "index": [], "kinds": [], "references": [], "developers": [], "commands": [],
                 "model_files": [], "benchmarks": []}
