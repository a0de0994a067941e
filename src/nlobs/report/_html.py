"""Building blocks of a self-contained HTML report: sections, tables, figures, maths, a bibliography.

Everything is inlined (no script, no font, no file beside the page): figures are PNG data URIs
drawn at twice their displayed resolution and shown at their natural size, so a figure's text
has the same size in every figure; maths is MathML (SymPy's LaTeX printer, converted by
latex2mathml), which browsers render natively, offline.

Prose may carry inline maths between dollar signs, ``"decays like $e^{-(\\varepsilon - K)t}$"``:
:func:`prose` renders it for HTML and :func:`plain` turns it into readable Unicode for a terminal.
"""

from __future__ import annotations

import base64
import html
import io
import re
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import sympy as sp
from latex2mathml.converter import convert as _latex_to_mathml

from .._display import fmt_number
from ..references import REFERENCES, cited_keys, full_citation

__all__ = ["fmt", "maths", "expr", "prose", "plain", "equations", "figure", "img", "table", "section", "details", "pre",
           "bibliography", "page", "HTML", "CSS", "FIGURE_WIDTH", "HALF_WIDTH"]

#: Width in inches of a full-width figure and of one of two side-by-side figures. Figures are
#: shown at 96 CSS pixels per inch (never scaled up), so fonts match across figures.
FIGURE_WIDTH = 10.4
HALF_WIDTH = 5.1
_CSS_DPI = 96
_PNG_DPI = 192  # twice the displayed resolution: sharp on high-density screens

CSS = """
body { font-family: system-ui, -apple-system, 'Segoe UI', sans-serif; margin: 0 auto; max-width: 1060px; padding: 1.5rem;
       color: #1d232a; line-height: 1.5; font-size: 16px; }
h1 { font-size: 1.7rem; margin-bottom: .2rem; } h2 { border-bottom: 2px solid #dfe3e8; padding-bottom: .25rem; margin-top: 2.5rem; }
h3 { font-size: 1.05rem; margin: 1.2rem 0 .4rem; }
.ref { color: #57606a; font-size: .9rem; } .ok { color: #1a7f37; font-weight: 600; } .fail { color: #cf222e; font-weight: 600; } .unchecked { color: #9a6700; font-weight: 600; }
.warn { color: #9a6700; font-weight: 600; }
.figs { display: flex; flex-wrap: wrap; gap: 16px; } figure { margin: .3rem 0; }
figcaption { font-weight: 600; margin: .2rem 0; }
table { border-collapse: collapse; margin: .5rem 0 1rem; font-size: .9rem; display: block; overflow-x: auto; max-width: 100%; }
th, td { border: 1px solid #d0d7de; padding: .3rem .6rem; text-align: right; white-space: nowrap; } th { background: #f6f8fa; }
td.l, th.l { text-align: left; white-space: normal; }
pre { background: #f6f8fa; padding: .7rem; font-size: .82rem; border-radius: 6px; white-space: pre-wrap; overflow-wrap: anywhere; }
details { margin: .4rem 0; } summary { cursor: pointer; color: #0969da; }
img { max-width: 100%; height: auto; border: 1px solid #eaeef2; border-radius: 4px; }
nav ol { columns: 2; } .claims li { margin: .25rem 0; } .note { color: #57606a; font-size: .92rem; }
math { font-size: 1.05em; } math[display=block] { margin: .4rem 0; overflow-x: auto; max-width: 100%; }
.eqs { overflow-x: auto; } .eqs mtd { padding: .15rem .2rem; } .eqs mtd:first-child { text-align: right; }
.eqs mtd:last-child { text-align: left; } .bib li { margin: .35rem 0; }
"""


def fmt(value: Any, digits: int = 3) -> str:
    """A number for a table: 3 significant digits, '—' for None and NaN; text as is."""
    return fmt_number(value, digits)


# -- maths ------------------------------------------------------------------------------------

