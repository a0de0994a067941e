"""User-facing text cites works through the one table in nlobs.references (DEVELOPERS guide)."""

from __future__ import annotations

import ast
import io
import re
import tokenize
from pathlib import Path

import pytest

import nlobs
from nlobs.references import REFERENCES, bibliography, cite, cited_keys, full_citation

ROOT = Path(nlobs.__file__).parent
FILE_NAME = re.compile(r"\d{3}_[0-9a-f]{16}\.txt")
BARE_NUMBER = re.compile(r"(?<![\w.])00[0-4](?![\w-])")


def _string_literals(path: Path):
    """(line, text) of every string literal that is not a docstring nor the key given to cite(...) or work(...)."""
    src = path.read_text()
    docs = set()
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
                docs.add((first.value.lineno, first.value.col_offset))
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) in ("cite", "work") and node.args \
                and isinstance(node.args[0], ast.Constant):
            docs.add((node.args[0].lineno, node.args[0].col_offset))
    for tok in tokenize.generate_tokens(io.StringIO(src).readline):
        if tok.type == tokenize.STRING and tok.start not in docs:
            yield tok.start[0], tok.string


def test_no_user_facing_string_names_a_paper_by_file_or_number():
    bad = []
    for path in sorted(ROOT.rglob("*.py")):
        if path.name == "references.py":
            continue
        for line, text in _string_literals(path):
            text = re.sub(r"cite\(['\"]\w+['\"]", "cite(", text)  # the key inside an f-string's cite(...) call
            if FILE_NAME.search(text) or BARE_NUMBER.search(text):
                bad.append(f"{path.relative_to(ROOT)}:{line}: {text[:80]}")
    assert not bad, "cite papers with nlobs.references.cite(...):\n" + "\n".join(bad)


def test_the_table_gives_authors_title_venue_and_year_for_every_work():
    for key, ref in REFERENCES.items():
        assert ref.authors and ref.title and ref.venue and 1900 < ref.year < 2100, key
        full = full_citation(key)
        assert ref.title in full and str(ref.year) in full and ref.authors in full
    assert {"000", "001", "002", "003", "004"} <= set(REFERENCES)
    assert REFERENCES["004"].doi == "10.1109/TAC.2018.2839526"


def test_cite_and_the_bibliography_of_a_text():
    text = f"see {cite('004', 'Proposition 3')} and {cite('002')}"
    assert text == "see Yi, Ortega & Zhang (2019), Proposition 3 and Besançon (2010)"
    assert cited_keys(text) == ["004", "002"]
    assert bibliography(text)[0].startswith('B. Yi, R. Ortega, W. Zhang, "On state observers')
    with pytest.raises(KeyError, match="no reference 'zz'"):
        cite("zz")


def test_certificates_cite_by_author():
    from nlobs.examples import EXAMPLES  # noqa: F401 - registers nothing at import; designs below are cheap

    pend = nlobs.System(states=["x1", "x2"], f=["x2", "-sin(x1) + u"], inputs=["u"], outputs=["y"], h=["x1"])
    cert = nlobs.design_output_injection(pend, poles=[-2, -3]).certificate
    assert cited_keys(cert.reference) == ["002"] and not FILE_NAME.search(str(cert))


def _docstrings(path: Path):
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node, clean=False)
            if doc:
                yield getattr(node, "lineno", 1), doc


def test_docstrings_cite_by_author_and_year():
    """Docstrings become the API reference: no paper file names, no bare paper numbers."""
    found = [(path, line, doc, FILE_NAME.search(doc) or BARE_NUMBER.search(doc))
             for path in sorted(ROOT.rglob("*.py")) if path.name != "references.py" for line, doc in _docstrings(path)]
    bad = [f"{path.relative_to(ROOT)}:{line}: ...{doc[max(0, m.start() - 30):m.end() + 30]!r}" for path, line, doc, m in found if m]
    assert not bad, "cite papers by author and year in docstrings:\n" + "\n".join(bad)


def test_author_year_citations_of_the_table_are_spelled_as_the_table_spells_them():
    """A docstring that cites a work of the table by its surnames uses the table's label (so that
    cited_keys finds it: `nlobs kinds` and the bibliographies are built from it)."""
    bad = []
    for path in sorted(ROOT.rglob("*.py")):
        for line, doc in _docstrings(path):
            for r in REFERENCES.values():
                first = r.short.split(",")[0].split(" &")[0]
                for m in re.finditer(rf"{re.escape(first)}[^()\n]{{0,60}}\(?{r.year}\)?", doc):
                    if r.label not in doc[max(0, m.start() - 5):m.end() + 5] and r.short in m.group(0):
                        bad.append(f"{path.relative_to(ROOT)}:{line}: {m.group(0)!r} (the table: {r.label!r})")
    assert not bad, "\n".join(bad)
