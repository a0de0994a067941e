"""Lane-parallel C for batches: the step's SX instructions applied to W trajectories at once.

CasADi's code generator writes scalar code (one trajectory per call), which compilers cannot
vectorise across trajectories. Here each CasADi work variable becomes an array of W lanes and
each SX instruction a short loop over the lanes, which ``gcc -O3 -march=native`` turns into SIMD
instructions. The batch driver runs blocks of W trajectories in structure-of-arrays layout.
Results agree with the scalar path to round-off (floating-point contraction may differ).
"""

from __future__ import annotations

import ctypes
import math

import casadi as ca
import numpy as np

from ..errors import EngineError
from ._codegen import _ERFINV, _build, bind_batch, built_path, call_batch, signature_of

__all__ = ["simd_supported", "CompiledSimdBatch", "LANES"]

LANES = 8
_KERNEL_VERSION = "fused-lanes-3"  # part of the cache key: bump when _kernel's output changes

_BINARY = {
    ca.OP_ADD: "{a} + {b}", ca.OP_SUB: "{a} - {b}", ca.OP_MUL: "{a} * {b}", ca.OP_DIV: "{a} / {b}",
    ca.OP_POW: "pow({a}, {b})", ca.OP_CONSTPOW: "pow({a}, {b})", ca.OP_ATAN2: "atan2({a}, {b})",
    ca.OP_FMIN: "fmin({a}, {b})", ca.OP_FMAX: "fmax({a}, {b})", ca.OP_FMOD: "fmod({a}, {b})",
    ca.OP_COPYSIGN: "copysign({a}, {b})", ca.OP_HYPOT: "hypot({a}, {b})", ca.OP_REMAINDER: "remainder({a}, {b})",
    ca.OP_PRINTME: "{a}", ca.OP_LIFT: "{a}",
    ca.OP_LT: "({a} < {b})", ca.OP_LE: "({a} <= {b})", ca.OP_EQ: "({a} == {b})", ca.OP_NE: "({a} != {b})",
    ca.OP_AND: "({a} && {b})", ca.OP_OR: "({a} || {b})", ca.OP_IF_ELSE_ZERO: "({a} ? {b} : 0)",
}
_UNARY = {
    ca.OP_ASSIGN: "{a}", ca.OP_NEG: "-{a}", ca.OP_SQ: "{a} * {a}", ca.OP_TWICE: "2 * {a}", ca.OP_INV: "1 / {a}",
    ca.OP_SQRT: "sqrt({a})", ca.OP_EXP: "exp({a})", ca.OP_LOG: "log({a})", ca.OP_SIN: "sin({a})",
    ca.OP_COS: "cos({a})", ca.OP_TAN: "tan({a})", ca.OP_ASIN: "asin({a})", ca.OP_ACOS: "acos({a})",
    ca.OP_ATAN: "atan({a})", ca.OP_SINH: "sinh({a})", ca.OP_COSH: "cosh({a})", ca.OP_TANH: "tanh({a})",
    ca.OP_ASINH: "asinh({a})", ca.OP_ACOSH: "acosh({a})", ca.OP_ATANH: "atanh({a})", ca.OP_FABS: "fabs({a})",
    ca.OP_FLOOR: "floor({a})", ca.OP_CEIL: "ceil({a})", ca.OP_ERF: "erf({a})", ca.OP_EXPM1: "expm1({a})",
    ca.OP_LOG1P: "log1p({a})", ca.OP_NOT: "(!{a})", ca.OP_ERFINV: "nlobs_erfinv({a})",
    ca.OP_SIGN: "(({a}) > 0 ? 1.0 : (({a}) < 0 ? -1.0 : 0.0))",
}


def simd_supported(fn: ca.Function) -> bool:
    """Whether every instruction of `fn` (an SX function) can be written lane-parallel."""
    if not fn.is_a("SXFunction"):
        return False
    known = set(_BINARY) | set(_UNARY) | {ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST}
    return all(fn.instruction_id(k) in known for k in range(fn.n_instructions()))


def _literal(v: float) -> str:
    if math.isnan(v):
        return "NAN"
    if math.isinf(v):
        return "INFINITY" if v > 0 else "-INFINITY"
    return repr(float(v))


def _kernel(fn: ca.Function, W: int) -> str:
    """C for ``void nlobs_step_w(const double **arg, double **res)`` over W lanes ([nz][W] layout).

    One loop over the lanes holds every instruction, each CasADi work variable a scalar local of
    the loop body: the shape of a hand-written structure-of-arrays loop, which the compiler keeps in
    registers and vectorises across the lanes (``#pragma omp simd``-free: ``restrict`` pointers and
    ``GCC ivdep`` tell it the lanes are independent).
    """
    rows = [np.array(fn.sparsity_out(i).row(), dtype=int) for i in range(fn.n_out())]
    head = ["static inline void nlobs_step_w(const double **arg, double **res) {", "  int l;"]
    head += [f"  const double *restrict in{i} = arg[{i}];" for i in range(fn.n_in())]
    head += [f"  double *restrict out{i} = res[{i}];" for i in range(fn.n_out())]
    for i in range(fn.n_out()):  # structural zeros of sparse outputs
        dense = fn.size1_out(i) * fn.size2_out(i)
        if dense != fn.nnz_out(i):
            head.append(f"  for (l = 0; l < {dense * W}; ++l) out{i}[l] = 0;")
    n_w = max(fn.sz_w(), 1)
    body = ["  #pragma GCC ivdep", f"  for (l = 0; l < {W}; ++l) {{",
            "    double " + ", ".join(f"w{j}" for j in range(n_w)) + ";"]
    for k in range(fn.n_instructions()):
        op, ins, outs = fn.instruction_id(k), fn.instruction_input(k), fn.instruction_output(k)
        if op == ca.OP_INPUT:
            body.append(f"    w{outs[0]} = in{ins[0]}[{ins[1] * W} + l];")
        elif op == ca.OP_OUTPUT:
            body.append(f"    out{outs[0]}[{int(rows[outs[0]][outs[1]]) * W} + l] = w{ins[0]};")
        elif op == ca.OP_CONST:
            body.append(f"    w{outs[0]} = {_literal(fn.instruction_constant(k))};")
        elif op in _BINARY:
            body.append(f"    w{outs[0]} = {_BINARY[op].format(a=f'w{ins[0]}', b=f'w{ins[1]}')};")
        elif op in _UNARY:
            body.append(f"    w{outs[0]} = {_UNARY[op].format(a=f'w{ins[0]}')};")
        else:  # pragma: no cover - guarded by simd_supported
            raise EngineError(f"operation {op} has no lane-parallel form")
    body.append("  }")
    return "\n".join(head + body + ["}"])