def maths(latex: str, *, display: bool = False) -> str:
    """LaTeX as MathML (``<math>``), inline or as a displayed block."""
    return _latex_to_mathml(latex, display="block" if display else "inline")


def expr(e: Any, *, display: bool = False) -> str:
    """A SymPy expression, a SymPy matrix or a nested list (shown as a matrix) as MathML."""
    if isinstance(e, (list, tuple)):
        e = sp.Matrix(e)
    return maths(sp.latex(e), display=display)


_DOLLARS = re.compile(r"\$([^$]+)\$")
_MATHS_OR_CODE = re.compile(r"\$([^$]+)\$|`([^`]+)`")


def prose(text: str) -> str:
    """Escaped HTML of `text`, with the maths between dollar signs rendered and the code between backticks (a
    command, an option, a name) set as ``<code>``."""
    out, last = [], 0
    for m in _MATHS_OR_CODE.finditer(text):
        out.append(html.escape(text[last:m.start()]))
        out.append(maths(m.group(1)) if m.group(1) is not None else f"<code>{html.escape(m.group(2))}</code>")
        last = m.end()
    out.append(html.escape(text[last:]))
    return "".join(out)


_GREEK = {name: chr(code) for name, code in [
    ("alpha", 0x3B1), ("beta", 0x3B2), ("gamma", 0x3B3), ("delta", 0x3B4), ("epsilon", 0x3B5), ("varepsilon", 0x3B5),
    ("zeta", 0x3B6), ("eta", 0x3B7), ("theta", 0x3B8), ("kappa", 0x3BA), ("lambda", 0x3BB), ("mu", 0x3BC), ("nu", 0x3BD),
    ("xi", 0x3BE), ("pi", 0x3C0), ("rho", 0x3C1), ("sigma", 0x3C3), ("tau", 0x3C4), ("phi", 0x3C6), ("varphi", 0x3C6),
    ("chi", 0x3C7), ("psi", 0x3C8), ("omega", 0x3C9), ("Gamma", 0x393), ("Delta", 0x394), ("Theta", 0x398),
    ("Lambda", 0x39B), ("Xi", 0x39E), ("Pi", 0x3A0), ("Sigma", 0x3A3), ("Phi", 0x3A6), ("Psi", 0x3A8), ("Omega", 0x3A9)]}
_SYMBOLS = {"cdot": "·", "times": "×", "le": "≤", "leq": "≤", "ge": "≥", "geq": "≥", "ne": "≠", "neq": "≠", "to": "→",
            "rightarrow": "→", "infty": "∞", "in": "∈", "approx": "≈", "pm": "±", "mp": "∓", "partial": "∂", "nabla": "∇",
            "int": "∫", "sum": "∑", "|": "‖", "sin": "sin", "cos": "cos", "tan": "tan", "exp": "exp", "log": "log",
            "ln": "ln", "min": "min", "max": "max", "sup": "sup", "inf": "inf", "det": "det", ",": " ", ";": " ", "quad": "  ",
            "left": "", "right": "", "top": "ᵀ", "lambda_{\\min}": "λmin", "dot": "", "hat": "", "tilde": "", "bar": ""}
_SUP = str.maketrans("0123456789+-−=()niT", "⁰¹²³⁴⁵⁶⁷⁸⁹⁺⁻⁻⁼⁽⁾ⁿⁱᵀ")
_SUB = str.maketrans("0123456789+-=()", "₀₁₂₃₄₅₆₇₈₉₊₋₌₍₎")
_ACCENT = {"hat": "\u0302", "dot": "\u0307", "tilde": "\u0303", "bar": "\u0304"}


