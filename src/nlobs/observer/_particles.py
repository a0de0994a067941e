"""The particle filter's compiled loop: CasADi-generated model functions called from a C loop over samples and particles.

See :func:`nlobs.design.design_pf` for the filter. One call runs the whole recording: per sample, the particles'
RK4 steps with process noise (on a discrete-time model: one step of its map, then the noise of one step), the
Gaussian log-likelihoods, normalisation, the weighted mean and covariance,
the effective sample size and systematic resampling. Random numbers come from xoshiro256** (Blackman & Vigna)
seeded by splitmix64 from the design's seed, so a run is reproducible bit for bit.
"""

from __future__ import annotations

import ctypes
from typing import Any

import numpy as np

from ..design.kalman._pf import ParticleDesign
from ._base import AbstractObserver
from ..engine._codegen import _build, _generate, _renamed, built_path, signature_of
from ..errors import ShapeError
from ._particle_runs import ParticleRun, _Job, draws_needed

__all__ = ["ParticleObserver", "ParticleRun", "ParticleRunner", "draws_needed", "particle_runner"]

_C_PF = r"""
/* nlobs particle filter loop (see nlobs.observer._particles). Returns 0, or k + 1 when every particle's
   weight vanished at sample k (every output non-finite: outside the model's domain). */
#include <math.h>
#include <stdint.h>
#include <string.h>
#include <stdlib.h>
static uint64_t rs[4];
static void zigset(void);
static void seed_lanes(uint64_t seed);
static uint64_t rotl(const uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
static inline uint64_t next64(void) {
  const uint64_t result = rotl(rs[1] * 5, 7) * 9, t = rs[1] << 17;
  rs[2] ^= rs[0]; rs[3] ^= rs[1]; rs[1] ^= rs[2]; rs[0] ^= rs[3]; rs[2] ^= t; rs[3] = rotl(rs[3], 45);
  return result;
}
static void seed_stream(uint64_t seed) {
  int i;
  for (i = 0; i < 4; ++i) {
    uint64_t z = (seed += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL; z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    rs[i] = z ^ (z >> 31);
  }
  seed_lanes(seed);
}
static void seed_rng(uint64_t seed) { seed_stream(seed); zigset(); }
/* the draws of sample k (its resampling uniform first, then its move's normals) come from a stream of their own,
   seeded by (seed, k): a re-run from a saved cloud at sample k draws what the first pass drew there */
static void seed_row(uint64_t seed, long long k) {
  uint64_t z = seed ^ (0xd1b54a32d192ed03ULL * (uint64_t)(k + 1));
  z = (z ^ (z >> 31)) * 0x7fb5d329728ea185ULL; z = (z ^ (z >> 27)) * 0x81dadef4bc2a0c4bULL;
  seed_stream(z ^ (z >> 33));
}
static double unif(void) { return (next64() >> 11) * 0x1.0p-53; }
static double unif_open(void) { return ((next64() >> 11) + 0.5) * 0x1.0p-53; }  /* in (0, 1) */
/* standard normals by the ziggurat method of Marsaglia & Tsang (2000), 128 layers; the layer index and the
   32-bit value come from separate bits of one 64-bit draw (Doornik (2005): they must not share bits) */
static long long kn[128];
static double wn[128], fn[128];
static void zigset(void) {
  const double m1 = 2147483648.0, vn = 9.91256303526217e-3;
  double dn = 3.442619855899, tn = dn, q = vn / exp(-.5 * dn * dn);
  int i;
  kn[0] = (long long)((dn / q) * m1); kn[1] = 0;
  wn[0] = q / m1; wn[127] = dn / m1;
  fn[0] = 1.; fn[127] = exp(-.5 * dn * dn);
  for (i = 126; i >= 1; i--) {
    dn = sqrt(-2. * log(vn / dn + exp(-.5 * dn * dn)));
    kn[i + 1] = (long long)((dn / tn) * m1); tn = dn;
    fn[i] = exp(-.5 * dn * dn); wn[i] = dn / m1;
  }
}
static double gauss_slow(int iz, int32_t hz);
static inline double gauss(void) {  /* the fast path (about 99 % of the draws), inlined */
  uint64_t b = next64();
  int iz = (int)(b & 127);
  int32_t hz = (int32_t)(uint32_t)(b >> 32);
  long long ahz = hz < 0 ? -(long long)hz : (long long)hz;
  if (ahz < kn[iz]) return hz * wn[iz];
  return gauss_slow(iz, hz);
}
static __attribute__((noinline)) double gauss_slow(int iz, int32_t hz) {
  const double r = 3.442620;
  for (;;) {
    double x = hz * wn[iz], y;
    uint64_t b;
    long long ahz;
    if (iz == 0) {  /* the tail beyond r */
      do { x = -log(unif_open()) / r; y = -log(unif_open()); } while (y + y < x * x);
      return hz > 0 ? r + x : -r - x;
    }
    if (fn[iz] + unif() * (fn[iz - 1] - fn[iz]) < exp(-.5 * x * x)) return x;
    b = next64();
    iz = (int)(b & 127);
    hz = (int32_t)(uint32_t)(b >> 32);
    ahz = hz < 0 ? -(long long)hz : (long long)hz;
    if (ahz < kn[iz]) return hz * wn[iz];
  }
}
/* four independent xoshiro256** streams stepped together (the loop over lanes vectorises), for filling
   arrays of normals: the serial dependence of one stream's state was the particle loop's bottleneck */
#define LANES 4
static uint64_t ls[4][LANES];
static void seed_lanes(uint64_t seed) {
  int i, l;
  for (l = 0; l < LANES; ++l) for (i = 0; i < 4; ++i) {
    uint64_t z = (seed += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL; z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    ls[i][l] = z ^ (z >> 31);
  }
}
static void fill_normals(double* out, long long n) {
  uint64_t b[LANES];
  long long j = 0;
  int l;
  for (; j + LANES <= n; j += LANES) {
    for (l = 0; l < LANES; ++l) {
      const uint64_t t = ls[1][l] << 17;
      b[l] = rotl(ls[1][l] * 5, 7) * 9;
      ls[2][l] ^= ls[0][l]; ls[3][l] ^= ls[1][l]; ls[1][l] ^= ls[2][l]; ls[0][l] ^= ls[3][l]; ls[2][l] ^= t;
      ls[3][l] = rotl(ls[3][l], 45);
    }
    for (l = 0; l < LANES; ++l) {
      int iz = (int)(b[l] & 127);
      int32_t hz = (int32_t)(uint32_t)(b[l] >> 32);
      long long ahz = hz < 0 ? -(long long)hz : (long long)hz;
      out[j + l] = ahz < kn[iz] ? hz * wn[iz] : gauss_slow(iz, hz);
    }
  }
  for (; j < n; ++j) out[j] = gauss();
}
long long nlobs_normals(long long seed, long long n, double* out) {
  long long i;
  seed_rng((uint64_t)seed);
  fill_normals(out, n);
  return 0;
}

static const double* arg[SZ_ARG];
static double* res[SZ_RES];
static casadi_int iw[SZ_IW + 1];
static double w[SZ_W + 1];

static void prop(double* x, double t, double h, const double* u, double* out) {
  arg[0] = x; arg[1] = &t; arg[2] = &h; arg[3] = u; res[0] = out;
  nlobs_prop(arg, res, iw, w, 0);
}
/* log N(y; h(x), R) over the measured outputs: W is the inverse Cholesky factor (rows of missing outputs zero) */
static double loglik(const double* x, double t, const double* u, const double* y, const double* W, double cst) {
  double yh[NY + 1], e[NY + 1], q = 0, v;
  int i, j;
  arg[0] = x; arg[1] = &t; arg[2] = u; res[0] = yh;
  nlobs_meas(arg, res, iw, w, 0);
  for (i = 0; i < NY; ++i) e[i] = y[i] - yh[i];
  for (i = 0; i < NY; ++i) { v = 0; for (j = 0; j < NY; ++j) v += W[i * NY + j] * e[j]; q += v * v; }
  q = cst - 0.5 * q;
  return q == q ? q : -INFINITY;  /* outside the model's domain (NaN output): weight 0 */
}
/* move every particle over one interval: nsub RK4 steps of length h, each followed by sqrt(h) Lq xi; on a map
   (map != 0) one step of the map followed by Lq xi (Q is the covariance per step) */
static double* nbuf;  /* M * NX standard normals, drawn in one tight loop per step */
/* external draws (checking another engine against this one): normals M*NX for the initial particles, then
   M*NX per noisy move in order; one uniform per sample for its systematic resampling. NULL: the generator. */
static const double* ext_n;
static const double* ext_u;
static long long ext_off;
static void move(double* X, long long M, double t0, double h, long long nsub, const double* u, const double* Lq, int noise,
                 long long map) {
  double tmp[NX + 1], sq = map ? 1.0 : sqrt(h);
  long long i, s, j;
  int a, b;
  for (s = 0; s < nsub; ++s) {
    for (i = 0; i < M; ++i) {
      double* x = X + i * NX;
      prop(x, t0 + s * h, h, u, tmp);
      for (a = 0; a < NX; ++a) x[a] = tmp[a];
    }
    if (noise) {
      const double* src = nbuf;
      if (ext_n) { src = ext_n + ext_off; ext_off += M * NX; } else fill_normals(nbuf, M * NX);
      for (i = 0; i < M; ++i) {
        double* x = X + i * NX;
        const double* xi = src + i * NX;
        for (a = 0; a < NX; ++a) { double acc = 0; for (b = 0; b < NX; ++b) acc += Lq[a * NX + b] * xi[b]; x[a] += sq * acc; }
      }
    }
  }
}
/* normalise log-weights in place to weights summing to 1; returns log of the sum of exp(lw) (or NaN) */
static double normalise(double* lw, double* wk, long long M) {
  double m = -INFINITY, s = 0;
  long long i;
  for (i = 0; i < M; ++i) if (lw[i] > m) m = lw[i];
  if (!(m > -INFINITY && m < INFINITY)) return NAN;
  for (i = 0; i < M; ++i) { wk[i] = exp(lw[i] - m); s += wk[i]; }
  m += log(s);
  s = 1 / s;
  for (i = 0; i < M; ++i) { wk[i] *= s; lw[i] -= m; }
  return m;
}
/* systematic resampling (Kitagawa 1996): idx[i] = the particle whose cumulative weight first exceeds (i + U)/M */
static void systematic(const double* wk, long long M, long long* idx, double u) {  /* u uniform in [0, 1) */
  double c = wk[0], step = 1.0 / M, p = u * step;
  long long i, j = 0;
  for (i = 0; i < M; ++i, p += step) {
    while (p > c && j < M - 1) { ++j; c += wk[j]; }
    idx[i] = j;
  }
}
static void wmean(const double* X, const double* wk, long long M, double* out) {
  long long i;
  int a;
  for (a = 0; a < NX; ++a) out[a] = 0;
  for (i = 0; i < M; ++i) for (a = 0; a < NX; ++a) out[a] += wk[i] * X[i * NX + a];
}
static void gather(const double* X, const long long* idx, long long M, double* out) {
  long long i;
  for (i = 0; i < M; ++i) memcpy(out + i * NX, X + idx[i] * NX, sizeof(double) * NX);
}

static long long pf_loop(const double* t, const double* U, const double* Y, const double* W, const double* cst,
                   const double* nsub, const double* x0, const double* L0, const double* Lq, long long N, long long M,
                   long long aux, long long map, double thresh, long long seed, double* X, double* Xb, double* lw, double* wk,
                   double* mu, double* lmu, long long* idx, double* xhat, double* P, double* ess, double* resampled,
                   double* ll, double* xprior, long long k0, const double* X_init, const double* lw_init,
                   const double* keep, double* kept_X, double* kept_lw) {
  long long k, i, nkept = 0;
  int a, b;
  double xi[NX + 1], s, sw2, urow = 0;
  zigset();
  nbuf = (double*)malloc(sizeof(double) * M * NX);
  if (!nbuf) return -1;
  ext_off = (ext_n && !X_init) ? M * NX : 0;
  if (X_init) {  /* resume: the cloud after sample k0 (row 0 of this call), weights as log-weights */
    double m = -INFINITY, sum = 0;
    memcpy(X, X_init, sizeof(double) * M * NX);
    for (i = 0; i < M; ++i) { lw[i] = lw_init[i]; if (lw[i] > m) m = lw[i]; }
    for (i = 0; i < M; ++i) { wk[i] = exp(lw[i] - m); sum += wk[i]; }
    for (i = 0; i < M; ++i) wk[i] /= sum;
  } else {
    seed_row((uint64_t)seed, k0);
    urow = ext_u ? ext_u[0] : unif();
    for (i = 0; i < M; ++i) {
      for (a = 0; a < NX; ++a) xi[a] = ext_n ? ext_n[i * NX + a] : gauss();
      for (a = 0; a < NX; ++a) { double acc = 0; for (b = 0; b <= a; ++b) acc += L0[a * NX + b] * xi[b]; X[i * NX + a] = x0[a] + acc; }
      lw[i] = -log((double)M); wk[i] = 1.0 / M;
    }
  }
  for (k = X_init ? 1 : 0; k < N; ++k) {
    const double* y = Y + k * NY; const double* Wk = W + k * NY * NY;
    resampled[k] = 0;
    if (k > 0) {
      seed_row((uint64_t)seed, k0 + k);
      urow = ext_u ? ext_u[k] : unif();
    }
    if (k > 0) {
      const double* u = U + (k - 1) * NU;
      double h = (t[k] - t[k - 1]) / nsub[k - 1];
      if (aux) {  /* Pitt & Shephard: first stage on the noise-free moves mu_i */
        memcpy(mu, X, sizeof(double) * M * NX);
        move(mu, M, t[k - 1], h, (long long)nsub[k - 1], u, Lq, 0, map);
        wmean(mu, wk, M, xprior + k * NX);
        for (i = 0; i < M; ++i) { lmu[i] = loglik(mu + i * NX, t[k], U + k * NU, y, Wk, cst[k]); lw[i] += lmu[i]; }
        s = normalise(lw, wk, M);
        if (!(s == s)) return k + 1;
        systematic(wk, M, idx, urow);
        gather(X, idx, M, Xb);
        memcpy(X, Xb, sizeof(double) * M * NX);
        move(X, M, t[k - 1], h, (long long)nsub[k - 1], u, Lq, 1, map);
        for (i = 0; i < M; ++i) lw[i] = loglik(X + i * NX, t[k], U + k * NU, y, Wk, cst[k]) - lmu[idx[i]];
        resampled[k] = 1;
        /* log p(y_k | y_1:k-1) ~ log sum_i w_i p(y|mu_i) + log mean_i of the second-stage weights */
        ll[k] = s;
        s = normalise(lw, wk, M);
        if (!(s == s)) return k + 1;
        ll[k] += s - log((double)M);
      } else {
        move(X, M, t[k - 1], h, (long long)nsub[k - 1], u, Lq, 1, map);
        wmean(X, wk, M, xprior + k * NX);
      }
    } else {
      wmean(X, wk, M, xprior);
    }
    if (!aux || k == 0) {
      for (i = 0; i < M; ++i) lw[i] += loglik(X + i * NX, t[k], U + k * NU, y, Wk, cst[k]);
      s = normalise(lw, wk, M);
      if (!(s == s)) return k + 1;
      ll[k] = s;
    }
    /* estimate, covariance and ESS before resampling: one pass for the mean, one for the covariance */
    {
      double mean[NX + 1], cov[NX * NX + 1], d[NX + 1];
      for (a = 0; a < NX; ++a) mean[a] = 0;
      for (a = 0; a < NX * NX; ++a) cov[a] = 0;
      sw2 = 0;
      for (i = 0; i < M; ++i) {
        const double* x = X + i * NX;
        for (a = 0; a < NX; ++a) mean[a] += wk[i] * x[a];
        sw2 += wk[i] * wk[i];
      }
      for (i = 0; i < M; ++i) {
        const double* x = X + i * NX;
        for (a = 0; a < NX; ++a) d[a] = x[a] - mean[a];
        for (a = 0; a < NX; ++a) for (b = 0; b <= a; ++b) cov[a * NX + b] += wk[i] * d[a] * d[b];
      }
      for (a = 0; a < NX; ++a) {
        xhat[k * NX + a] = mean[a];
        for (b = 0; b <= a; ++b) { P[k * NX * NX + a * NX + b] = cov[a * NX + b]; P[k * NX * NX + b * NX + a] = cov[a * NX + b]; }
      }
    }
    ess[k] = 1 / sw2;
    if (!aux && ess[k] < thresh * M) {
      systematic(wk, M, idx, urow);
      gather(X, idx, M, Xb);
      memcpy(X, Xb, sizeof(double) * M * NX);
      for (i = 0; i < M; ++i) { lw[i] = -log((double)M); wk[i] = 1.0 / M; }
      resampled[k] = 1;
    }
    if (keep && keep[k] > 0) {  /* save the cloud after this sample, to resume from it */
      memcpy(kept_X + nkept * M * NX, X, sizeof(double) * M * NX);
      memcpy(kept_lw + nkept * M, lw, sizeof(double) * M);
      ++nkept;
    }
  }
  return 0;
}

long long nlobs_pf(const double* t, const double* U, const double* Y, const double* W, const double* cst,
                   const double* nsub, const double* x0, const double* L0, const double* Lq, long long N, long long M,
                   long long aux, long long map, double thresh, long long seed, double* X, double* Xb, double* lw, double* wk,
                   double* mu, double* lmu, long long* idx, double* xhat, double* P, double* ess, double* resampled,
                   double* ll, double* xprior, const double* draws_n, const double* draws_u, long long k0,
                   const double* X_init, const double* lw_init, const double* keep, double* kept_X, double* kept_lw) {
  long long rc;
  ext_n = draws_n; ext_u = draws_u;
  rc = pf_loop(t, U, Y, W, cst, nsub, x0, L0, Lq, N, M, aux, map, thresh, seed, X, Xb, lw, wk, mu, lmu, idx, xhat, P,
               ess, resampled, ll, xprior, k0, X_init, lw_init, keep, kept_X, kept_lw);
  free(nbuf);
  nbuf = 0;
  ext_n = 0; ext_u = 0;
  return rc;
}
"""


