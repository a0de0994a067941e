"""The user's model in the advisor's text: the equations as written, shown once, then referred to by name.

The analyses and designs work on the model with its parameter values substituted (exact rationals:
``g = 9.81`` becomes ``981/100``) and its ``[definitions]`` inlined, and their messages quote the
expressions in that form. A user reads them against the file they wrote, so the advisor's text

- shows the model once, as written (the file's own strings, numbers and definition names; for a
  model built in Python, its expressions with the parameters by name), and
- replaces each long substituted equation quoted in a message by a reference to that row
  (``[vy' above]``), so that one 90-character expression is not repeated a dozen times.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..model import System

__all__ = ["ModelText", "model_text"]

#: Expressions shorter than this are left where they are quoted (a reference would be no shorter).
SHORT = 30


@dataclass(frozen=True)
class ModelText:
    """Rows of the model as written, and the substituted strings that stand for them in messages."""

    rows: tuple[tuple[str, str], ...]                 # ("vy'", "(Ff*cos(delta) + Fr)/m - vx*r"), ("yr", "r")
    definitions: tuple[tuple[str, str], ...] = ()     # ("af", "delta - atan((vy + lf*r)/vx)")
    quoted: tuple[tuple[str, str], ...] = ()          # (substituted text, reference) longest first
    units: tuple[tuple[str, str], ...] = ()           # the file's [units]: ("x", "m"), ("t", "s")

    def lines(self, indent: str = "  ") -> list[str]:
        """The model once, as written."""
        out = [f"{indent}model (as written): " + "; ".join(f"{k} = {v}" for k, v in self.rows)]
        if self.definitions:
            out.append(f"{indent}  where " + "; ".join(f"{k} = {v}" for k, v in self.definitions))
        return out

    def refer(self, text: str) -> str:
        """`text` with every long substituted equation replaced by a reference to its row."""
        for sub, ref in self.quoted:
            if sub in text:
                text = text.replace(sub, ref)
        return text


def _written(path: str | None) -> dict[str, Any] | None:
    if not path:
        return None
    try:
        with Path(path).open("rb") as fh:
            return tomllib.load(fh)
    except (OSError, tomllib.TOMLDecodeError, ValueError):
        return None


def model_text(system: System, path: str | None = None, plant_states: Sequence[str] | None = None,
               units: Mapping[str, str] | None = None) -> ModelText:
    """The rows of `system` as the file at `path` writes them (else with parameters by name), with the
    substituted strings that messages quote for each row. `plant_states` limits the rows to the model's own
    states (unknown parameters appended to the state have no equation of their own to show)."""
    doc = _written(path) or {}
    dyn = doc.get("dynamics") if isinstance(doc.get("dynamics"), dict) else {}
    outp = doc.get("output") if isinstance(doc.get("output"), dict) else {}
    defs = doc.get("definitions") if isinstance(doc.get("definitions"), dict) else {}
    states = list(plant_states) if plant_states is not None else list(system.states)
    f_sub, h_sub = system.substituted()
    rows: list[tuple[str, str]] = []
    quoted: list[tuple[str, str]] = []
    for i, s in enumerate(system.states):
        if s not in states:
            continue
        written = dyn.get(s) if isinstance(dyn.get(s), str) else str(system.f[i])
        rows.append((f"{s}'", " ".join(written.split())))
        sub = str(f_sub[i])
        if len(sub) >= SHORT:
            quoted.append((sub, f"[{s}' above]"))
    for k, y in enumerate(system.outputs):
        written = outp.get(y) if isinstance(outp.get(y), str) else str(system.h[k])
        rows.append((y, " ".join(written.split())))
        sub = str(h_sub[k])
        if len(sub) >= SHORT:
            quoted.append((sub, f"[{y} above]"))
    definitions = tuple((k, " ".join(v.split())) for k, v in defs.items() if isinstance(v, str))
    quoted.sort(key=lambda q: -len(q[0]))
    return ModelText(tuple(rows), definitions, tuple(quoted), tuple((units or {}).items()))
