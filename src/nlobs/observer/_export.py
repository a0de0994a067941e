"""C export: an observer's discrete step as dependency-free C (CasADi codegen plus a small wrapper).

The exported step is exactly what :meth:`OnlineObserver.update` (and :func:`nlobs.estimate`
with zero-order hold) does between two samples: integrate the flow from the previous sample
time with the previous input and measurement held (classical RK4, in ``n = ceil(dt/max_step)``
equal steps), apply the sample-time update with the new measurement (continuous-discrete
observers), and return the estimate. The equations come from the design's CasADi functions
through :class:`casadi.CodeGenerator`; the generated file includes only ``<math.h>``, allocates
nothing and keeps no global state (every call is re-entrant).
"""

from __future__ import annotations

import importlib.metadata
import keyword
import os
import re
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from ..design import ObserverDesign, check_positive
from ..engine import compile_system, rk4_step
from ..errors import ModelError, PreconditionError
from ._base import AbstractObserver, Observer
from ._convert import as_observer
from ._signals import delays_of

__all__ = ["CExport", "export_c"]

_C_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,39}")
_C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto if inline int long "
    "register restrict return short signed sizeof static struct switch typedef union unsigned void volatile while "
    "main".split())


@dataclass(frozen=True)
class CExport:
    """What :func:`export_c` wrote.

    Attributes
    ----------
    name : str
        The C prefix of every exported symbol (``NAME_init``, ``NAME_step``, ``NAME_NZ``, ...).
    source, header, example : pathlib.Path
        ``NAME.c`` (the observer), ``NAME.h`` (its interface) and ``main.c`` (a CSV filter).
    n_z, n_states, n_inputs, n_outputs : int
        Sizes of the internal state, the estimate, u and y.
    max_step : float or None
        The largest RK4 step between samples baked into the code (None: one step per interval).
    delays : dict of str to float, or None
        The known measurement delay of each output (seconds) of the fusion filter ``NAME_fusion_step``
        (None: no fusion filter was written).
    history : int or None
        The knots the fusion filter's history holds (``NAME_HISTORY``).
    min_interval : float or None
        The smallest row spacing the history was sized for (None: `history` was given directly).
    """

    name: str
    source: Path
    header: Path
    example: Path
    n_z: int
    n_states: int
    n_inputs: int
    n_outputs: int
    max_step: float | None
    delays: dict[str, float] | None = None
    history: int | None = None
    min_interval: float | None = None

    @property
    def build_command(self) -> str:
        """A command that compiles the example program (run in the export directory)."""
        return f"cc -std=c99 -O2 -o {self.name} {self.source.name} {self.example.name} -lm"

    def __str__(self) -> str:
        lines = [f"C export {self.name!r}: z has {self.n_z} entries, x̂ {self.n_states}, u {self.n_inputs}, y {self.n_outputs}"
                 + (f"; RK4 steps <= {self.max_step:g}" if self.max_step else "; one RK4 step per sample interval")]
        if self.delays is not None:
            late = ", ".join(f"{k} {v:g} s" for k, v in self.delays.items() if v > 0) or "none"
            lines.append(f"fusion filter {self.name}_fusion_step (rows stamped at arrival): delays {late}; history of "
                         f"{self.history} knots"
                         + (f" (rows at least {self.min_interval:g} s apart)" if self.min_interval is not None else ""))
        for p in (self.source, self.header, self.example):
            lines.append(f"  {p} ({p.stat().st_size} bytes)")
        lines.append(f"  build the example: cd {self.source.parent} && {self.build_command}")
        return "\n".join(lines)


def _version() -> str:
    try:
        return importlib.metadata.version("nlobs")
    except importlib.metadata.PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "(source tree)"


# Characters allowed in text copied into generated C comments: printable ASCII without `*`, `/`
# (no comment ends or starts), `\\` (no line splices) and `?` (no trigraphs such as ??/). Everything
# else (newlines, control and bidi characters, non-ASCII) becomes `_`. Text reaches C only through
# _c_comment and _c_string, whatever the model file or the Python caller allowed as a name.
_COMMENT_SAFE = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 _-+.,:;=()[]<>'!#%&|^~@$\"{}")
_COMMENT_MAX = 160


def _c_comment(text: Any) -> str:
    """`text` made safe for a C block or line comment (see _COMMENT_SAFE), at most 160 characters."""
    s = "".join(ch if ch in _COMMENT_SAFE else "_" for ch in str(text))
    return s if len(s) <= _COMMENT_MAX else s[: _COMMENT_MAX - 3] + "..."


def _c_string(text: Any) -> str:
    """The body of a C string literal that prints `text` verbatim (fputs, not printf): letters, digits,
    `_` and `,` as they are, every other byte as an octal escape (so no quote, backslash, trigraph or
    newline can end the literal)."""
    out = []
    for b in str(text).encode("utf-8"):
        ch = chr(b)
        out.append(ch if (ch.isascii() and (ch.isalnum() or ch in "_,")) else f"\\{b:03o}")
    return "".join(out)


def _default_name(design: ObserverDesign) -> str:
    raw = f"{design.system.name}_{design.method}"
    name = re.sub(r"_+", "_", re.sub(r"[^A-Za-z0-9_]", "_", raw)).strip("_")  # CasADi refuses "__" in names
    if not name[:1].isalpha():
        name = "obs_" + name
    return name[:40].rstrip("_")


def _check_name(name: str) -> str:
    if (not isinstance(name, str) or not _C_NAME.fullmatch(name) or "__" in name or name in _C_KEYWORDS
            or keyword.iskeyword(name)):
        raise ValueError(f"export_c: `name` must be a C identifier of at most 40 characters (a letter, then letters, "
                         f"digits or single underscores; not a C keyword), got {repr(name)[:60]}")  # fullmatch: "abc\n" is refused
    return name