class ParticleRunner:
    """A particle filter design compiled to run on recordings (the C loop is built once per machine, cached)."""

    def __init__(self, design: ParticleDesign):
        self.design = design
        s = design.system
        self.n, self.nu, self.ny = s.n_states, s.n_inputs, s.n_outputs
        rp, rm = _renamed(design.prop, "nlobs_prop"), _renamed(design.meas, "nlobs_meas")

        def code() -> str:
            defs = {"SZ_ARG": max(rp.sz_arg(), rm.sz_arg()), "SZ_RES": max(rp.sz_res(), rm.sz_res()),
                    "SZ_IW": max(rp.sz_iw(), rm.sz_iw()), "SZ_W": max(rp.sz_w(), rm.sz_w()),
                    "NX": self.n, "NY": self.ny, "NU": max(self.nu, 1)}
            driver = _C_PF
            for k, v in defs.items():
                driver = driver.replace(k, str(int(v)))
            return _generate(rp, rm) + driver

        sig = signature_of(design.prop) + signature_of(design.meas) + f"{self.n},{self.ny},{self.nu}"
        path = _build(code, "particles", built_path("particles", sig, _C_PF))
        lib = ctypes.CDLL(str(path))
        fn = lib.nlobs_pf
        dbl, ll = ctypes.POINTER(ctypes.c_double), ctypes.c_longlong
        fn.argtypes = [dbl] * 9 + [ll, ll, ll, ll, ctypes.c_double, ll] + [dbl] * 6 + [ctypes.POINTER(ctypes.c_longlong)] + [dbl] * 8 \
            + [ll] + [dbl] * 5
        fn.restype = ll
        lib.nlobs_normals.argtypes = [ll, ll, ctypes.POINTER(ctypes.c_double)]
        lib.nlobs_normals.restype = ll
        self._fn, self._lib = fn, lib

    def normals(self, n: int, seed: int) -> np.ndarray:
        """`n` standard normal draws of the filter's generator (for checking it)."""
        out = np.empty(int(n))
        self._lib.nlobs_normals(int(seed), int(n), out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)))
        return out

    def run(self, t: Any, *args: Any, u: Any = None, y: Any = None, mask: Any = None, xhat0: Any = None,
            seed: int | None = None, particles: int | None = None, name: str | None = None,
            draws: tuple[np.ndarray, np.ndarray] | None = None, resume: tuple[np.ndarray, np.ndarray] | None = None,
            k0: int = 0, keep: np.ndarray | None = None) -> ParticleRun:
        """Run the filter on samples: times `t` (N,), inputs `u` (N, m) and outputs `y` (N, p), held between samples:
        ``run(t, u=..., y=...)``.

        Sample k's random numbers come from a stream seeded by (seed, k0 + k): `resume` = (particles, log-weights),
        the cloud after the first sample of `t` (sample k0 of an earlier run), goes on from there with the draws that
        run made (row 0's results are then NaN); `keep` (N bools) saves the cloud after those samples (``kept``).

        `mask` (N, p) marks measured outputs (1) and missing ones (0); `xhat0`, `seed` and `particles`
        override the design's. `draws` = (normals, uniforms) replaces the generator (to check another engine
        against this one): the initial particles' normals then each noisy move's, M·n each, in order
        (:func:`draws_needed`), and one uniform per sample for its resampling.

        Raises
        ------
        FiniteEscapeError
            When every particle's likelihood vanishes at a sample (the particles missed the measurement:
            more particles, a larger Q or R, or a better x̂0).
        """
        job = _Job.of(self, t, args, u, y, mask, xhat0, seed, particles, name)
        n_draws = draws_needed(self.design, job.nsub, job.N, job.M)
        dn = du = None
        if draws is not None:
            dn, du = (np.ascontiguousarray(a, dtype=float).reshape(-1) for a in draws)
            if dn.size != n_draws or du.size != job.N:
                raise ShapeError(f"{job.label}: `draws` must hold {n_draws} normals and {job.N} uniforms, got {dn.size} and {du.size}")
        M, N, n = job.M, job.N, self.n
        X, Xb, mu = (np.empty((M, n)) for _ in range(3))
        lw, wk, lmu = np.empty(M), np.empty(M), np.empty(M)
        idx = np.empty(M, dtype=np.int64)
        xhat, P = np.full((N, n), np.nan), np.full((N, n, n), np.nan)
        ess, res, llk, prior = np.full(N, np.nan), np.zeros(N), np.full(N, np.nan), np.full((N, n), np.nan)
        p = ctypes.POINTER(ctypes.c_double)
        null = ctypes.cast(None, p)
        d = self.design
        Xi = Li = None
        if resume is not None:
            Xi = np.ascontiguousarray(resume[0], dtype=float).reshape(M, n)
            Li = np.ascontiguousarray(resume[1], dtype=float).reshape(M)
        kf = None if keep is None else np.ascontiguousarray(keep, dtype=float).reshape(N)
        n_keep = 0 if kf is None else int(np.count_nonzero(kf > 0))
        kX, kL = np.empty((n_keep, M, n)), np.empty((n_keep, M))
        rc = self._fn(job.t.ctypes.data_as(p), job.U.ctypes.data_as(p), job.y.ctypes.data_as(p), job.W.ctypes.data_as(p),
                      job.cst.ctypes.data_as(p), job.nsub.ctypes.data_as(p), job.x0.ctypes.data_as(p), job.L0.ctypes.data_as(p),
                      job.Lq.ctypes.data_as(p), N, M, int(d.scheme == "auxiliary"), int(d.system.is_discrete), d.threshold,
                      job.seed, X.ctypes.data_as(p), Xb.ctypes.data_as(p), lw.ctypes.data_as(p), wk.ctypes.data_as(p),
                      mu.ctypes.data_as(p), lmu.ctypes.data_as(p), idx.ctypes.data_as(ctypes.POINTER(ctypes.c_longlong)),
                      xhat.ctypes.data_as(p), P.ctypes.data_as(p), ess.ctypes.data_as(p), res.ctypes.data_as(p),
                      llk.ctypes.data_as(p), prior.ctypes.data_as(p),
                      null if dn is None else dn.ctypes.data_as(p), null if du is None else du.ctypes.data_as(p), int(k0),
                      null if Xi is None else Xi.ctypes.data_as(p), null if Li is None else Li.ctypes.data_as(p),
                      null if kf is None else kf.ctypes.data_as(p), kX.ctypes.data_as(p), kL.ctypes.data_as(p))
        if rc < 0:
            raise MemoryError(f"{job.label}: no memory for {M} particles' random numbers")
        if rc:
            job.vanished(int(rc - 1), xhat)
        return ParticleRun(job.t, xhat, P, ess, res > 0, llk, X.copy(), np.exp(lw), prior, lw.copy(),
                           None if kf is None else (kX, kL))


