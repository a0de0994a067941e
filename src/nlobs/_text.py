"""User text that nlobs shows again: cut it short in messages, and keep labels safe at the source.

A model file is user text, and parts of it travel on: into error messages (a terminal, a JSON
object), the HTML report, CSV headers and the comments of exported C. Two rules keep that safe:

- messages quote user text through :func:`shorten` (a ``repr``, so control characters appear
  escaped, cut to a few dozen characters with the full length stated);
- labels (a model's name and description, units, observer names) are checked once, where they
  enter (:func:`check_label`): no control or format characters, no C comment delimiters.
"""

from __future__ import annotations

import reprlib
import unicodedata
from collections.abc import Iterable
from typing import Any

__all__ = ["shorten", "shorten_list", "check_label", "LabelError"]

#: Unicode categories a label may not contain: controls (newline, escape), format characters
#: (bidirectional overrides, zero-width joiners), surrogates, private use, unassigned, line and
#: paragraph separators.
_FORBIDDEN_CATEGORIES = frozenset({"Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp"})

_REPR = reprlib.Repr()
_REPR.maxstring = 60
_REPR.maxother = 60
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6
_REPR.maxlevel = 3


def shorten(value: Any, limit: int = 60) -> str:
    """A short ``repr`` of `value` for a message: at most about `limit` characters.

    >>> shorten("x" * 1000, 10)
    "'xxxxxxxxxx'… (1000 characters)"
    >>> shorten("a\\x1b[2J")
    "'a\\\\x1b[2J'"
    """
    if isinstance(value, str):
        if len(value) <= limit:
            return repr(value)
        return repr(value[:limit]) + f"… ({len(value)} characters)"
    try:
        return _REPR.repr(value)
    except Exception:  # noqa: BLE001 - a repr that fails must not hide the real error
        return f"<{type(value).__name__}>"


def shorten_list(names: Iterable[str], limit: int = 20, sep: str = ", ") -> str:
    """Names joined for a message, at most `limit` of them (then "… (N in all)")."""
    items = list(names)
    shown = [n if len(n) <= 40 else n[:40] + "…" for n in items[:limit]]
    text = sep.join(shown) or "(none)"
    return text + (f"{sep}… ({len(items)} in all)" if len(items) > limit else "")


class LabelError(ValueError):
    """Raised by :func:`check_label`; callers turn it into their own error with the place."""


def check_label(text: Any, what: str, *, max_length: int = 200) -> str:
    """Return `text` if it is a safe label, else raise :class:`LabelError` saying why.

    A label is a string of at most `max_length` characters with no control or format
    characters (no newline, escape, bidirectional override) and no ``*/`` or ``/*``.
    """
    if not isinstance(text, str):
        raise LabelError(f"the {what} must be a string, got {type(text).__name__}")
    if len(text) > max_length:
        raise LabelError(f"the {what} is {len(text)} characters long; the limit is {max_length}")
    for i, ch in enumerate(text):
        if unicodedata.category(ch) in _FORBIDDEN_CATEGORIES:
            raise LabelError(f"the {what} contains the control or format character U+{ord(ch):04X} at position {i}; "
                             "use printable characters only (no newlines, tabs or escape sequences)")
    for bad in ("*/", "/*"):
        if bad in text:
            raise LabelError(f"the {what} contains `{bad}` (a C comment delimiter); remove it")
    return text
