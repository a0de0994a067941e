"""How results show themselves: a text table for the terminal, the same table as HTML for a
notebook, and a pandas DataFrame for further work; compact reprs of big result objects.

Used by every layer (a top-level private module, like ``_progress``), so it imports nothing
of nlobs.
"""

from __future__ import annotations

import html
import textwrap
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Column", "SummaryTable", "fmt_number", "html_block", "short_repr"]

#: The one mark for "no value" in every table nlobs prints (not converged, not defined).
MISSING = "—"


def fmt_number(value: Any, digits: int = 3) -> str:
    """A number for a table: `digits` significant digits; ``—`` for None and NaN."""
    if value is None:
        return MISSING
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int):
        return str(value)
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    if v != v:  # NaN
        return MISSING
    return f"{v:.{digits}g}"


@dataclass(frozen=True)
class Column:
    """One column of a :class:`SummaryTable`: the row key, its header, and how to format a value."""

    key: str
    header: str
    fmt: Callable[[Any], str] = fmt_number
    numeric: bool = True


@dataclass(frozen=True)
class SummaryTable:
    """A table of results that prints as text, shows as HTML in a notebook and converts to pandas.

    Attributes
    ----------
    title : str
        One line above the table.
    columns : sequence of Column
    rows : sequence of mapping
        One mapping per row, keyed by the columns' keys (raw values: numbers, None, text).
    notes : sequence of str
        Lines printed under the table (failures, what a dash means).
    """

    title: str
    columns: Sequence[Column]
    rows: Sequence[Mapping[str, Any]]
    notes: Sequence[str] = field(default_factory=tuple)

    def _cells(self) -> list[list[str]]:
        return [[c.fmt(r.get(c.key)) for c in self.columns] for r in self.rows]

    def __str__(self) -> str:
        cells = self._cells()
        widths = [max([len(c.header)] + [len(row[i]) for row in cells]) for i, c in enumerate(self.columns)]

        def line(values: Sequence[str]) -> str:
            return " ".join(v.rjust(w) if c.numeric else v.ljust(w) for v, w, c in zip(values, widths, self.columns)).rstrip()

        head = line([c.header for c in self.columns])
        out = [self.title, head, "-" * len(head)] + [line(row) for row in cells]
        width = max(88, len(head))
        notes = [wrapped for n in self.notes for wrapped in (textwrap.wrap(n, width, subsequent_indent="  ") or [""])]
        return "\n".join(out + notes)

    def __repr__(self) -> str:
        return str(self)

    def _repr_html_(self) -> str:
        head = "".join(f"<th>{html.escape(c.header)}</th>" for c in self.columns)
        body = "".join(
            "<tr>" + "".join(f"<td style='text-align:{'right' if c.numeric else 'left'}'>{html.escape(v)}</td>"
                             for v, c in zip(row, self.columns)) + "</tr>" for row in self._cells())
        notes = "".join(f"<div>{html.escape(n)}</div>" for n in self.notes)
        return (f"<div class='nlobs-summary'><div><b>{html.escape(self.title)}</b></div>"
                f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>{notes}</div>")

    def to_pandas(self) -> Any:
        """The rows as a DataFrame (raw values, one column per key; needs pandas)."""
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError("to_pandas needs pandas: pip install 'nlobs[pandas]'") from e
        return pd.DataFrame([{c.key: r.get(c.key) for c in self.columns} for r in self.rows],
                            columns=[c.key for c in self.columns])


def html_block(title: str, text: str) -> str:
    """A result's text form as an HTML block for a notebook: a bold title over preformatted text."""
    return (f"<div class='nlobs-result'><b>{html.escape(title)}</b>"
            f"<pre style='white-space:pre-wrap'>{html.escape(text)}</pre></div>")


def short_repr(obj: Any, fields: Mapping[str, Any]) -> str:
    """``ClassName(field=value, ...)`` with short values (arrays by shape)."""
    parts = []
    for k, v in fields.items():
        shape = getattr(v, "shape", None)
        if shape is not None and getattr(v, "ndim", 0) > 0:
            parts.append(f"{k}=<array {'×'.join(map(str, shape))}>")
        elif isinstance(v, (list, tuple)) and len(v) > 6:
            parts.append(f"{k}=[{', '.join(map(repr, v[:5]))}, ... {len(v)} items]")
        else:
            parts.append(f"{k}={v!r}")
    return f"{type(obj).__name__}({', '.join(parts)})"