def _functions(design: ObserverDesign, name: str) -> tuple[ca.Function, ca.Function, ca.Function]:
    """init(xhat0) -> z0; rk4(z, t, h, u, y) -> z(t + h); sample(z, t, u, y, m, y_prev) -> (z+, xhat, y_held)."""
    fns = [design.flow, design.output, design.initial] + ([design.update] if design.update is not None else [])
    Sym = ca.SX if all(f.is_a("SXFunction") for f in fns) else ca.MX
    s = design.system
    nz, nx, nu, ny = design.n_z, s.n_states, s.n_inputs, s.n_outputs
    z, t, h = Sym.sym("z", nz), Sym.sym("t"), Sym.sym("h")
    u, y, m, y_prev = Sym.sym("u", nu), Sym.sym("y", ny), Sym.sym("m", ny), Sym.sym("y_prev", ny)
    x0 = Sym.sym("xhat0", nx)
    init = ca.Function(f"{name}_cg_init", [x0], [design.initial(x0)], ["xhat0"], ["z0"])
    # one RK4 step of the flow with u and y held: the same graph as Observer.step_function(1)
    z_next = rk4_step(lambda tt, zz, _k: design.flow(tt, zz, u, y), t, z, h)
    rk4 = ca.Function(f"{name}_cg_rk4", [z, t, h, u, y], [z_next], ["z", "t", "h", "u", "y"], ["z_next"])
    # missing outputs (m = 0) are replaced by the prediction h(t, x̂(z⁻), u), as OnlineObserver does
    _, hfun = compile_system(s).bind()
    y_hat = hfun(t, design.output(t, z, u, y_prev), u)
    y_used = m * y + (1 - m) * y_hat
    z_plus = design.update(t, z, u, y_used, m) if design.update is not None else z
    xhat = design.output(t, z_plus, u, y_used)
    sample = ca.Function(f"{name}_cg_sample", [z, t, u, y, m, y_prev], [z_plus, xhat, y_used],
                         ["z", "t", "u", "y", "m", "y_prev"], ["z_plus", "xhat", "y_held"])
    return init, rk4, sample


def _fusion_functions(design: ObserverDesign, name: str) -> tuple[ca.Function, ca.Function]:
    """update(z, t, u, y, m) -> z+ (the design's J as it is: the fusion filter fills the missing entries of y itself);
    output(z, t, u, y) -> xhat (H)."""
    fns = [design.output] + ([design.update] if design.update is not None else [])
    Sym = ca.SX if all(f.is_a("SXFunction") for f in fns) else ca.MX
    s = design.system
    z, t = Sym.sym("z", design.n_z), Sym.sym("t")
    u, y, m = Sym.sym("u", s.n_inputs), Sym.sym("y", s.n_outputs), Sym.sym("m", s.n_outputs)
    update = ca.Function(f"{name}_cg_update", [z, t, u, y, m], [design.update(t, z, u, y, m)],
                         ["z", "t", "u", "y", "m"], ["z_plus"])
    output = ca.Function(f"{name}_cg_output", [z, t, u, y], [design.output(t, z, u, y)], ["z", "t", "u", "y"], ["xhat"])
    return update, output


def _generate(fns: list[ca.Function], name: str, method: str) -> str:
    with tempfile.TemporaryDirectory(prefix="nlobs-export-") as tmp:
        gen = ca.CodeGenerator(f"{name}_cg.c", {"with_header": False, "main": False, "with_export": False,
                                                "prefix": f"{name}_cg_", "casadi_real": "double", "casadi_int": "int"})
        for fn in fns:
            gen.add(fn)
        gen.generate(tmp + os.sep)
        code = (Path(tmp) / f"{name}_cg.c").read_text()
    # closed-form equations need only <math.h>; an embedded solver (MHE's IPOPT) would need its library
    others = sorted(set(re.findall(r"#include\s*<([^>]+)>", code)) - {"math.h"})
    if others:
        raise PreconditionError(
            f"export_c: the {method!r} observer cannot be exported as dependency-free C: its equations call code that "
            f"needs {', '.join(f'<{h}>' for h in others)} (an embedded solver, such as the NLP solved by MHE at each "
            "sample). Export an observer whose equations are closed-form (EKF, UKF, Luenberger, output injection, ...)")
    return code


def _doubles(values: Any) -> str:
    return ", ".join(repr(float(v)) for v in np.asarray(values, dtype=float).reshape(-1)) or "0.0"


_HEADER = """\
/* {name}.h -- {title}
 *
 * Generated by nlobs {version} (C through CasADi {casadi}). Dependency-free: the
 * implementation {name}.c needs only <math.h>, allocates nothing and has no global
 * state, so every function is re-entrant.
 *
 *   z  internal state ({nz}):  {z_names}
 *   x  estimate ({nx}):        {x_names}
 *   u  inputs ({nu}):          {u_names}
 *   y  outputs ({ny}):         {y_names}
 *
 * Usage, one call per sample (see main.c):
 *
 *   double z[{NAME}_NZ], xhat[{NAME}_NX], y_held[{NAME}_NY_ALLOC], u_prev[{NAME}_NU_ALLOC];
 *   {name}_init(NULL, z);                       // z0 from the design's default xhat0
 *   {name}_step(z, t0, 0.0, NULL, NULL, u0, y0, z, xhat, y_held);   // first sample: dt = 0
 *   ...                                         // then, for each new sample (t, u, y):
 *   {name}_step(z, t, t - t_prev, u_prev, y_held, u, y, z, xhat, y_held);
 *
 * Semantics (those of nlobs' OnlineObserver.update and of nlobs.estimate with hold="zoh"):
 * from t - dt to t the flow is integrated with u_prev and y_prev held, in
 * n = max(1, ceil(dt / {NAME}_MAX_STEP - 1e-9)) classical RK4 steps of dt/n ({max_step_text});
 * then, at t, the sample-time update uses the new y and u{update_text}; xhat is the estimate
 * at t. A NaN entry of y marks a missing output: it is left out of the update and replaced by
 * the predicted output; y_held receives the measurement to hold until the next sample (y with
 * its missing entries predicted) -- pass it back as y_prev.
 */
#ifndef {NAME}_H
#define {NAME}_H

#ifdef __cplusplus
extern "C" {{
#endif

#define {NAME}_NZ {nz}
#define {NAME}_NX {nx}
#define {NAME}_NU {nu}
#define {NAME}_NY {ny}
/* sizes to declare arrays with (C has no zero-length arrays) */
#define {NAME}_NU_ALLOC {nu_alloc}
#define {NAME}_NY_ALLOC {ny_alloc}
/* largest RK4 step between samples; 0 means one RK4 step per sample interval */
#define {NAME}_MAX_STEP {max_step_c}

/* return codes */
#define {NAME}_OK 0
#define {NAME}_EINPUT 1     /* dt < 0, t or dt not finite, or an infinite entry of y */
#define {NAME}_ENONFINITE 2 /* the new state or the estimate is not finite (the observer diverged) */
#define {NAME}_EINTERNAL 3  /* a generated function failed */

/* The design's default initial estimate xhat0 ({nx} numbers). */
extern const double {name}_xhat0_default[{NAME}_NX];

/* z0 from the initial estimate xhat0 (NULL: {name}_xhat0_default). Returns {NAME}_OK. */
int {name}_init(const double *xhat0, double *z);

/* One sample: see above. y is required; u may be NULL when the model has no inputs;
 * u_prev and y_prev may be NULL on the first sample (dt = 0; zeros). z_next may be z
 * (in place); y_held may be NULL. On an error z_next and xhat are left unchanged. */
int {name}_step(const double *z, double t, double dt,
                const double *u_prev, const double *y_prev,
                const double *u, const double *y,
                double *z_next, double *xhat, double *y_held);
{fusion_decls}
#ifdef __cplusplus
}} /* extern "C" */
#endif

#endif /* {NAME}_H */
"""

