"""What several commands share: loading designs from a model file, JSON cleaning, error lines."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

__all__ = ["designs_of", "clean", "error_message"]


def error_message(e: BaseException) -> str:
    """The first line of an error's message (a KeyError's message without its quotes)."""
    text = e.args[0] if isinstance(e, KeyError) and e.args else str(e)
    return (str(text).splitlines() or [type(e).__name__])[0]


def designs_of(model_file: Any, names: Sequence[str] | None) -> dict[str, Any]:
    """The designs of the observers `names` configured in `model_file` (all when `names` is empty),
    after the identifiability check of its unknown parameters (``nlobs.design.designs_from_file``)."""
    from ..design import designs_from_file

    return designs_from_file(model_file, names)


def clean(value: Any) -> Any:
    """JSON-safe: NaN/inf become null."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: clean(v) for k, v in value.items()}
    if isinstance(value, list):
        return [clean(v) for v in value]
    return value
