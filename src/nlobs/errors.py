"""The nlobs exception tree.

Every error nlobs raises on purpose is a :class:`NlobsError`, and each one also
derives from the built-in exception a caller would naturally catch
(``ValueError`` for bad input, ``RuntimeError`` for numerical failures), so
``except ValueError`` keeps working for code that does not know about nlobs.

Messages follow one template: what failed, where, what was expected, what was
found, and what to change.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ._text import shorten

__all__ = [
    "NlobsError",
    "ModelError",
    "ModelFileError",
    "SymbolicBudgetError",
    "ResourceError",
    "FormError",
    "ShapeError",
    "PreconditionError",
    "DataError",
    "EngineError",
    "FiniteEscapeError",
    "SolverError",
    "TimeBudgetError",
    "ConvergenceWarning",
]


class NlobsError(Exception):
    """Base class of every error raised by nlobs on purpose."""


class ModelError(NlobsError, ValueError):
    """A model is malformed: unknown symbol, duplicate name, wrong number of equations."""


class ModelFileError(ModelError):
    """A model file is malformed or tries to do something a model file may not do.

    Attributes
    ----------
    path : str
        The file (or ``"<string>"``).
    key : str
        The dotted TOML key where the problem is (``"dynamics.x2"``), or ``""``.
    text : str
        The offending text, if any.
    """

    def __init__(self, message: str, *, path: str = "<string>", key: str = "", text: str = ""):
        # user text is quoted short (a repr, so control characters show escaped): the reason must not
        # drown behind a 50 MB line; the attributes keep the full values
        where = path if len(path) <= 200 and path.isprintable() else shorten(path, 200)
        if key:
            where += f", key `{key if len(key) <= 80 and key.isprintable() else shorten(key, 80)}`"
        shown = f": {shorten(text)}" if text else ""
        super().__init__(f"{where}{shown}: {message}")
        self.path = path
        self.key = key
        self.text = text


class SymbolicBudgetError(ModelError):
    """Symbolic work on a model's expressions exceeded its size or time budget (see ``nlobs.model.symbolic_budget``)."""


class FormError(NlobsError, ValueError):
    """A model is not in the structured form asked for; the message names the entry that breaks it."""


class ShapeError(NlobsError, ValueError):
    """An array has the wrong shape."""


class PreconditionError(NlobsError, ValueError):
    """A design's precondition does not hold (unobservable pair, non-Hurwitz gain, ...)."""


class DataError(NlobsError, ValueError):
    """Measured or recorded data are unusable (NaN/inf, non-increasing time, ...)."""


class EngineError(NlobsError, RuntimeError):
    """The numeric engine failed (compiler error, CasADi error)."""


class FiniteEscapeError(NlobsError, RuntimeError):
    """A simulation blew up: a state became non-finite or left the allowed bound.

    Attributes
    ----------
    t : float
        Time of the last finite sample before the blow-up.
    x : numpy.ndarray
        The state at that time.
    where : str
        Which system blew up (``"plant"``, ``"the plant's output"`` or the observer's name).
    culprits : tuple of (str, float)
        The entries that left the bound or became non-finite in the next step (at most two), when known.

    `message` replaces the default text when the caller knows more (the sample, the data).
    """

    def __init__(self, where: str, t: float, x: np.ndarray, names: Sequence[str], bound: float, *,
                 message: str | None = None, hint: str = "", culprits: Sequence[tuple[str, float]] = ()):
        shown = _shown(names, np.asarray(x, dtype=float), [c for c, _ in culprits])
        if culprits and not message:
            went = ", ".join(f"{c} = {v:.3g}" for c, v in culprits)
            shown = f"{shown}; in the next step {went}"
        if message:
            text = message
        elif hint:  # where exactly, when the "next step" is not one step (e.g. between two recorded samples)
            text = (f"{where} blew up after t = {t:.6g}: its state became non-finite {hint}; last finite state: {shown}. "
                    "Check the model, the initial estimate and the tuning, or pass a smaller `max_step`.")
        else:
            text = (f"{where} blew up after t = {t:.6g}: the state left |x| <= {bound:g} or became "
                    f"non-finite in the next step; last finite state: {shown}. " +
                    ("Check the observer's tuning and its initial estimate, or reduce `dt`." if where.startswith("observer")
                     else "Check the model and the initial state, or reduce `dt`."))
        super().__init__(text)
        self.where = where
        self.t = float(t)
        self.x = np.asarray(x, dtype=float)
        #: The one or two entries that left the bound or became non-finite in the next step, with their values.
        self.culprits = tuple((str(c), float(v)) for c, v in culprits)

    @property
    def reason(self) -> str:
        """One line: when, and the quantities that blew up (for a table row)."""
        went = ", ".join(f"{c} = {v:.3g}" for c, v in self.culprits)
        return f"blew up after t = {self.t:.6g}" + (f" ({went} in the next step)" if went else "")


def _shown(names: Sequence[str], x: np.ndarray, first: Sequence[str], limit: int = 6) -> str:
    """``name=value`` of a state; a long one (a filter's 36 covariance entries) as the named entries `first`
    and the largest ones, up to `limit`, and how many are left out."""
    pairs = list(zip(names, x))
    if len(pairs) <= limit:
        return ", ".join(f"{n}={v:.6g}" for n, v in pairs)
    order = sorted(range(len(pairs)), key=lambda i: (pairs[i][0] not in first, -abs(pairs[i][1]) if np.isfinite(pairs[i][1])
                                                                              else -np.inf))
    keep = sorted(order[:limit])
    return ", ".join(f"{pairs[i][0]}={pairs[i][1]:.6g}" for i in keep) + f" (the largest {limit} of {len(pairs)} entries)"


class SolverError(NlobsError, RuntimeError):
    """An optimisation solved inside an estimator failed (e.g. the NLP of a moving-horizon window).

    Attributes
    ----------
    window : tuple of float
        The time span (first and last sample time) of the data the solver was given.
    status : str
        What the solver(s) reported.
    """

    def __init__(self, message: str, *, window: tuple[float, float], status: str):
        super().__init__(message)
        self.window = (float(window[0]), float(window[1]))
        self.status = status


class TimeBudgetError(NlobsError, RuntimeError):
    """A run (one observer's, in ``nlobs design --run``) did not finish within its time budget.

    Attributes
    ----------
    seconds : float
        The budget.
    what : str
        What was running when it ran out (compiling, the compiled loop, the virtual machine).
    """

    def __init__(self, seconds: float, what: str):
        super().__init__(f"did not finish within {seconds:g} s (its time budget; it was {what}). Give it more time "
                         "(nlobs design --run --budget SECONDS) or run it alone with nlobs simulate")
        self.seconds, self.what = float(seconds), what


class ResourceError(NlobsError, MemoryError):
    """A computation ran out of memory or of Python's recursion depth (a MemoryError, so code that catches those still
    does); the message says which, where, and what to change.

    Attributes
    ----------
    resource : str
        ``"memory"`` or ``"recursion depth"``.
    stage : str
        What was running.
    """

    def __init__(self, resource: str, stage: str, advice: str):
        super().__init__(f"ran out of {resource} during {stage}" + (f". {advice}" if advice else ""))
        self.resource, self.stage = resource, stage


class ConvergenceWarning(UserWarning):
    """A soft failure: an estimate did not converge, a fallback was used."""
