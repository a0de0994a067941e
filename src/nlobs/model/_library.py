"""The bundled model library: classic models shipped in ``nlobs/models``, usable by name wherever a
model file is expected (``nlobs design lorenz``, ``load_model("lorenz")``).

A path that exists always wins over a bundled name, so a user's own ``lorenz.toml`` is never
shadowed. :func:`load_model` calls :func:`bundled_path` when the path it was given does not exist.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

__all__ = ["LibraryEntry", "bundled_names", "bundled_path", "bundled_folder"]

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


def bundled_folder() -> Path:
    return Path(__file__).resolve().parent.parent / "models"  # package data (pyproject: nlobs = ["models/*.toml"])


def bundled_names() -> tuple[str, ...]:
    """The names of the bundled models, sorted."""
    return tuple(sorted(p.stem for p in bundled_folder().glob("*.toml")))


def bundled_path(name: str) -> Path | None:
    """The file of the bundled model `name` (``"lorenz"`` or ``"lorenz.toml"``), or None when there is none.

    Only a bare name is looked up: anything with a directory part is a path, never a library name.
    """
    text = str(name)
    stem = text[:-5] if text.endswith(".toml") else text
    if not _NAME.match(stem):
        return None
    path = bundled_folder() / f"{stem}.toml"
    return path if path.is_file() else None


@dataclass(frozen=True)
class LibraryEntry:
    """One bundled model: its name, the one-line description (which cites its source), and its size."""

    name: str
    description: str
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    path: str

    def to_dict(self) -> dict[str, object]:
        return {"name": self.name, "description": self.description, "states": list(self.states),
                "inputs": list(self.inputs), "outputs": list(self.outputs), "path": self.path}