_FUSION_HEADER = """
/* ---- Known measurement delays: the fusion filter -------------------------------------------
 *
 * Output j's sample taken at time s reaches the program at s + {name}_delay[j] (seconds):
 *   {delay_text}
 * Feed the rows as they arrive, stamped at arrival (a logger's CSV; see main.c):
 *
 *   {name}_fusion f;                     // caller-allocated: sizeof({name}_fusion) bytes, no malloc
 *   {name}_fusion_init(&f, NULL);        // xhat0: the design's default
 *   for each row (t, u, y):              // y[j] NaN: nothing of output j arrived at t
 *     rc = {name}_fusion_step(&f, t, u, y, xhat);
 *
 * Semantics (those of nlobs.estimate(observer, recording, delay={{...}}), exact re-processing): a
 * number y[j] in the row stamped t is the sample taken at s = t - {name}_delay[j]. The filter
 * keeps a history of knots -- the row times, and the times samples were taken -- with the state
 * after each. A late sample is inserted at the time it was taken, and the filter runs again from
 * the knot just before it: the flow from knot to knot (RK4, u and the held measurement of the
 * knot held; n = max(1, ceil(gap / {NAME}_MAX_STEP - 1e-9)) equal steps per gap; gaps of at most
 * 64 ulp (relative) are not integrated), the update at each knot that has samples, in the order
 * they were taken, then on to t. The input held over a gap, and used by the update at a knot, is
 * that of the row whose hold interval [t_r, t_r+1) contains the knot. A sample taken within 64 ulp
 * (relative) of a knot -- a row, or other samples -- is applied there, with them (t - delay is
 * rounded). Exact: the estimate at t equals the undelayed filter
 * (the same flow and update, as {name}_step applies them, with the rows and the taken times as
 * its sample times) run on the samples that have arrived by t, each applied at the time it was
 * taken. An output with delay 0 is applied at its row, as {name}_step applies it. A row with no
 * sample moves the filter on without an update. Samples taken before the first row are left
 * out (counted in f.early). Missing entries at a knot are left out of the update (mask m = 0);
 * the held measurement y_held is, per output, the last sample in taken order (zero before the
 * first): the continuous-discrete observers of nlobs read y only through the update.
 *
 * The history holds {NAME}_HISTORY knots: every row and taken time within the largest delay
 * ({NAME}_MAX_DELAY s) of the newest row, plus one. {sizing_text}
 * A row that would not fit returns {NAME}_EHISTORY and changes nothing: export again with a
 * smaller min_interval or a larger history.
 */
#define {NAME}_HISTORY {history}
#define {NAME}_MAX_DELAY {max_delay_c}
/* the smallest row spacing the history was sized for (0: the history was given directly) */
#define {NAME}_MIN_INTERVAL {min_interval_c}
#define {NAME}_EHISTORY 4   /* the history is full: rows closer than {NAME}_MIN_INTERVAL */
#define {NAME}_ESTATE 5     /* not initialised, or an earlier step failed: call {name}_fusion_init */

/* The delay of each output (seconds), in the order of y. */
extern const double {name}_delay[{NAME}_NY_ALLOC];

/* One knot of the history: a row time or a time samples were taken. */
typedef struct {{
  double t;                        /* the knot's time */
  double z[{NAME}_NZ];             /* the state at t, after the update with the samples taken at t */
  double u[{NAME}_NU_ALLOC];       /* the input held from t on (the row whose hold interval holds t) */
  double y[{NAME}_NY_ALLOC];       /* the samples taken at t, where m = 1 */
  double m[{NAME}_NY_ALLOC];       /* 1: output j was taken at t */
  double y_held[{NAME}_NY_ALLOC];  /* per output, the last sample taken at or before t */
  int row;                         /* 1: a row time */
  int sampled;                     /* 1: some output was taken at t (an update is applied there) */
}} {name}_knot;

/* The fusion filter's whole state (fixed size; copy it to keep a snapshot). */
typedef struct {{
  {name}_knot knot[{NAME}_HISTORY];  /* storage, in no particular order */
  int order[{NAME}_HISTORY];         /* knot[order[0]], ..., knot[order[n - 1]]: the knots in time order */
  int free_slot[{NAME}_HISTORY];     /* the unused storage */
  int n, n_free;
  double z0[{NAME}_NZ];              /* the state before the first row */
  double t0;                         /* the first row's time */
  long early;                        /* delayed samples taken before t0, left out */
  int status;                        /* {NAME}_OK, or the error that stopped the filter */
  unsigned magic;                    /* set by {name}_fusion_init */
}} {name}_fusion;

/* Start from the initial estimate xhat0 (NULL: {name}_xhat0_default); the first row is the first
 * {name}_fusion_step. Returns {NAME}_OK. */
int {name}_fusion_init({name}_fusion *f, const double *xhat0);

/* One row stamped at arrival: t (increasing), the input u applied from t on (NULL when the model
 * has no inputs), y with NaN where nothing arrived; xhat receives the estimate at t from every
 * sample arrived by t. Errors: {NAME}_EINPUT (t not after the last row, a non-finite t or u, an
 * infinite y; nothing changed), {NAME}_EHISTORY (nothing changed), {NAME}_ENONFINITE or
 * {NAME}_EINTERNAL (the filter diverged or a generated function failed: it stops, and returns
 * {NAME}_ESTATE until {name}_fusion_init), {NAME}_ESTATE. xhat is written only on {NAME}_OK. */
int {name}_fusion_step({name}_fusion *f, double t, const double *u, const double *y, double *xhat);
"""