_RUNNERS: dict[tuple[int, str], Any] = {}


def particle_runner(design: ParticleDesign, engine: str | None = None) -> Any:
    """The runner for `design` on its engine (``design.engine`` unless `engine` is given: "c", the compiled loop;
    "jax", :class:`nlobs.observer._particles_jax.JaxParticleRunner`), built on first use, then cached for the process."""
    engine = getattr(design, "engine", "c") if engine is None else engine
    if engine not in ("c", "jax"):
        raise ValueError(f"particle_runner: `engine` must be 'c' or 'jax', got {engine!r}")
    key = (id(design), engine)
    r = _RUNNERS.get(key)
    if r is None or r.design is not design:
        if engine == "jax":
            from ._particles_jax import JaxParticleRunner

            r = JaxParticleRunner(design)
        else:
            r = ParticleRunner(design)
        _RUNNERS[key] = r
    return r


class ParticleObserver(AbstractObserver):
    """A particle filter as an observer of :func:`nlobs.simulate` and :func:`nlobs.estimate`.

    A particle filter is not an ODE observer: its state is a random cloud of particles, run over a whole
    recording at once by :class:`ParticleRunner`. The per-step calls of :class:`AbstractObserver`
    (rhs, update, step, online use) are therefore refused with a clear error.
    """

    def __init__(self, design: ParticleDesign, name: str | None = None):
        if not isinstance(design, ParticleDesign):
            raise TypeError(f"ParticleObserver needs a ParticleDesign (from design_pf), got {type(design).__name__}")
        self._design = design
        self.name = name or design.method

    @property
    def design(self) -> ParticleDesign:  # type: ignore[override]
        return self._design

    def _refuse(self, what: str) -> Any:
        raise TypeError(f"{what}: a particle filter ({self.name!r}) runs on a whole recording, not step by step; use "
                        "nlobs.simulate, nlobs.estimate, or nlobs.observer.particle_runner(design).run(t, u=u, y=y)")

    def rhs(self, t: float, z: Any, u: Any = None, y: Any = None) -> np.ndarray:
        return self._refuse("rhs")

    def estimate(self, t: float, z: Any, u: Any = None, y: Any = None) -> np.ndarray:
        return self._refuse("estimate")

    def update(self, t: float, z: Any, u: Any = None, y: Any = None, mask: Any = None) -> np.ndarray:
        return self._refuse("update")

    def step(self, t: float, z: Any, dt: float, u: Any, y: Any, *, substeps: int = 1) -> np.ndarray:
        return self._refuse("step")

    def start(self, xhat0: Any = None, *, max_step: float | None = None) -> Any:
        return self._refuse("start")

    def initial_state(self, xhat0: Any = None) -> np.ndarray:
        """The mean of the initial particles (the design's x̂0 unless given)."""
        x0 = self._design.xhat0 if xhat0 is None else np.asarray(xhat0, dtype=float).reshape(-1)
        if x0.size != self.system.n_states:
            raise ShapeError(f"`xhat0` must have {self.system.n_states} entries, got {x0.size}")
        return x0

    def trace_on(self, t: np.ndarray, y: np.ndarray, u: np.ndarray, *, mask: Any = None, xhat0: Any = None,
                 name: str | None = None) -> tuple[ParticleRun, np.ndarray]:
        """Run on samples and return the run and the output predicted before each sample, h(x̂⁻)."""
        run = particle_runner(self._design).run(t, u=u, y=y, mask=mask, xhat0=xhat0, name=name or self.name)
        N = run.t.size
        uu = np.zeros((N, self.system.n_inputs)) if u is None else np.asarray(u, dtype=float).reshape(N, -1)
        yp = np.asarray(self._design.meas.map(N)(run.xhat_prior.T, run.t[None, :], uu.T), dtype=float).T
        return run, yp.reshape(N, self.system.n_outputs)

    def __repr__(self) -> str:
        return f"ParticleObserver({self.name!r}, scheme={self._design.scheme!r}, particles={self._design.particles})"
