"""A recursion s_{k+1} = step(s_k, a_k, c) over the rows of a table, compiled or on CasADi's VM by measured cost."""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from ..engine import Backend, choose_backend
from ..engine._codegen import _DRIVER, COSTS, CompiledLoop, built_path, signature_of


class Loop:
    """Run ``step(s, a, c) -> s_next`` over the rows of A, returning every state (rows).

    Where: as :func:`nlobs.engine.choose_backend` decides for ``engine`` — compiled (a C loop, built once per
    machine and cached on disk) when the build exists or the VM time spent on this step in this process reaches
    the predicted compile time, else CasADi's virtual machine (``mapaccum``). A state that becomes non-finite
    is returned as such (the caller decides).
    """

    def __init__(self, step: ca.Function):
        self.step = step
        self.ns = step.size1_in(0)
        self.n_instr = step.n_instructions()
        self._sig: str | None = None
        self._c: CompiledLoop | None = None
        self._vm: dict[int, ca.Function] = {}

    @property
    def signature(self) -> str:
        if self._sig is None:
            self._sig = signature_of(self.step)
        return self._sig

    def backend(self, engine: Backend, steps: int) -> str:
        if self._c is not None and engine != "vm":
            return "c"
        path = built_path("loop", self.signature, _DRIVER)
        if path is None:
            return "vm"
        return choose_backend(engine, ready=path.exists(), n_instr=self.n_instr, vm_instr=float(steps) * self.n_instr,
                              signature=self.signature)

    def __call__(self, s0: np.ndarray, A: np.ndarray, c: np.ndarray, engine: Backend = "auto") -> np.ndarray:
        N = A.shape[0]
        out = np.empty((N, self.ns))
        if N == 0:
            return out
        s0 = np.ascontiguousarray(s0, dtype=float).reshape(self.ns)
        c = np.ascontiguousarray(c, dtype=float).reshape(-1)
        if self.backend(engine, N) == "c":
            if self._c is None:
                self._c = CompiledLoop(self.step, self.signature)
            good = self._c(s0, np.ascontiguousarray(A, dtype=float), c, out)
            if good < N:
                out[good + 1:] = np.nan
            return out
        fn = self._vm.get(N)
        if fn is None:
            fn = self._vm[N] = self.step.mapaccum(f"{self.step.name()}_loop", N)
        t0 = time.perf_counter()
        res = np.asarray(fn(s0, np.asarray(A, dtype=float).T, c)).T
        spent = time.perf_counter() - t0
        COSTS.spent[self.signature] = COSTS.spent.get(self.signature, 0.0) + spent
        COSTS.record_vm(float(N) * self.n_instr, spent)
        return res