_WRAPPER = """
/* ---- nlobs wrapper: the sample-to-sample step (see {name}.h) ------------------------- */

#define {NAME}_SZ_ARG {sz_arg}
#define {NAME}_SZ_RES {sz_res}
#define {NAME}_SZ_IW {sz_iw}
#define {NAME}_SZ_W {sz_w}

const double {name}_xhat0_default[{NAME}_NX] = {{{xhat0}}};

int {name}_init(const double *xhat0, double *z) {{
  const double *arg[{NAME}_SZ_ARG];
  double *res[{NAME}_SZ_RES];
  int iw[{NAME}_SZ_IW];
  double w[{NAME}_SZ_W];
  arg[0] = xhat0 ? xhat0 : {name}_xhat0_default;
  res[0] = z;
  return {name}_cg_init(arg, res, iw, w, 0) ? {NAME}_EINTERNAL : {NAME}_OK;
}}

int {name}_step(const double *z, double t, double dt,
                const double *u_prev, const double *y_prev,
                const double *u, const double *y,
                double *z_next, double *xhat, double *y_held) {{
  static const double zeros[{NAME}_NY_ALLOC > {NAME}_NU_ALLOC ? {NAME}_NY_ALLOC : {NAME}_NU_ALLOC] = {{0}};
  const double *arg[{NAME}_SZ_ARG];
  double *res[{NAME}_SZ_RES];
  int iw[{NAME}_SZ_IW];
  double w[{NAME}_SZ_W];
  double za[{NAME}_NZ], zb[{NAME}_NZ], x_new[{NAME}_NX];
  double y_clean[{NAME}_NY_ALLOC], mask[{NAME}_NY_ALLOC], y_new[{NAME}_NY_ALLOC];
  double h, t_prev;
  long n, k;
  int i;

  if (!(dt >= 0.0) || !(t - t == 0.0) || !(dt - dt == 0.0)) return {NAME}_EINPUT; /* NaN fails too */
  if (!u_prev) u_prev = zeros;
  if (!y_prev) y_prev = zeros;
  if (!u) u = zeros;
  for (i = 0; i < {NAME}_NY; ++i) {{
    if (y[i] != y[i]) {{ mask[i] = 0.0; y_clean[i] = 0.0; }}           /* NaN: a missing output */
    else if (y[i] - y[i] != 0.0) return {NAME}_EINPUT;                 /* +-inf */
    else {{ mask[i] = 1.0; y_clean[i] = y[i]; }}
  }}
  for (i = 0; i < {NAME}_NZ; ++i) za[i] = z[i];

  if (dt > 0.0) {{
    n = 1;
    if ({NAME}_MAX_STEP > 0.0) {{
      double q = ceil(dt / {NAME}_MAX_STEP - 1e-9);
      if (!(q < 1e9)) return {NAME}_EINPUT;
      if (q > 1.0) n = (long) q;
    }}
    h = dt / (double) n;
    t_prev = t - dt;
    for (k = 0; k < n; ++k) {{
      double tk = t_prev + (double) k * h;  /* as Observer.step_function: t + i*h */
      arg[0] = za; arg[1] = &tk; arg[2] = &h; arg[3] = u_prev; arg[4] = y_prev;
      res[0] = zb;
      if ({name}_cg_rk4(arg, res, iw, w, 0)) return {NAME}_EINTERNAL;
      for (i = 0; i < {NAME}_NZ; ++i) za[i] = zb[i];
    }}
  }}

  arg[0] = za; arg[1] = &t; arg[2] = u; arg[3] = y_clean; arg[4] = mask; arg[5] = y_prev;
  res[0] = zb; res[1] = x_new; res[2] = y_new;
  if ({name}_cg_sample(arg, res, iw, w, 0)) return {NAME}_EINTERNAL;
  for (i = 0; i < {NAME}_NZ; ++i) if (zb[i] - zb[i] != 0.0) return {NAME}_ENONFINITE;
  for (i = 0; i < {NAME}_NX; ++i) if (x_new[i] - x_new[i] != 0.0) return {NAME}_ENONFINITE;
  for (i = 0; i < {NAME}_NZ; ++i) z_next[i] = zb[i];
  for (i = 0; i < {NAME}_NX; ++i) xhat[i] = x_new[i];
  if (y_held) for (i = 0; i < {NAME}_NY; ++i) y_held[i] = y_new[i];
  return {NAME}_OK;
}}
"""