def _plain_maths(tex: str) -> str:
    s = tex
    s = re.sub(r"\\(hat|dot|tilde|bar)\{(\w)\}", lambda m: m.group(2) + _ACCENT[m.group(1)], s)
    s = re.sub(r"\\(hat|dot|tilde|bar)\s*(\w)", lambda m: m.group(2) + _ACCENT[m.group(1)], s)
    s = re.sub(r"\\frac\{([^{}]*)\}\{([^{}]*)\}", r"(\1)/(\2)", s)
    s = re.sub(r"\\sqrt\{([^{}]*)\}", r"√(\1)", s)
    s = re.sub(r"\\(?:mathrm|text|operatorname)\{([^{}]*)\}", r"\1", s)
    s = re.sub(r"\\([A-Za-z]+|[|,;])", lambda m: _GREEK.get(m.group(1), _SYMBOLS.get(m.group(1), m.group(1))), s)

    def script(m: re.Match[str], table: dict[int, int], mark: str) -> str:
        body = m.group(1) if m.group(1) is not None else m.group(2)
        conv = body.translate(table)
        return conv if all(c not in body for c in "abcdefghjklmopqrsuvwxyzABCDEFGHIJKLMNOPQRSUVWXYZ*/.,") or len(body) == 0 \
            else body if mark == "_" and body.isalpha() else f"{mark}({body})" if len(body) > 1 else f"{mark}{body}"

    s = re.sub(r"\^\{([^{}]*)\}|\^(\S)", lambda m: script(m, _SUP, "^"), s)
    s = re.sub(r"_\{([^{}]*)\}|_(\S)", lambda m: script(m, _SUB, "_"), s)
    return s.replace("{", "").replace("}", "")


def plain(text: str) -> str:
    """`text` for a terminal: the maths between dollar signs as readable Unicode.

    >>> plain(r"below $\\|e(0)\\| e^{-(\\varepsilon - K)t}$ from t = 0")
    'below ‖e(0)‖ e^(-(ε - K)t) from t = 0'
    """
    return _DOLLARS.sub(lambda m: _plain_maths(m.group(1)), text)


def _dotted(name: str) -> str:
    """The time derivative of a state as LaTeX, the dot on the letter: x1 -> \\dot{x}_{1}."""
    tex = sp.latex(sp.Symbol(name))
    m = re.fullmatch(r"(\\?[A-Za-z]+)_\{(.+)\}", tex)
    return rf"\dot{{{m.group(1)}}}_{{{m.group(2)}}}" if m else rf"\dot{{{tex}}}"


def _next(name: str) -> str:
    """The next value of a state of a map as LaTeX: x1 -> x_{1}[k+1]."""
    return rf"{sp.latex(sp.Symbol(name))}[k+1]"


def _number(v: float) -> str:
    """A number as LaTeX, 6 significant digits: 0.002, 4 \\cdot 10^{6} (not 4e+06, which maths reads as e + 06)."""
    mantissa, _, exponent = f"{v:g}".partition("e")
    if not exponent:
        return mantissa
    power = f"10^{{{int(exponent)}}}"
    return power if mantissa == "1" else rf"{mantissa} \cdot {power}"


def equations(system: Any, *, display: bool = True) -> str:
    """A model's equations, ẋᵢ = fᵢ(x, u, t) (xᵢ[k+1] = fᵢ(x, u, t) for a map, ``time="discrete"``) and
    yⱼ = hⱼ(x, u, t), as one aligned MathML block."""
    lhs = _next if getattr(system, "is_discrete", False) else _dotted
    rows = [rf"{lhs(n)} &=& {sp.latex(e)}" for n, e in zip(system.states, system.f)]
    rows += [rf"{sp.latex(sp.Symbol(n))} &=& {sp.latex(e)}" for n, e in zip(system.outputs, system.h)]
    body = maths(r"\begin{array}{rcl}" + r"\\".join(rows) + r"\end{array}", display=display)
    params = getattr(system, "params", {}) or {}
    if params:
        body += "<p class='note'>parameters: " + ", ".join(
            maths(f"{sp.latex(sp.Symbol(k))} = {_number(v)}") for k, v in params.items()) + "</p>"
    return f"<div class='eqs'>{body}</div>"