_DRIVER = r"""
/* blocks of W trajectories; same contract as the scalar batch driver */
long long nlobs_batch(const double* S0, const double* A, long long a_stride, const double* C, long long c_stride,
                      double* Sout, double* Oout, long long n_save, long long n_traj, long long n_steps,
                      long long stride, double bound, long long* status) {
  double buf_s[NS * W], buf_n[NS * W], a[NA * W + 1], c[NC * W + 1], o[NO * W + 1];
  double *s = buf_s, *nxt = buf_n, *tmp;  /* swapped after each step: no copy */
  const double* arg[3];
  double* res[2];
  long long j0, k, isave, next_save, j;
  int i, l, alive[W], n_alive;
  long long bad;
  for (j0 = 0; j0 < n_traj; j0 += W) {
    for (l = 0; l < W; ++l) {
      j = j0 + l < n_traj ? j0 + l : n_traj - 1;  /* padding lanes repeat the last trajectory */
      alive[l] = j0 + l < n_traj;
      for (i = 0; i < NS; ++i) s[i * W + l] = S0[j * NS + i];
      for (i = 0; i < NC; ++i) c[i * W + l] = C[j * c_stride + i];
      if (alive[l]) status[j] = n_steps;
    }
    arg[1] = a; arg[2] = c; res[1] = o;
    isave = 0; next_save = 0;
    for (k = 0; k <= n_steps; ++k) {
      for (l = 0; l < W; ++l) {
        j = j0 + l < n_traj ? j0 + l : n_traj - 1;
        for (i = 0; i < NA; ++i) a[i * W + l] = A[j * a_stride + k * NA + i];
      }
      arg[0] = s; res[0] = nxt;
      nlobs_step_w(arg, res);
      if (k == next_save) {
        for (l = 0; l < W; ++l) {
          if (!alive[l]) continue;
          j = j0 + l;
          for (i = 0; i < NS; ++i) Sout[(j * n_save + isave) * NS + i] = s[i * W + l];
          for (i = 0; i < NO; ++i) Oout[(j * n_save + isave) * NO + i] = o[i * W + l];
        }
        ++isave;
        next_save = next_save + stride < n_steps ? next_save + stride : n_steps;
      }
      if (k == n_steps) break;
      /* any state out of bound or NaN: an integer OR of the compare masks, which the compiler vectorises
         (a floating-point sum could not be reordered, and its chain of dependent additions took a third of the step) */
      bad = 0;
      for (i = 0; i < NS * W; ++i) bad |= fabs(nxt[i]) <= bound ? 0 : -1;
      if (bad) {
        n_alive = 0;
        for (l = 0; l < W; ++l) {
          if (!alive[l]) continue;
          for (i = 0; i < NS; ++i) if (!(fabs(nxt[i * W + l]) <= bound)) { alive[l] = 0; status[j0 + l] = k; break; }
          n_alive += alive[l];
        }
        if (!n_alive) break;
      }
      tmp = s; s = nxt; nxt = tmp;
    }
  }
  return 0;
}
"""


class CompiledSimdBatch:
    """A step ``(s, a, c) -> (s_next, o)`` compiled lane-parallel with a batch driver.

    Same call as :class:`nlobs.engine._codegen.CompiledBatch`.
    """

    def __init__(self, step: ca.Function, lanes: int = LANES, sig: str | None = None):
        if step.n_in() != 3 or step.n_out() != 2 or not simd_supported(step):
            raise EngineError("CompiledSimdBatch needs an SX step(s, a, c) -> (s_next, o) with supported operations")
        self.ns, self.na, self.nc, self.no = step.size1_in(0), step.size1_in(1), step.size1_in(2), step.size1_out(1)
        sizes = {"NS": self.ns, "NA": self.na, "NC": self.nc, "NO": self.no, "W": lanes}

        def code() -> str:
            return ("#include <math.h>\n" + "".join(f"#define {k} {v}\n" for k, v in sizes.items()) + _ERFINV
                    + _kernel(step, lanes) + _DRIVER)

        so = built_path("simd", (sig or signature_of(step)) + f"/{lanes}", _DRIVER + _KERNEL_VERSION)
        self.path = _build(code, "simd", so, n_instr=step.n_instructions())
        self._lib = ctypes.CDLL(str(self.path))
        self._run = bind_batch(self._lib)

    def __call__(self, S0: np.ndarray, A: np.ndarray, a_stride: int, C: np.ndarray, c_stride: int, Sout: np.ndarray,
                 Oout: np.ndarray, n_steps: int, stride: int, bound: float, status: np.ndarray) -> None:
        call_batch(self._run, S0, A, a_stride, C, c_stride, Sout, Oout, n_steps, stride, bound, status)