_FUSION_WRAPPER = """
/* ---- nlobs wrapper: the fusion filter with known measurement delays (see {name}.h) ------- */

#define {NAME}_TOL(s) (1.4210854715202004e-14 * (fabs(s) > 1.0 ? fabs(s) : 1.0))  /* nlobs' time tolerance: 64 ulp */
#define {NAME}_MAGIC 0x6e6c6f62u
#define {NAME}_KNOT(f, i) ((f)->knot[(f)->order[i]])

const double {name}_delay[{NAME}_NY_ALLOC] = {{{delays_c}}};
/* the outputs by decreasing delay, then by index: the samples of a row in the order they were taken */
static const int {name}_taken_order[{NAME}_NY_ALLOC] = {{{taken_order_c}}};

int {name}_fusion_init({name}_fusion *f, const double *xhat0) {{
  int i, rc;
  if (!f) return {NAME}_EINPUT;
  rc = {name}_init(xhat0, f->z0);
  for (i = 0; i < {NAME}_HISTORY; ++i) f->free_slot[i] = {NAME}_HISTORY - 1 - i;
  f->n = 0;
  f->n_free = {NAME}_HISTORY;
  f->t0 = 0.0;
  f->early = 0;
  f->status = rc;
  f->magic = {NAME}_MAGIC;
  return rc;
}}

/* the flow from ta to tb with u and y held, in place on z (as {name}_step integrates a sample interval) */
static int {name}_flow(double *z, double ta, double tb, const double *u, const double *y) {{
  const double *arg[{NAME}_SZ_ARG];
  double *res[{NAME}_SZ_RES];
  int iw[{NAME}_SZ_IW];
  double w[{NAME}_SZ_W];
  double zb[{NAME}_NZ], h, dt = tb - ta;
  long n = 1, k;
  int i;
  if (!(dt > {NAME}_TOL(tb))) return {NAME}_OK;
  if ({NAME}_MAX_STEP > 0.0) {{
    double q = ceil(dt / {NAME}_MAX_STEP - 1e-9);
    if (!(q < 1e9)) return {NAME}_EINPUT;
    if (q > 1.0) n = (long) q;
  }}
  h = dt / (double) n;
  for (k = 0; k < n; ++k) {{
    double tk = ta + (double) k * h;
    arg[0] = z; arg[1] = &tk; arg[2] = &h; arg[3] = u; arg[4] = y;
    res[0] = zb;
    if ({name}_cg_rk4(arg, res, iw, w, 0)) return {NAME}_EINTERNAL;
    for (i = 0; i < {NAME}_NZ; ++i) z[i] = zb[i];
  }}
  return {NAME}_OK;
}}

int {name}_fusion_step({name}_fusion *f, double t, const double *u, const double *y, double *xhat) {{
  static const double zeros[{NAME}_NY_ALLOC > {NAME}_NU_ALLOC ? {NAME}_NY_ALLOC : {NAME}_NU_ALLOC] = {{0}};
  const double *arg[{NAME}_SZ_ARG];
  double *res[{NAME}_SZ_RES];
  int iw[{NAME}_SZ_IW];
  double w[{NAME}_SZ_W];
  double x_new[{NAME}_NX], y_fill[{NAME}_NY_ALLOC], zb[{NAME}_NZ], s, cut;
  int i, j, jj, c, pos, first, need, ndrop, slot, target, rc = {NAME}_OK;
  {name}_knot *k;

  if (!f || f->magic != {NAME}_MAGIC || f->status != {NAME}_OK) return {NAME}_ESTATE;
  if (!y) return {NAME}_EINPUT;
  if (!u) u = zeros;
  if (!(t - t == 0.0)) return {NAME}_EINPUT;                            /* NaN or inf */
  for (i = 0; i < {NAME}_NU; ++i) if (!(u[i] - u[i] == 0.0)) return {NAME}_EINPUT;
  for (j = 0; j < {NAME}_NY; ++j) if (y[j] == y[j] && y[j] - y[j] != 0.0) return {NAME}_EINPUT;
  if (f->n > 0) {{
    double t_last = {NAME}_KNOT(f, f->n - 1).t;
    if (!(t > t_last)) return {NAME}_EINPUT;
    if ({NAME}_MAX_STEP > 0.0 && !((t - t_last) / {NAME}_MAX_STEP < 1e9)) return {NAME}_EINPUT;
  }}

  /* no sample of this row or a later one is taken before t - MAX_DELAY: the knots before it go,
     but the last of them (the state a replay starts from) */
  ndrop = 0;
  if (f->n > 0) {{
    cut = t - {NAME}_MAX_DELAY;
    cut -= {NAME}_TOL(cut);
    while (ndrop + 1 < f->n && {NAME}_KNOT(f, ndrop + 1).t < cut) ++ndrop;
  }}
  need = f->n - ndrop + 1;                                               /* the row's knot */
  for (j = 0; j < {NAME}_NY; ++j) if (y[j] == y[j] && {name}_delay[j] > 0.0) ++need;   /* a knot per late sample */
  if (need > {NAME}_HISTORY) return {NAME}_EHISTORY;

  for (i = 0; i < ndrop; ++i) f->free_slot[f->n_free++] = f->order[i];
  for (i = ndrop; i < f->n; ++i) f->order[i - ndrop] = f->order[i];
  f->n -= ndrop;
  if (f->n == 0) f->t0 = t;

  /* the row's knot */
  slot = f->free_slot[--f->n_free];
  k = &f->knot[slot];
  k->t = t;
  k->row = 1;
  k->sampled = 0;
  for (i = 0; i < {NAME}_NU; ++i) k->u[i] = u[i];
  for (j = 0; j < {NAME}_NY; ++j) {{ k->y[j] = 0.0; k->m[j] = 0.0; }}
  f->order[f->n++] = slot;
  first = f->n - 1;

  /* the row's samples, each at the time it was taken */
  for (jj = 0; jj < {NAME}_NY; ++jj) {{
    j = {name}_taken_order[jj];
    if (!(y[j] == y[j])) continue;                                       /* nothing arrived */
    s = t - {name}_delay[j];
    if (!(s >= f->t0 - {NAME}_TOL(f->t0))) {{ ++f->early; continue; }}   /* taken before the first row */
    pos = f->n;                                                          /* the first knot at or after s */
    while (pos > 0 && {NAME}_KNOT(f, pos - 1).t >= s) --pos;
    /* a knot within the tolerance of s (a row, or other samples' time): the nearer one either side */
    target = -1;
    if (pos < f->n && {NAME}_KNOT(f, pos).t - s <= {NAME}_TOL(s)) target = pos;
    if (pos > 0 && s - {NAME}_KNOT(f, pos - 1).t <= {NAME}_TOL(s)
        && (target < 0 || s - {NAME}_KNOT(f, pos - 1).t < {NAME}_KNOT(f, pos).t - s)) target = pos - 1;
    if (target < 0 && pos == 0) target = 0;       /* before the first row by rounding only: applied there */
    if (target < 0) {{                                                   /* a knot of its own */
      slot = f->free_slot[--f->n_free];
      k = &f->knot[slot];
      k->t = s;
      k->row = 0;
      k->sampled = 0;
      for (i = f->n; i > pos; --i) f->order[i] = f->order[i - 1];
      f->order[pos] = slot;
      ++f->n;
      if (first >= pos) ++first;
      /* the input of the row whose hold interval contains s: the previous knot's (no row is within the
         tolerance after s, and every row since the cut is a knot) */
      for (i = 0; i < {NAME}_NU; ++i) k->u[i] = {NAME}_KNOT(f, pos - 1).u[i];
      for (c = 0; c < {NAME}_NY; ++c) {{ k->y[c] = 0.0; k->m[c] = 0.0; }}
      target = pos;
    }}
    k = &{NAME}_KNOT(f, target);
    k->y[j] = y[j];
    k->m[j] = 1.0;
    k->sampled = 1;
    if (target < first) first = target;
  }}

  /* run again from the knot before the earliest change: flow, update where samples were taken */
  for (i = first; i < f->n; ++i) {{
    const double *zp, *up, *yp;
    double tp;
    k = &{NAME}_KNOT(f, i);
    if (i == 0) {{ tp = f->t0; zp = f->z0; up = k->u; yp = zeros; }}    /* only before any knot was dropped */
    else {{
      const {name}_knot *prev = &{NAME}_KNOT(f, i - 1);
      tp = prev->t; zp = prev->z; up = prev->u; yp = prev->y_held;
    }}
    for (c = 0; c < {NAME}_NZ; ++c) zb[c] = zp[c];
    rc = {name}_flow(zb, tp, k->t, up, yp);
    if (rc != {NAME}_OK) goto failed;
    for (c = 0; c < {NAME}_NY; ++c) y_fill[c] = k->m[c] > 0.0 ? k->y[c] : yp[c];
    if (k->sampled) {{
      arg[0] = zb; arg[1] = &k->t; arg[2] = k->u; arg[3] = y_fill; arg[4] = k->m;
      res[0] = k->z;
      if ({name}_cg_update(arg, res, iw, w, 0)) {{ rc = {NAME}_EINTERNAL; goto failed; }}
    }} else {{
      for (c = 0; c < {NAME}_NZ; ++c) k->z[c] = zb[c];
    }}
    for (c = 0; c < {NAME}_NY; ++c) k->y_held[c] = y_fill[c];
    for (c = 0; c < {NAME}_NZ; ++c) if (k->z[c] - k->z[c] != 0.0) {{ rc = {NAME}_ENONFINITE; goto failed; }}
  }}

  /* the estimate at t */
  k = &{NAME}_KNOT(f, f->n - 1);
  arg[0] = k->z; arg[1] = &k->t; arg[2] = k->u; arg[3] = k->y_held;
  res[0] = x_new;
  if ({name}_cg_output(arg, res, iw, w, 0)) {{ rc = {NAME}_EINTERNAL; goto failed; }}
  for (i = 0; i < {NAME}_NX; ++i) if (x_new[i] - x_new[i] != 0.0) {{ rc = {NAME}_ENONFINITE; goto failed; }}
  if (xhat) for (i = 0; i < {NAME}_NX; ++i) xhat[i] = x_new[i];
  return {NAME}_OK;

failed:
  f->status = rc;
  return rc;
}}
"""

