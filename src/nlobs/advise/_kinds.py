r"""Each registered observer kind tried on the advisor's context: its own ``tune`` (declared with the kind, next to its
design function; :mod:`nlobs.design._kind`) chooses options or says why the kind does not apply, and the design
runs with those options.

A precondition that fails comes back with the design's own message (the failed condition and its numbers). A kind
without a ``tune`` is listed as "not tuned" with the options its design function takes; one whose time base is not
the model's is refused with that reason.
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..design import KINDS, ObserverDesign, Tuning, design_from_config, options_of
from ..design._tune import clean_message
from ..errors import FormError, ModelError, NlobsError, PreconditionError, ShapeError, SymbolicBudgetError
from ..model._budget import symbolic_budget, symbolic_seconds
from ._advice import Candidate
from ._context import Context

__all__ = ["try_kind", "KIND_SECONDS", "kind_seconds"]

#: Seconds of symbolic work (SymPy) one kind's trial may take in the advisor before it is reported as "not checked
#: within budget" (a design called directly keeps the larger budget of one step, NLOBS_SYMBOLIC_SECONDS); the
#: environment variable NLOBS_KIND_SECONDS overrides it.
KIND_SECONDS = 5.0


def kind_seconds() -> float:
    """The advisor's symbolic budget per kind: ``$NLOBS_KIND_SECONDS``, else :data:`KIND_SECONDS`."""
    try:
        return max(0.1, float(os.environ.get("NLOBS_KIND_SECONDS", KIND_SECONDS)))
    except ValueError:
        return KIND_SECONDS


def _guarantee(d: ObserverDesign) -> str:
    checks = d.certificate.checks
    held = [c for c in checks if c.status == "holds"]
    assumed = [c for c in checks if c.status == "assumed"]
    text = f"{len(held)} certificate check(s) hold"
    if assumed:
        text += "; assumed, not verified: " + "; ".join(c.condition for c in assumed)
    return text


def _designed(ctx: Context, kind: str, options: Mapping[str, Any], tuning: str, *, runnable: bool = True,
              extra: str = "") -> Candidate:
    """The design of `kind` with `options` (x̂(0) from the context when the design takes one), as a candidate."""
    opts = dict(options)
    ref = KINDS[kind].citation
    if "xhat0" in options_of(KINDS[kind].design) and "xhat0" not in opts:
        opts["xhat0"] = [float(v) for v in ctx.xhat0]
    try:
        d = design_from_config(ctx.system, kind, opts)
    except (PreconditionError, FormError, ShapeError, ModelError) as e:
        return Candidate(kind, "fails", clean_message(e), opts, ref)
    why = f"{tuning}; {_guarantee(d)}" + (f"; {extra}" if extra else "")
    return Candidate(kind, "applies", why, opts, ref, d, runnable)


def _candidate(ctx: Context, kind: str, tuning: Tuning) -> Candidate:
    """A kind's tuning as a candidate: designed when tuned; a rule marking the kind as the choice is kept in `ctx`."""
    ref = KINDS[kind].citation
    if tuning.status != "tuned":
        return Candidate(kind, tuning.status, tuning.why, tuning.options, ref)
    cand = _designed(ctx, kind, tuning.options, tuning.why, runnable=tuning.runnable, extra=tuning.extra)
    if tuning.choice and (ctx.choice is None or tuning.choice_rank > getattr(ctx, "choice_rank", 0)):
        ctx.choice = (kind, tuning.choice_reason or tuning.why)
        ctx.choice_rank = tuning.choice_rank
        ctx.notes.append(tuning.choice)
        ctx.choice_notes[kind] = tuning.choice   # checked against the screening and the run (advise._reconcile_choice)
    return cand


def _from_file(ctx: Context, kind: str, auto: Candidate) -> Candidate:
    """A kind nlobs cannot tune by itself, designed with what the user supplied in the file's ``[observers.NAME]``."""
    name, options = ctx.configs[kind]
    xh = options.get("xhat0")
    if isinstance(xh, (list, tuple)) and ctx.unknown and len(xh) == ctx.model.n_states:  # the guesses go at the end
        options = {**options, "xhat0": [*xh, *(float(ctx.model.params[k]) for k in ctx.unknown)]}
    cand = _designed(ctx, kind, options, f"designed from the file's [observers.{name}] (nlobs cannot tune this kind by "
                     "itself)")
    ref = auto.reference or KINDS[kind].citation
    if not cand.applies:
        return Candidate(kind, "fails", f"the file's [observers.{name}] does not design: {cand.why}", cand.options, ref)
    return Candidate(kind, "applies", cand.why, cand.options, ref, cand.design, cand.runnable)


def _tuned(ctx: Context, kind: str) -> Candidate:
    """Run the kind's precheck and tune within the advisor's symbolic budget; numerical warnings join its evidence."""
    k = KINDS[kind]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            with symbolic_budget(f"advise: {kind}", seconds=min(kind_seconds(), symbolic_seconds())):
                ok, why = k.precheck(ctx) if k.precheck is not None else (True, "")
                cand = _candidate(ctx, kind, k.tune(ctx)) if ok else Candidate(kind, "fails", why, {}, k.citation)
        except SymbolicBudgetError:
            limit = min(kind_seconds(), symbolic_seconds())
            cand = Candidate(kind, "fails", f"not checked within budget (its symbolic work took more than {limit:g} s, the "
                             "advisor's budget per kind; the environment variable NLOBS_KIND_SECONDS raises it)", {},
                             k.citation)
        except (NlobsError, ValueError, TypeError, ArithmeticError, np.linalg.LinAlgError) as e:
            cand = Candidate(kind, "fails", f"the automatic design failed: {type(e).__name__}: {clean_message(e)}", {},
                             k.citation)
    msgs = sorted({str(w.message).splitlines()[0] for w in caught if not issubclass(w.category, DeprecationWarning)})
    if msgs:  # numerical warnings of the design's linear algebra are part of its evidence, not noise on stderr
        cand = Candidate(cand.kind, cand.status, cand.why + "; numerical warning: " + "; ".join(msgs), cand.options,
                         cand.reference, cand.design, cand.runnable)
    return cand


def try_kind(ctx: Context, kind: str) -> Candidate:
    """The candidate for one kind: blocked by an unobservable state or by its time base, tuned, or not tuned."""
    t0 = time.perf_counter()
    k = KINDS[kind]
    time_base = getattr(ctx.system, "time", "continuous")
    if not k.runs_on(time_base):
        cand = Candidate(kind, "fails", f"{k.time_base}-time only (the model is {time_base}-time)", {}, k.citation)
    elif ctx.blockers and kind != "custom":
        cand = Candidate(kind, "fails", "; ".join(ctx.blockers), {}, k.citation)
    elif k.tune is not None:
        cand = _tuned(ctx, kind)
    else:
        opts = options_of(k.design)
        cand = Candidate(kind, "not tuned", f"no automatic tuning is known for this kind; give its options in the model file "
                         f"([observers.NAME] kind = {kind!r} with {', '.join(opts)}) and `nlobs design` uses them",
                         {o: "..." for o in opts}, k.citation)
    if cand.status in ("needs input", "not tuned") and kind in ctx.configs and not ctx.blockers:
        cand = _from_file(ctx, kind, cand)
    return Candidate(cand.kind, cand.status, cand.why, cand.options, cand.reference, cand.design, cand.runnable,
                     time.perf_counter() - t0)
