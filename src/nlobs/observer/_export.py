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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from ..design import ObserverDesign, check_positive
from ..engine import compile_system, rk4_step
from ..errors import PreconditionError
from ._base import AbstractObserver, Observer
from ._convert import as_observer

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

    @property
    def build_command(self) -> str:
        """A command that compiles the example program (run in the export directory)."""
        return f"cc -std=c99 -O2 -o {self.name} {self.source.name} {self.example.name} -lm"

    def __str__(self) -> str:
        lines = [f"C export {self.name!r}: z has {self.n_z} entries, x̂ {self.n_states}, u {self.n_inputs}, y {self.n_outputs}"
                 + (f"; RK4 steps <= {self.max_step:g}" if self.max_step else "; one RK4 step per sample interval")]
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

#ifdef __cplusplus
}} /* extern "C" */
#endif

#endif /* {NAME}_H */
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

#define NCOL (1 + {NAME}_NU + {NAME}_NY)

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


def export_c(observer: AbstractObserver | ObserverDesign, directory: str | os.PathLike[str], *, name: str | None = None,
             max_step: float | None = None) -> CExport:
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
        step per sample interval). Baked into the code as ``NAME_MAX_STEP``.

    Returns
    -------
    CExport
        The paths written and the sizes; ``str()`` shows how to build the example.

    Raises
    ------
    ValueError
        For a `name` that is not a C identifier, a `max_step` that is not positive and finite.
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
    out = Path(directory)
    fns = list(_functions(design, name))
    body = _generate(fns, name, design.method)  # before writing anything: it may refuse
    s = design.system
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
    )
    header = out / f"{name}.h"
    source = out / f"{name}.c"
    example = out / "main.c"
    out.mkdir(parents=True, exist_ok=True)
    header.write_text(_HEADER.format(**fill))
    source.write_text(f"/* {name}.c -- {fill['title']}; generated by nlobs {fill['version']}. Interface: {name}.h */\n"
                      f'#include "{name}.h"\n' + body + _WRAPPER.format(**fill))
    example.write_text(_MAIN.format(**fill))
    return CExport(name, source, header, example, nz, nx, nu, ny, max_step)