_CSV_PARSE = """#define NCOL (1 + {NAME}_NU + {NAME}_NY)

/* split a line at commas into v[0..NCOL-1]; empty or unparsable y fields become NaN */
static int parse(char *line, double *v) {{
  char *p = line, *end;
  int j;
  for (j = 0; j < NCOL; ++j) {{
    while (*p == ' ' || *p == '\\t') ++p;
    if (*p == ',' || *p == '\\n' || *p == '\\r' || *p == '\\0') {{
      if (j <= {NAME}_NU) return -1;   /* t and u may not be missing */
      v[j] = NAN;
    }} else {{
      v[j] = strtod(p, &end);
      if (end == p) return -1;
      p = end;
    }}
    while (*p == ' ' || *p == '\\t') ++p;
    if (j < NCOL - 1) {{
      if (*p != ',') return -1;
      ++p;
    }}
  }}
  return 0;
}}
"""

_MAIN = """\
/* main.c -- example: run the observer {name} on a CSV read from stdin.
 *
 * Input: one sample per line, "t,u1..u{nu},y1..y{ny}" in this order:
 *   t,{in_cols}
 * (a first line that does not start with a number is a header and is skipped; an empty
 * y field or "nan" marks a missing output). Output: "t,xhat..." per sample, on stdout.
 * Optional arguments: the initial estimate xhat0 ({nx} numbers; default: the design's).
 *
 * Build and run:  cc -std=c99 -O2 -o {name} {name}.c main.c -lm
 *                 ./{name} < data.csv > estimates.csv
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include "{name}.h"

""" + _CSV_PARSE + """
int main(int argc, char **argv) {{
  static char line[1 << 16];
  double v[NCOL], z[{NAME}_NZ], xhat[{NAME}_NX], xhat0[{NAME}_NX];
  double u_prev[{NAME}_NU_ALLOC], y_held[{NAME}_NY_ALLOC];
  double t_prev = 0.0;
  long lineno = 0, samples = 0;
  int i, rc;

  if (argc != 1 && argc != 1 + {NAME}_NX) {{
    fprintf(stderr, "usage: %s [xhat0 ({nx} numbers)] < data.csv\\n", argv[0]);
    return 2;
  }}
  for (i = 0; i < {NAME}_NX; ++i) xhat0[i] = argc > 1 ? atof(argv[1 + i]) : {name}_xhat0_default[i];
  {name}_init(xhat0, z);
  for (i = 0; i < {NAME}_NU_ALLOC; ++i) u_prev[i] = 0.0;
  for (i = 0; i < {NAME}_NY_ALLOC; ++i) y_held[i] = 0.0;
  fputs("t,{out_cols}\\n", stdout);
  while (fgets(line, sizeof line, stdin)) {{
    ++lineno;
    if (strspn(line, " \\t\\r\\n") == strlen(line)) continue;
    if (parse(line, v) != 0) {{
      if (samples == 0 && lineno == 1) continue;  /* a header */
      fprintf(stderr, "line %ld: expected %d comma-separated numbers (t, u, y)\\n", lineno, NCOL);
      return 1;
    }}
    rc = {name}_step(z, v[0], samples ? v[0] - t_prev : 0.0, u_prev, y_held,
                     v + 1, v + 1 + {NAME}_NU, z, xhat, y_held);
    if (rc != {NAME}_OK) {{
      fprintf(stderr, "line %ld (t = %g): %s\\n", lineno, v[0],
              rc == {NAME}_EINPUT ? "bad sample (time went backwards or a value is infinite)"
                                  : "the observer diverged (non-finite state)");
      return 1;
    }}
    printf("%.17g", v[0]);
    for (i = 0; i < {NAME}_NX; ++i) printf(",%.17g", xhat[i]);
    printf("\\n");
    for (i = 0; i < {NAME}_NU; ++i) u_prev[i] = v[1 + i];
    t_prev = v[0];
    ++samples;
  }}
  return 0;
}}
"""


_MAIN_FUSION = """\
/* main.c -- example: run the observer {name} on a CSV stamped at arrival, read from stdin.
 *
 * Input: one row per line, "t,u1..u{nu},y1..y{ny}" in this order:
 *   t,{in_cols}
 * stamped when the values arrived: a delayed output's value in the row stamped t was taken
 * at t - delay ({delay_text}). An empty y field or "nan": nothing of that output arrived at t.
 * (A first line that does not start with a number is a header and is skipped.)
 * Output: "t,xhat..." per row, on stdout: the estimate at t from every sample arrived by t
 * (see {name}_fusion_step in {name}.h). Optional arguments: the initial estimate xhat0 ({nx}
 * numbers; default: the design's).
 *
 * Build and run:  cc -std=c99 -O2 -o {name} {name}.c main.c -lm
 *                 ./{name} < data.csv > estimates.csv
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include "{name}.h"

""" + _CSV_PARSE + """
static const char *why(int rc) {{
  switch (rc) {{
    case {NAME}_EINPUT: return "bad row (time did not increase, or a value is infinite)";
    case {NAME}_EHISTORY: return "the history is full: rows closer together than the export was sized for "
                                 "(export again with a smaller min_interval or a larger history)";
    case {NAME}_ENONFINITE: return "the observer diverged (non-finite state)";
    default: return "internal error";
  }}
}}

int main(int argc, char **argv) {{
  static char line[1 << 16];
  static {name}_fusion f;   /* large: not on the stack */
  double v[NCOL], xhat[{NAME}_NX], xhat0[{NAME}_NX];
  long lineno = 0, rows = 0;
  int i, rc;

  if (argc != 1 && argc != 1 + {NAME}_NX) {{
    fprintf(stderr, "usage: %s [xhat0 ({nx} numbers)] < data.csv\\n", argv[0]);
    return 2;
  }}
  for (i = 0; i < {NAME}_NX; ++i) xhat0[i] = argc > 1 ? atof(argv[1 + i]) : {name}_xhat0_default[i];
  {name}_fusion_init(&f, xhat0);
  fputs("t,{out_cols}\\n", stdout);
  while (fgets(line, sizeof line, stdin)) {{
    ++lineno;
    if (strspn(line, " \\t\\r\\n") == strlen(line)) continue;
    if (parse(line, v) != 0) {{
      if (rows == 0 && lineno == 1) continue;  /* a header */
      fprintf(stderr, "line %ld: expected %d comma-separated numbers (t, u, y)\\n", lineno, NCOL);
      return 1;
    }}
    rc = {name}_fusion_step(&f, v[0], v + 1, v + 1 + {NAME}_NU, xhat);
    if (rc != {NAME}_OK) {{
      fprintf(stderr, "line %ld (t = %g): %s\\n", lineno, v[0], why(rc));
      return 1;
    }}
    printf("%.17g", v[0]);
    for (i = 0; i < {NAME}_NX; ++i) printf(",%.17g", xhat[i]);
    printf("\\n");
    ++rows;
  }}
  if (f.early) fprintf(stderr, "note: %ld delayed sample(s) taken before the first row were left out\\n", f.early);
  return 0;
}}
"""


