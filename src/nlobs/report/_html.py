"""A self-contained HTML report: text, tables and plots embedded as PNG data URIs."""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

__all__ = ["figure_png", "img", "table", "page", "fmt"]

CSS = """
body { font-family: system-ui, -apple-system, 'Segoe UI', sans-serif; margin: 0 auto; max-width: 1100px; padding: 1.5rem;
       color: #1d232a; line-height: 1.45; }
h1 { font-size: 1.7rem; margin-bottom: .2rem; } h2 { border-bottom: 2px solid #dfe3e8; padding-bottom: .25rem; margin-top: 2.5rem; }
h3 { font-size: 1.05rem; margin: 1.2rem 0 .4rem; }
.ref { color: #57606a; font-size: .9rem; } .ok { color: #1a7f37; font-weight: 600; } .fail { color: #cf222e; font-weight: 600; }
table { border-collapse: collapse; margin: .5rem 0 1rem; font-size: .9rem; }
th, td { border: 1px solid #d0d7de; padding: .3rem .6rem; text-align: right; } th { background: #f6f8fa; }
td:first-child, th:first-child, td.l { text-align: left; }
pre { background: #f6f8fa; padding: .7rem; overflow-x: auto; font-size: .82rem; border-radius: 6px; }
details { margin: .4rem 0; } summary { cursor: pointer; color: #0969da; }
img { max-width: 100%; border: 1px solid #eaeef2; border-radius: 4px; margin: .3rem 0; }
nav ul { columns: 2; } .claims li { margin: .2rem 0; } .note { color: #57606a; font-size: .9rem; }
"""


def fmt(value: Any, digits: int = 3) -> str:
    """A number for a table: 3 significant digits, '—' for None."""
    if value is None:
        return "—"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def figure_png(fig: Any, dpi: int = 100) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def img(fig: Any, alt: str) -> str:
    data = base64.b64encode(figure_png(fig)).decode()
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def table(rows: Sequence[Mapping[str, Any]], columns: Sequence[tuple[str, str]]) -> str:
    """An HTML table of `rows` with `columns` = [(key, header), ...]."""
    head = "".join(f"<th>{html.escape(h)}</th>" for _, h in columns)
    body = []
    for r in rows:
        body.append("<tr>" + "".join(f"<td>{html.escape(fmt(r.get(k)))}</td>" for k, _ in columns) + "</tr>")
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def page(title: str, subtitle: str, body: Iterable[str]) -> str:
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{CSS}</style></head><body><h1>{html.escape(title)}</h1><p class='ref'>{subtitle}</p>"
            + "".join(body) + "</body></html>")