# -- figures, tables, text --------------------------------------------------------------------

def _png(fig: Any) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=_PNG_DPI)
    return buf.getvalue()


def img(fig: Any, alt: str) -> str:
    """A matplotlib figure as an inline PNG shown at its natural size (96 CSS px per inch)."""
    w, h = fig.get_size_inches()
    data = base64.b64encode(_png(fig)).decode()
    return (f'<img alt="{html.escape(alt)}" width="{round(w * _CSS_DPI)}" height="{round(h * _CSS_DPI)}" '
            f'src="data:image/png;base64,{data}">')


def figure(fig: Any, caption: str = "", *, alt: str | None = None) -> str:
    """A ``<figure>`` with the plot and an optional caption (prose, maths allowed)."""
    cap = f"<figcaption>{prose(caption)}</figcaption>" if caption else ""
    return f"<figure>{cap}{img(fig, alt or plain(caption) or 'figure')}</figure>"


def table(rows: Sequence[Mapping[str, Any]], columns: Sequence[tuple[str, str]]) -> str:
    """An HTML table of `rows` with `columns` = [(key, header), ...]; text columns left-aligned."""
    def is_text(k: str) -> bool:
        return any(isinstance(r.get(k), str) for r in rows)

    text = {k for k, _ in columns if is_text(k)}
    head = "".join(f"<th{' class=l' if k in text else ''}>{html.escape(h)}</th>" for k, h in columns)
    body = "".join("<tr>" + "".join(
        f"<td{' class=l' if k in text else ''}>{prose(fmt(r.get(k)))}</td>" for k, _ in columns) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def pre(text: str) -> str:
    """Preformatted text (wrapped, never wider than the page)."""
    return f"<pre>{html.escape(text)}</pre>"


def details(summary: str, body: str, *, open: bool = False) -> str:
    """A collapsible block."""
    return f"<details{' open' if open else ''}><summary>{html.escape(summary)}</summary>{body}</details>"


def section(title: str, body: Iterable[str] | str, *, id: str | None = None, level: int = 2, subtitle: str = "") -> str:
    """A heading (prose, maths allowed), an optional grey subtitle, and the body."""
    anchor = f" id='{html.escape(id)}'" if id else ""
    sub = f"<p class='ref'>{subtitle}</p>" if subtitle else ""
    return f"<section><h{level}{anchor}>{prose(title)}</h{level}>{sub}{body if isinstance(body, str) else ''.join(body)}</section>"


def bibliography(*texts: str, title: str = "References") -> str:
    """The full references (authors, title, venue, year) of every work cited in `texts`, each with an
    anchor ``ref-KEY``; empty when nothing is cited."""
    keys = cited_keys("\n".join(texts))
    if not keys:
        return ""
    items = []
    for k in keys:
        r = REFERENCES[k]
        link = f" <a href='https://doi.org/{html.escape(r.doi)}'>doi:{html.escape(r.doi)}</a>" if r.doi else ""
        items.append(f"<li id='ref-{html.escape(k)}'>{html.escape(full_citation(k).removesuffix(f', doi:{r.doi}.'))}{link}</li>")
    return section(title, f"<ol class='bib'>{''.join(items)}</ol>", id="references")


class HTML(str):
    """A piece of HTML that shows itself as HTML in a notebook (and in a documentation gallery)."""

    def _repr_html_(self) -> str:
        return str(self)


def page(title: str, subtitle: str, body: Iterable[str]) -> str:
    """A complete HTML page (UTF-8, inline CSS, nothing loaded from elsewhere)."""
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'><title>{html.escape(title)}</title>"
            f"<style>{CSS}</style></head><body><h1>{html.escape(title)}</h1><p class='ref'>{subtitle}</p>"
            + "".join(body) + "</body></html>")