def _shown_name(text: Any) -> str:
    return repr(_c_comment(text))


def _history_size(d: np.ndarray, min_interval: Any, history: Any) -> tuple[int, float | None]:
    """The knots the fusion filter must hold, and the row spacing it was sized for.

    At a row t the history keeps the knots taken at or after t - max(d) and one before; with rows at least h apart,
    those are at most R = floor(max(d)/h) + 1 rows and, per distinct positive delay, at most R taken times; the row
    then adds its own knot and one per late sample. R takes one more as a margin."""
    late = d[d > 0]
    per_row = 1 + late.size                # the row's knot, and a knot per late sample
    if history is not None:
        if isinstance(history, bool) or not isinstance(history, (int, np.integer)) or history < per_row + 1:
            raise ValueError(f"export_c: `history` must be a whole number of knots >= {per_row + 1} (a kept knot, the row's "
                             f"and one per delayed output), got {history!r}")
        if int(history) > 10**6:
            raise ValueError(f"export_c: `history` = {history} knots is more than 10^6; give a smaller one")
        return int(history), None
    if not late.size:
        return per_row + 2, None
    if min_interval is None:
        raise ValueError("export_c: with measurement `delays`, give `min_interval` (the smallest spacing of the rows the "
                         "program will be fed, in seconds) to size the history buffer, or `history` (the number of knots)")
    h = check_positive(min_interval, "min_interval", "export_c")
    rows = int(np.floor(late.max() / h + 1e-9)) + 2
    size = rows * (1 + np.unique(late).size) + per_row + 1
    if size > 10**6:
        raise ValueError(f"export_c: a delay of {late.max():g} s with rows {h:g} s apart needs a history of {size} knots "
                         "(more than 10^6); give a larger `min_interval`")
    return size, h


def _fusion_setup(design: ObserverDesign, delays: Any, min_interval: Any, history: Any) -> tuple[Any, int, Any]:
    """The checked delays of each output, the history's size and the smallest row interval (None, 0, None without
    delays)."""
    s = design.system
    if delays is None:
        if min_interval is not None or history is not None:
            raise ValueError("export_c: `min_interval` and `history` size the history of the fusion filter, which is "
                             "written only with measurement `delays`; give `delays` too, or leave them out")
        return None, 0, None
    d = delays_of(delays, list(s.outputs), "export_c", "delays")
    if s.is_discrete:
        raise ModelError(f"export_c: measurement delays on the discrete-time model {_shown_name(s.name)}: the fusion "
                         "filter re-runs a flow between knots, which a map does not have; export without `delays`")
    if not design.sampled:
        raise ModelError(f"export_c: the {design.method!r} observer takes the output continuously; measurement delays "
                         "are handled by the continuous-discrete observers (a flow between samples and an update at "
                         "each: ekf, ukf, srekf, srukf, iekf, ...)")
    n_hist, min_interval = _history_size(d, min_interval, history)
    return d, n_hist, min_interval


