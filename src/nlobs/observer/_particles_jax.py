"""The particle filter on JAX: the C loop of ``_particles.py``, step for step, as one XLA program (CPU or GPU).

For 10⁵–10⁶ particles, where a GPU pays. The model functions are the design's own CasADi ``prop`` and ``meas``,
translated by :func:`nlobs.engine._jax.to_jax` and mapped over the particles; the sample loop is a
``lax.scan``. Same algorithm as the C loop (bootstrap: propagate with noise, weight, resample
systematically (Kitagawa (1996)) when ESS < threshold·M), so with the same draws the two agree to rounding
(tests/observer/test_particles_jax.py). The draws themselves come from JAX's counter-based generator
(threefry, keyed by the design's seed and the sample index): reproducible bit for bit on one machine,
but not the C engine's xoshiro256** stream; ``draws=`` feeds both engines the same numbers.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..design.kalman._pf import ParticleDesign
from ..engine._jax import _jax, to_jax
from ..errors import ModelError, ShapeError
from ._particle_runs import ParticleRun, _Job, draws_needed

__all__ = ["JaxParticleRunner"]


class JaxParticleRunner:
    """A particle filter design run by the JAX engine (see the module docstring)."""

    def __init__(self, design: ParticleDesign):
        if design.scheme != "bootstrap":
            raise ModelError(f"engine='jax' runs the bootstrap particle filter; the {design.scheme} scheme runs on the C engine")
        self.design = design
        s = design.system
        self.n, self.nu, self.ny = s.n_states, s.n_inputs, s.n_outputs
        self._programs: dict[tuple[int, int, bool], Any] = {}

    def _program(self, M: int, nmax: int, external: bool) -> Any:
        key = (M, nmax, external)
        hit = self._programs.get(key)
        if hit is not None:
            return hit
        jax = _jax()
        jnp, lax = jax.numpy, jax.lax
        d = self.design
        prop1, meas1 = to_jax(d.prop), to_jax(d.meas)
        prop = jax.vmap(lambda x, t, h, u: prop1(x, t, h, u)[0], in_axes=(0, None, None, None))
        meas = jax.vmap(lambda x, t, u: meas1(x, t, u)[0], in_axes=(0, None, None))
        n, is_map, thresh = self.n, bool(d.system.is_discrete), float(d.threshold)
        logM = float(np.log(M))

        def loglik(X: Any, t: Any, u: Any, y: Any, W: Any, cst: Any) -> Any:
            v = (y[None, :] - meas(X, t, u)) @ W.T
            q = cst - 0.5 * jnp.sum(v * v, axis=1)
            return jnp.where(jnp.isnan(q), -jnp.inf, q)

        def weigh(lw: Any) -> tuple[Any, Any, Any]:
            m = jnp.max(lw)
            e = jnp.exp(lw - m)
            s = jnp.sum(e)
            wk = e * (1.0 / s)
            m = m + jnp.log(s)
            return lw - m, wk, m

        def sample(Lq: Any, carry: Any, row: Any) -> tuple[Any, Any]:
            X, lw, wk, failed = carry
            k, t_prev, t_k, u_prev, u_k, y, W, cst, nsub, unif, key_or_normals = row
            h = (t_k - t_prev) / nsub

            def substep(s: Any, X: Any) -> Any:
                X = prop(X, t_prev + s * h, h, u_prev)
                xi = key_or_normals[s] if external else jax.random.normal(jax.random.fold_in(key_or_normals, s), (M, n))
                return X + (1.0 if is_map else jnp.sqrt(h)) * (xi @ Lq.T)

            moved = lax.fori_loop(0, nsub.astype(jnp.int32), substep, X)
            X = jnp.where(k > 0, moved, X)
            prior = wk @ X
            lw = lw + loglik(X, t_k, u_k, y, W, cst)
            lw, wk, ll = weigh(lw)
            ok = jnp.isfinite(ll)
            failed = jnp.where((failed < 0) & ~ok, k, failed)
            mean = wk @ X
            D = X - mean
            P = (D * wk[:, None]).T @ D
            ess = 1.0 / jnp.sum(wk * wk)
            resample = ess < thresh * M
            p = (unif + jnp.arange(M)) * (1.0 / M)
            idx = jnp.minimum(jnp.searchsorted(jnp.cumsum(wk), p, side="left"), M - 1)
            X = jnp.where(resample, X[idx], X)
            lw = jnp.where(resample, jnp.full(M, -logM), lw)
            wk = jnp.where(resample, jnp.full(M, 1.0 / M), wk)
            return (X, lw, wk, failed), (mean, P, ess, resample, ll, prior)

        def run(x0: Any, L0: Any, Lq: Any, xi0: Any, rows: Any) -> Any:
            X = x0[None, :] + xi0 @ L0.T
            init = (X, jnp.full(M, -logM), jnp.full(M, 1.0 / M), jnp.int64(-1))
            return lax.scan(lambda c, r: sample(Lq, c, r), init, rows)

        program = self._programs[key] = jax.jit(run)
        return program

    def run(self, t: Any, *args: Any, u: Any = None, y: Any = None, mask: Any = None, xhat0: Any = None,
            seed: int | None = None, particles: int | None = None, name: str | None = None,
            draws: tuple[np.ndarray, np.ndarray] | None = None) -> ParticleRun:
        """As :meth:`nlobs.observer.ParticleRunner.run` (same arguments, same result)."""
        jax = _jax()
        jnp = jax.numpy
        job = _Job.of(self, t, args, u, y, mask, xhat0, seed, particles, name)
        M, N, n = job.M, job.N, self.n
        nsub = job.nsub[:N - 1].astype(np.int64)
        nmax = int(nsub.max()) if nsub.size else 1
        external = draws is not None
        if external:
            dn, du = (np.asarray(a, dtype=float).reshape(-1) for a in draws)
            need = draws_needed(self.design, job.nsub, N, M)
            if dn.size != need or du.size != N:
                raise ShapeError(f"{job.label}: `draws` must hold {need} normals and {N} uniforms, got {dn.size} and {du.size}")
            xi0 = dn[:M * n].reshape(M, n)
            per = np.zeros((N, nmax, M, n))   # sample k's sub-step s takes the next M·n normals, in order
            off = M * n
            for k in range(1, N):
                for s in range(int(nsub[k - 1])):
                    per[k, s] = dn[off:off + M * n].reshape(M, n)
                    off += M * n
            noise: Any = jnp.asarray(per)
            unif = jnp.asarray(du)
        else:
            key = jax.random.PRNGKey(job.seed)
            k0, ku, kn = jax.random.split(key, 3)
            xi0 = jax.random.normal(k0, (M, n))
            unif = jax.random.uniform(ku, (N,))
            noise = jax.vmap(lambda k: jax.random.fold_in(kn, k))(jnp.arange(N))
        idx = np.arange(N)
        prev = np.maximum(idx - 1, 0)
        ns = np.r_[1, nsub] if N > 1 else np.ones(1, dtype=np.int64)
        ns[0] = 1   # the first sample weights the initial particles: its move (h = 0) is computed and discarded
        rows = (jnp.asarray(idx), jnp.asarray(job.t[prev]), jnp.asarray(job.t), jnp.asarray(job.U[prev]), jnp.asarray(job.U),
                jnp.asarray(job.y), jnp.asarray(job.W), jnp.asarray(job.cst), jnp.asarray(ns.astype(float)),
                unif, noise)
        program = self._program(M, nmax, external)
        (X, lw, _, failed), (mean, P, ess, res, ll, prior) = program(jnp.asarray(job.x0), jnp.asarray(job.L0),
                                                                     jnp.asarray(job.Lq), jnp.asarray(xi0), rows)
        xhat = np.array(mean)
        failed = int(failed)
        if failed >= 0:
            xhat[failed:] = np.nan
            job.vanished(failed, xhat)
        return ParticleRun(job.t, xhat, np.array(P), np.array(ess), np.asarray(res, dtype=bool), np.array(ll),
                           np.array(X), np.exp(np.array(lw)), np.array(prior))