def export_c(observer: AbstractObserver | ObserverDesign, directory: str | os.PathLike[str], *, name: str | None = None,
             max_step: float | None = None, delays: Mapping[str, float] | None = None, min_interval: float | None = None,
             history: int | None = None) -> CExport:
    r"""Write an observer's sample-to-sample step as dependency-free C: ``NAME.c``, ``NAME.h``, ``main.c``.

    The exported ``NAME_step(z, t, dt, u_prev, y_prev, u, y) -> (z_next, xhat)`` does what
    :meth:`OnlineObserver.update` does (and :func:`nlobs.estimate` with ``hold="zoh"``):

    .. math::

        z^- = \Phi_{RK4}^{n}(z;\ t - \Delta t \to t;\ u_{prev}, y_{prev}), \qquad
        z^+ = J(t, z^-, u, y, m), \qquad \hat x = H(t, z^+, u, y),

    with :math:`n = \max(1, \lceil \Delta t / \text{max\_step} \rceil)` classical RK4 steps
    of the flow F (u and y held), J the sample-time update of a continuous-discrete observer
    (the identity for a continuous one) and m the mask of measured outputs (NaN in y marks a
    missing output). An observer of a discrete-time model has no flow (F = 0): its step is the map's
    predict-from-the-last-sample and correct, J. ``NAME_init(xhat0, z)`` gives the initial internal state. The equations
    are generated by :class:`casadi.CodeGenerator` from the design's CasADi functions; the C
    file includes only ``<math.h>``, never allocates and keeps no global state. ``main.c``
    is an example program that reads ``t, u..., y...`` lines from stdin and prints
    ``t, xhat...``.

    With `delays` (known measurement delays, ``{output: seconds}``) the C file also holds a fusion
    filter for rows stamped at *arrival*, with the semantics of ``nlobs.estimate(..., delay=delays)``:
    ``NAME_fusion_init(&f, xhat0)``, then ``NAME_fusion_step(&f, t, u, y, xhat)`` per row (NaN in y:
    nothing of that output arrived at t). A number y_j in the row stamped t was taken at
    :math:`t - d_j`; the filter keeps a fixed-size, caller-allocated history (``NAME_fusion``) of
    the knots -- the row times and the times samples were taken -- with the state after each, puts a
    late sample at the time it was taken and runs again from the knot before it. The estimate at t
    is exactly the undelayed filter on the samples that have arrived by t, each applied when it was
    taken (taken times between rows are knots of their own: the flow to them, the update there with
    the input of the row whose hold interval contains them, then on). Outputs of delay 0 are applied
    at their row, as ``NAME_step`` does. The history holds ``NAME_HISTORY`` knots, sized from
    `min_interval`; a row that would not fit returns ``NAME_EHISTORY`` and changes nothing. The example
    ``main.c`` then runs the fusion filter on a CSV stamped at arrival (the CSV that
    :meth:`nlobs.Run.to_csv` writes for a delayed run).

    Parameters
    ----------
    observer : Observer or ObserverDesign
        The observer to export (its design's CasADi equations are used).
    directory : path
        Where to write the three files (created if needed; existing files are replaced).
    name : str, optional
        The C prefix of every symbol and the file name (default: ``MODEL_METHOD``, e.g.
        ``pendulum_ekf``). A C identifier of at most 40 characters.
    max_step : float, optional
        Largest RK4 step between samples, as in :func:`nlobs.estimate` (default: one RK4
        step per sample interval). Baked into the code as ``NAME_MAX_STEP``. With `delays`, the RK4
        steps are those of each gap between knots, as :func:`nlobs.estimate` takes them when
        `max_step` sets them (there its rule h·ρ <= 1 on the flow's rate may shorten them further).
    delays : mapping of output name to seconds, optional
        Known measurement delays (outputs not named: 0): writes the fusion filter described above. A
        model file's ``[simulation] delay`` is the same mapping. Needs a continuous-discrete observer
        (EKF, UKF, their square-root forms, IEKF, ...) of a continuous-time model.
    min_interval : float, optional
        With delays: the smallest spacing of the rows the program will be fed (seconds). Sizes the
        history: ``NAME_HISTORY = (floor(max delay / min_interval) + 2) * (1 + distinct positive
        delays) + 2 + delayed outputs``.
    history : int, optional
        With delays: the number of knots the history holds, given directly (instead of `min_interval`).

    Returns
    -------
    CExport
        The paths written and the sizes; ``str()`` shows how to build the example.

    Raises
    ------
    ValueError
        For a `name` that is not a C identifier, a `max_step` that is not positive and finite; for
        `delays` that name no output or are not finite and >= 0, and for delays without
        `min_interval` or `history`.
    ModelError
        For `delays` on an observer that takes the output continuously, or on a discrete-time model.
    TypeError
        For an observer whose equations are not CasADi functions (not built from a design).
    PreconditionError
        For an observer whose equations embed a solver that needs a library (MHE's IPOPT).

    Examples
    --------
    >>> import tempfile, nlobs
    >>> vdp = nlobs.System(states=["x1", "x2"], f=["x2", "(1 - x1**2)*x2 - x1"], outputs=["y"], h=["x1"], name="vdp")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     exp = export_c(nlobs.design_ekf(vdp, Q=0.01 * np.eye(2), R=[[1e-4]]), folder, max_step=1e-3)
    ...     sorted(p.name for p in Path(folder).iterdir())
    ['main.c', 'vdp_ekf.c', 'vdp_ekf.h']
    >>> exp.name, exp.n_z
    ('vdp_ekf', 6)
    """
    obs = as_observer(observer)
    if not isinstance(obs, Observer):
        raise TypeError(f"export_c: needs an Observer built from an ObserverDesign (CasADi equations), "
                        f"got {type(obs).__name__}; pass the design returned by a design_* function")
    design = obs.design
    if design.update is not None and isinstance(design.update, ca.Callback):
        raise PreconditionError(
            f"export_c: the {design.method!r} observer cannot be exported as dependency-free C: its update runs a numerical "
            "solver from Python at each sample (the NLP solved by MHE). Export an observer whose equations are closed-form "
            "(EKF, UKF, Luenberger, output injection, ...)")
    name = _check_name(_default_name(design) if name is None else name)
    if max_step is not None:
        max_step = check_positive(max_step, "max_step", "export_c")
    s = design.system
    fusion = delays is not None
    d, n_hist, min_interval = _fusion_setup(design, delays, min_interval, history)
    out = Path(directory)
    fns = list(_functions(design, name)) + (list(_fusion_functions(design, name)) if fusion else [])
    body = _generate(fns, name, design.method)  # before writing anything: it may refuse
    nz, nx, nu, ny = design.n_z, s.n_states, s.n_inputs, s.n_outputs
    NAME = name.upper()
    fill = dict(
        name=name, NAME=NAME, nz=nz, nx=nx, nu=nu, ny=ny, nu_alloc=max(nu, 1), ny_alloc=max(ny, 1),
        version=_c_comment(_version()), casadi=_c_comment(ca.__version__),
        title=_c_comment(f"{design.method} observer for the model '{s.name}' "
                         f"({'continuous-discrete' if design.sampled else 'continuous'})"),
        z_names=_c_comment(", ".join(design.z_names)), x_names=_c_comment(", ".join(s.states)),
        u_names=_c_comment(", ".join(s.inputs) or "(none)"), y_names=_c_comment(", ".join(s.outputs)),
        max_step_c=repr(max_step) if max_step else "0.0",
        max_step_text=f"max_step = {max_step:g}" if max_step else "max_step = 0: n = 1",
        update_text=" (the continuous-discrete update)" if design.sampled else " (none: a continuous observer)",
        sz_arg=max(max(f.sz_arg() for f in fns), 1), sz_res=max(max(f.sz_res() for f in fns), 1),
        sz_iw=max(max(f.sz_iw() for f in fns), 1), sz_w=max(max(f.sz_w() for f in fns), 1),
        xhat0=_doubles(design.xhat0),
        in_cols=_c_comment(",".join([*s.inputs, *s.outputs])), out_cols=_c_string(",".join(f"xhat_{v}" for v in s.states)),
        fusion_decls="",
    )
    if fusion:
        late = [(o, float(v)) for o, v in zip(s.outputs, d) if v > 0]
        fill.update(
            delay_text=_c_comment(", ".join(f"{o} {v!r} s" for o, v in late) or "none (every output at its row)"),
            history=n_hist, max_delay_c=repr(float(d.max())), min_interval_c=repr(min_interval) if min_interval else "0.0",
            sizing_text=(f"Sized for rows at least {min_interval!r} s apart." if min_interval else "Given directly."),
            delays_c=_doubles(d), taken_order_c=", ".join(str(j) for j in sorted(range(ny), key=lambda j: (-d[j], j))) or "0",
        )
        fill["fusion_decls"] = _FUSION_HEADER.format(**fill)
    header = out / f"{name}.h"
    source = out / f"{name}.c"
    example = out / "main.c"
    out.mkdir(parents=True, exist_ok=True)
    header.write_text(_HEADER.format(**fill))
    source.write_text(f"/* {name}.c -- {fill['title']}; generated by nlobs {fill['version']}. Interface: {name}.h */\n"
                      f'#include "{name}.h"\n' + body + _WRAPPER.format(**fill)
                      + (_FUSION_WRAPPER.format(**fill) if fusion else ""))
    example.write_text((_MAIN_FUSION if fusion else _MAIN).format(**fill))
    return CExport(name, source, header, example, nz, nx, nu, ny, max_step,
                   delays={o: float(v) for o, v in zip(s.outputs, d)} if fusion else None,
                   history=n_hist if fusion else None, min_interval=min_interval if fusion else None)
