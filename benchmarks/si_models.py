"""StructuralIdentifiability.jl's benchmark models, transcribed for nlobs (data only, no nlobs logic).

Source: SciML/StructuralIdentifiability.jl @ b7bff91634575095369190ca7d418fe41f98cac2,
file ``benchmarking/benchmarks.jl`` (a Julia ``Dict`` of ``@ODEmodel(...)`` models; every entry of it is here,
NFkB included). Published timings of SI.jl's ``find_identifiable_functions`` (with states): the same commit,
``benchmarking/IdentifiableFunctions/benchmark_result.md`` (run 2023-09-15, Julia 1.9.3, Intel Xeon (Icelake),
15 GiB RAM, 7 workers, 600 s timeout), column "(:normalforms, 2)_with_states / Runtime".

Conventions
-----------
* ``x'(t) = rhs`` is a state, ``y(t) = expr`` an output; any other name written ``name(t)`` is an input (a known,
  generic signal); a bare name is a parameter. As in SI.jl's ``@ODEmodel`` macro (``src/input_macro.jl``), a bare
  name that is also written ``name(t)`` elsewhere is that time-dependent variable (KD1999's ``Arr``, SEIR 36 ref's
  ``q``).
* Expressions are in Python/SymPy syntax: ``^`` -> ``**``, the ``(t)`` suffixes removed, Julia's rational ``//``
  -> ``/`` (``//`` binds tighter than ``*`` in Julia; no ``a / b // c`` chain occurs, so no value changes), lines
  joined. The arithmetic is otherwise as written (nothing simplified). Decimal literals are kept (``0.011``):
  SI.jl rationalizes them (11//1000), nlobs parses them to the same exact rational.
* Each model: ``name`` (SI.jl's ``:name``), ``key`` (its key in the Dict), ``line`` (line of benchmarks.jl where
  the entry starts), ``states`` {state: rhs}, ``outputs`` {output: expr}, ``params``, ``inputs`` (in order of
  first appearance), ``si_functions_seconds`` (the published runtime, matched by exact name; None when the
  model is not in the table or its runtime is "-"), ``skip`` (SI.jl's ``:skip`` flag, False when absent),
  ``renamed`` {SI.jl name: name here}, ``fixed`` {parameter: value substituted into the expressions} and
  ``note`` (how the entry was read, when not plain).
* Renames: only the names nlobs's ``System`` refuses: ``lambda`` (a Python keyword) -> ``lam`` in SEIRT. SymPy's
  names (I, E, N, S, Q, O, beta, gamma, ...) are accepted by nlobs and kept.
* NFkB (lines 1297-1355): ``set_parameter_values`` fixes 16 parameters to rationals; their values are written in
  place of the names (``fixed`` lists them) and they are not parameters.
* Linear_compartment_hard_1/2 are built by SI.jl's ``linear_compartment_model`` (``src/lincomp.jl``); written
  out here term by term.
* The published runtimes were measured on the model files ``benchmarking/IdentifiableFunctions/results/<name>/
  <name>.jl`` of 2023, not on benchmarks.jl itself; where that file describes a different model than
  benchmarks.jl now does, ``note`` says so (the time is then of the other model). Every other model that has such
  a file was checked equal to it (same names; every right-hand side and output equal as rational functions):
  MAPK (all three), QY, HighDimNonLin, Pharm, NFkB (after the substitution) and the rest. In 2023 the SIR/SEIR
  models had N (and some a recovered state R) as states with N' = 0; SEIR 36 ref also had nu and q as states.
* The table's Akt pathway, CD8 T cell differentiation, PK1, PK2, Phosphorylation, cholera and
  generalizedLoktaVolterra (2o) are not in benchmarks.jl. They are the last seven entries, transcribed from their
  2023 model files (``file``, relative to ``benchmarking/IdentifiableFunctions``; ``key`` and ``line`` are None)
  with the same conventions (``pro_EGFR(t)``, which has no equation, is an input). Akt pathway is the Fujita model
  with the outputs multiplied out (checked equal as rational functions); the table times both.
* Some states occur in no right-hand side or output, as in the source: Biohydrogenation_io x7, SEIR_1_io R,
  SIR 21 R, SIR 19 U, Bruno2016 betaio and OHbetaio.
"""

from __future__ import annotations

from typing import Any

SOURCE = "SciML/StructuralIdentifiability.jl@b7bff91634575095369190ca7d418fe41f98cac2"
FILE = "benchmarking/benchmarks.jl"
TIMES_FILE = "benchmarking/IdentifiableFunctions/benchmark_result.md"

MODELS: dict[str, dict[str, Any]] = {
    "lv": {
        "name": "Modified LV for testing", "key": ":LV", "line": 2,
        "states": {
            "x1": "(a + b) * x1 - c * x1 * x2",
            "x2": "-a * b * x2 + d * x1 * x2",
        },
        "outputs": {
            "y1": "x1",
        },
        "params": ("a", "b", "c", "d"),
        "inputs": (),
        "si_functions_seconds": 0.07, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "siwr_orig": {
        "name": "SIWR original", "key": ":SIWR_orig", "line": 11,
        "states": {
            "S": "mu - bi * S * I - bw * S * W - mu * S + a * R",
            "I": "bw * S * W + bi * S * I - (gam + mu) * I",
            "W": "xi * (I - W)",
            "R": "gam * I - (mu + a) * R",
        },
        "outputs": {
            "y": "k * I",
        },
        "params": ("mu", "bi", "bw", "a", "gam", "xi", "k"),
        "inputs": (),
        "si_functions_seconds": 13.72, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "siwr_multiout": {
        "name": "SIWR with extra output", "key": ":SIWR_multiout", "line": 23,
        "states": {
            "S": "mu - bi * S * I - bw * S * W - mu * S + a * R",
            "I": "bw * S * W + bi * S * I - (gam + mu) * I",
            "W": "xi * (I - W)",
            "R": "gam * I - (mu + a) * R",
        },
        "outputs": {
            "y": "k * I",
            "y2": "S + I + R",
        },
        "params": ("mu", "bi", "bw", "a", "gam", "xi", "k"),
        "inputs": (),
        "si_functions_seconds": 0.67, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "pharm": {
        "name": "Pharm", "key": ":Pharm", "line": 36,
        "states": {
            "x0": "a1 * (x1 - x0) - (ka * n * x0) / (kc * ka + kc * x2 + ka * x0)",
            "x1": "a2 * (x0 - x1)",
            "x2": "b1 * (x3 - x2) - (kc * n * x2) / (kc * ka + kc * x2 + ka * x0)",
            "x3": "b2 * (x2 - x3)",
        },
        "outputs": {
            "y1": "x0",
        },
        "params": ("a1", "ka", "n", "kc", "a2", "b1", "b2"),
        "inputs": (),
        "si_functions_seconds": 152.26, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "seaijrc": {
        "name": "SEAIJRC Covid model", "key": ":SEAIJRC", "line": 52,
        "states": {
            "S": "-b * S * (I + J + q * A) * Ninv",
            "E": "b * S * (I + J + q * A) * Ninv - k * E",
            "A": "k * (1 - r) * E - g1 * A",
            "I": "k * r * E - (alpha + g1) * I",
            "J": "alpha * I - g2 * J",
            "C": "alpha * I",
            "Ninv": "0",
        },
        "outputs": {
            "y": "C",
            "y2": "Ninv",
        },
        "params": ("b", "q", "k", "r", "g1", "alpha", "g2"),
        "inputs": (),
        "si_functions_seconds": 85.13, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "mapk_5out": {
        "name": "MAPK model (5 outputs)", "key": ":MAPK_5out", "line": 68,
        "states": {
            "KS00": "-a00 * K * S00 + b00 * KS00 + gamma0100 * FS01 + gamma1000 * FS10 + gamma1100 * FS11",
            "KS01": ("-a01 * K * S01 + b01 * KS01 + c0001 * KS00 - alpha01 * F * S01 + beta01 * FS01 + gamma1101 * "
                     "FS11"),
            "KS10": ("-a10 * K * S10 + b10 * KS10 + c0010 * KS00 - alpha10 * F * S10 + beta10 * FS10 + gamma1110 * "
                     "FS11"),
            "FS01": "-alpha11 * F * S11 + beta11 * FS11 + c0111 * KS01 + c1011 * KS10 + c0011 * KS00",
            "FS10": "a00 * K * S00 - (b00 + c0001 + c0010 + c0011) * KS00",
            "FS11": "a01 * K * S01 - (b01 + c0111) * KS01",
            "K": "a10 * K * S10 - (b10 + c1011) * KS10",
            "F": "alpha01 * F * S01 - (beta01 + gamma0100) * FS01",
            "S00": "alpha10 * F * S10 - (beta10 + gamma1000) * FS10",
            "S01": "alpha11 * F * S11 - (beta11 + gamma1101 + gamma1110 + gamma1100) * FS11",
            "S10": ("-a00 * K * S00 + (b00 + c0001 + c0010 + c0011) * KS00 - a01 * K * S01 + (b01 + c0111) * KS01 - "
                    "a10 * K * S10 + (b10 + c1011) * KS10"),
            "S11": ("-alpha01 * F * S01 + (beta01 + gamma0100) * FS01 - alpha10 * F * S10 + (beta10 + gamma1000) * "
                    "FS10 - alpha11 * F * S11 + (beta11 + gamma1101 + gamma1110 + gamma1100) * FS11"),
        },
        "outputs": {
            "y1": "F",
            "y2": "S00",
            "y3": "S01",
            "y4": "S10",
            "y5": "S11",
        },
        "params": ("a00", "b00", "gamma0100", "gamma1000", "gamma1100", "a01", "b01", "c0001", "alpha01", "beta01",
                   "gamma1101", "a10", "b10", "c0010", "alpha10", "beta10", "gamma1110", "alpha11", "beta11", "c0111",
                   "c1011", "c0011"),
        "inputs": (),
        "si_functions_seconds": 48.45, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "mapk_5out_bis": {
        "name": "MAPK model (5 outputs bis)", "key": ":MAPK_5out_bis", "line": 118,
        "states": {
            "KS00": "-a00 * K * S00 + b00 * KS00 + gamma0100 * FS01 + gamma1000 * FS10 + gamma1100 * FS11",
            "KS01": ("-a01 * K * S01 + b01 * KS01 + c0001 * KS00 - alpha01 * F * S01 + beta01 * FS01 + gamma1101 * "
                     "FS11"),
            "KS10": ("-a10 * K * S10 + b10 * KS10 + c0010 * KS00 - alpha10 * F * S10 + beta10 * FS10 + gamma1110 * "
                     "FS11"),
            "FS01": "-alpha11 * F * S11 + beta11 * FS11 + c0111 * KS01 + c1011 * KS10 + c0011 * KS00",
            "FS10": "a00 * K * S00 - (b00 + c0001 + c0010 + c0011) * KS00",
            "FS11": "a01 * K * S01 - (b01 + c0111) * KS01",
            "K": "a10 * K * S10 - (b10 + c1011) * KS10",
            "F": "alpha01 * F * S01 - (beta01 + gamma0100) * FS01",
            "S00": "alpha10 * F * S10 - (beta10 + gamma1000) * FS10",
            "S01": "alpha11 * F * S11 - (beta11 + gamma1101 + gamma1110 + gamma1100) * FS11",
            "S10": ("-a00 * K * S00 + (b00 + c0001 + c0010 + c0011) * KS00 - a01 * K * S01 + (b01 + c0111) * KS01 - "
                    "a10 * K * S10 + (b10 + c1011) * KS10"),
            "S11": ("-alpha01 * F * S01 + (beta01 + gamma0100) * FS01 - alpha10 * F * S10 + (beta10 + gamma1000) * "
                    "FS10 - alpha11 * F * S11 + (beta11 + gamma1101 + gamma1110 + gamma1100) * FS11"),
        },
        "outputs": {
            "y0": "K",
            "y1": "F",
            "y2": "S00",
            "y3": "S01 + S10",
            "y4": "S11",
        },
        "params": ("a00", "b00", "gamma0100", "gamma1000", "gamma1100", "a01", "b01", "c0001", "alpha01", "beta01",
                   "gamma1101", "a10", "b10", "c0010", "alpha10", "beta10", "gamma1110", "alpha11", "beta11", "c0111",
                   "c1011", "c0011"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "mapk_6out": {
        "name": "MAPK model (6 outputs)", "key": ":MAPK_6out", "line": 169,
        "states": {
            "KS00": "-a00 * K * S00 + b00 * KS00 + gamma0100 * FS01 + gamma1000 * FS10 + gamma1100 * FS11",
            "KS01": ("-a01 * K * S01 + b01 * KS01 + c0001 * KS00 - alpha01 * F * S01 + beta01 * FS01 + gamma1101 * "
                     "FS11"),
            "KS10": ("-a10 * K * S10 + b10 * KS10 + c0010 * KS00 - alpha10 * F * S10 + beta10 * FS10 + gamma1110 * "
                     "FS11"),
            "FS01": "-alpha11 * F * S11 + beta11 * FS11 + c0111 * KS01 + c1011 * KS10 + c0011 * KS00",
            "FS10": "a00 * K * S00 - (b00 + c0001 + c0010 + c0011) * KS00",
            "FS11": "a01 * K * S01 - (b01 + c0111) * KS01",
            "K": "a10 * K * S10 - (b10 + c1011) * KS10",
            "F": "alpha01 * F * S01 - (beta01 + gamma0100) * FS01",
            "S00": "alpha10 * F * S10 - (beta10 + gamma1000) * FS10",
            "S01": "alpha11 * F * S11 - (beta11 + gamma1101 + gamma1110 + gamma1100) * FS11",
            "S10": ("-a00 * K * S00 + (b00 + c0001 + c0010 + c0011) * KS00 - a01 * K * S01 + (b01 + c0111) * KS01 - "
                    "a10 * K * S10 + (b10 + c1011) * KS10"),
            "S11": ("-alpha01 * F * S01 + (beta01 + gamma0100) * FS01 - alpha10 * F * S10 + (beta10 + gamma1000) * "
                    "FS10 - alpha11 * F * S11 + (beta11 + gamma1101 + gamma1110 + gamma1100) * FS11"),
        },
        "outputs": {
            "y0": "K",
            "y1": "F",
            "y2": "S00",
            "y3": "S01",
            "y4": "S10",
            "y5": "S11",
        },
        "params": ("a00", "b00", "gamma0100", "gamma1000", "gamma1100", "a01", "b01", "c0001", "alpha01", "beta01",
                   "gamma1101", "a10", "b10", "c0010", "alpha10", "beta10", "gamma1110", "alpha11", "beta11", "c0111",
                   "c1011", "c0011"),
        "inputs": (),
        "si_functions_seconds": 7.99, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "goodwin": {
        "name": "Goodwin oscillator", "key": ":Goodwin", "line": 220,
        "states": {
            "x1": "-b * x1 + 1 / (c + x4)",
            "x2": "alpha * x1 - beta * x2",
            "x3": "gama * x2 - delta * x3",
            "x4": "sigma * x4 * (gama * x2 - delta * x3) / x3",
        },
        "outputs": {
            "y": "x1",
        },
        "params": ("b", "c", "alpha", "beta", "gama", "delta", "sigma"),
        "inputs": (),
        "si_functions_seconds": 0.29, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "hiv": {
        "name": "HIV", "key": ":HIV", "line": 231,
        "states": {
            "x": "lm - d * x - beta * x * v",
            "y": "beta * x * v - a * y",
            "v": "k * y - u * v",
            "w": "c * x * y * w - c * q * y * w - b * w",
            "z": "c * q * y * w - h * z",
        },
        "outputs": {
            "y1": "w",
            "y2": "z",
        },
        "params": ("lm", "d", "beta", "a", "k", "u", "c", "q", "b", "h"),
        "inputs": (),
        "si_functions_seconds": 0.78, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "sirs_forced": {
        "name": "SIRS forced", "key": ":SIRC_forced", "line": 244,
        "states": {
            "s": "mu - mu * s - b0 * (1 + b1 * x1) * i * s + g * r",
            "i": "b0 * (1 + b1 * x1) * i * s - (nu + mu) * i",
            "r": "nu * i - (mu + g) * r",
            "x1": "-M * x2",
            "x2": "M * x1",
        },
        "outputs": {
            "y1": "i",
            "y2": "r",
        },
        "params": ("mu", "b0", "b1", "g", "nu", "M"),
        "inputs": (),
        "si_functions_seconds": 10.62, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "crn": {
        "name": "Chemical reaction network", "key": ":CRN", "line": 257,
        "states": {
            "x1": "-k1 * x1 * x2 + k2 * x4 + k4 * x6",
            "x2": "-k1 * x1 * x2 + k2 * x4 + k3 * x4",
            "x3": "k3 * x4 + k5 * x6 - k6 * x3 * x5",
            "x4": "k1 * x1 * x2 - k2 * x4 - k3 * x4",
            "x5": "k4 * x6 + k5 * x6 - k6 * x3 * x5",
            "x6": "-k4 * x6 - k5 * x6 + k6 * x3 * x5",
        },
        "outputs": {
            "y1": "x3",
            "y2": "x2",
        },
        "params": ("k1", "k2", "k4", "k3", "k5", "k6"),
        "inputs": (),
        "si_functions_seconds": 0.36, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "qwwc": {
        "name": "QWWC", "key": ":QWWC", "line": 271,
        "states": {
            "x": "a * (y - x) + y * z",
            "y": "b * (x + y) - x * z",
            "z": "-c * z - d * w + x * y",
            "w": "e * z - f * w + x * y",
        },
        "outputs": {
            "g": "x",
        },
        "params": ("a", "b", "c", "d", "e", "f"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "sliqr": {
        "name": "SLIQR", "key": ":SLIQR", "line": 286,
        "states": {
            "S": "-b * In * S * Ninv - u * S * Ninv",
            "L": "b * In * S * Ninv - a * L",
            "In": "a * L - g * In + s * Q",
            "Q": "(1 - e) * g * In - s * Q",
        },
        "outputs": {
            "y": "In * Ninv",
        },
        "params": ("b", "Ninv", "a", "g", "s", "e"),
        "inputs": ("u",),
        "si_functions_seconds": 1.42, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "st": {
        "name": "St", "key": ":St", "line": 297,
        "states": {
            "S": "r * S - (e + a * W) * S - d * W * S + g * R",
            "R": "rR * R + (e + a * W) * S - dr * W * R - g * R",
            "W": "Dd * (T - W)",
        },
        "outputs": {
            "y1": "S + R",
            "y2": "T",
        },
        "params": ("r", "e", "a", "d", "g", "rR", "dr", "Dd", "T"),
        "inputs": (),
        "si_functions_seconds": 37.54, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "qy": {
        "name": "QY", "key": ":QY", "line": 307,
        "states": {
            "P0": "P1",
            "P1": "P2",
            "P2": "P3",
            "P3": "P4",
            "P4": ("-(Ks * M * siga1 * siga2 * P1 + (Ks * M * siga1 + Ks * M * siga2 + Ks * siga1 * siga2 + siga1 * "
                   "siga2 * M) * P2 + (Ks * M + Ks * siga1 + Ks * siga2 + M * siga1 + M * siga2 + siga1 * siga2) * "
                   "P3 + (Ks + M + siga1 + siga2) * P4) - (Mar * P5 + beta + beta_SA / (siga2 * M) * (P3 + P2 * (Ks "
                   "+ M + Mar) + P1 * (Ks * M + Ks * Mar + M * Mar) + P0 * Ks * M * Mar) + beta_SI / M * (P2 + P1 * "
                   "(Ks + Mar) + P0 * Ks * Mar) + beta_SA * phi / ((1 - phi) * siga2 * M) * (P3 + P2 * (Ks + M + "
                   "siga2) + P1 * (Ks * M + Ks * siga2 + M * siga2) + P0 * Ks * M * siga2)) * (alpa + Ks * M * "
                   "siga1 * siga2 * P0 + (Ks * M * siga1 + Ks * M * siga2 + Ks * siga1 * siga2 + siga1 * siga2 * M) "
                   "* P1 + (Ks * M + Ks * siga1 + Ks * siga2 + M * siga1 + M * siga2 + siga1 * siga2) * P2 + (Ks + "
                   "M + siga1 + siga2) * P3 + P4)"),
            "P5": ("-Mar * P5 - (beta + beta_SA / (siga2 * M) * (P3 + P2 * (Ks + M + Mar) + P1 * (Ks * M + Ks * Mar "
                   "+ M * Mar) + P0 * Ks * M * Mar) + beta_SI / M * (P2 + P1 * (Ks + Mar) + P0 * Ks * Mar) + "
                   "beta_SA * phi / ((1 - phi) * siga2 * M) * (P3 + P2 * (Ks + M + siga2) + P1 * (Ks * M + Ks * "
                   "siga2 + M * siga2) + P0 * Ks * M * siga2))"),
        },
        "outputs": {
            "y": "P0",
        },
        "params": ("Ks", "M", "siga1", "siga2", "Mar", "beta", "beta_SA", "beta_SI", "phi", "alpa"),
        "inputs": (),
        "si_functions_seconds": 49.21, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "fujita": {
        "name": "Fujita", "key": ":Fujita", "line": 389,
        "states": {
            "EGFR": ("EGFR_turnover * pro_EGFR + EGF_EGFR * reaction_1_k2 - EGFR * EGFR_turnover - EGF_EGFR * "
                     "reaction_1_k1"),
            "pEGFR": ("EGF_EGFR * reaction_9_k1 - pEGFR * reaction_4_k1 + pEGFR_Akt * reaction_2_k2 + pEGFR_Akt * "
                      "reaction_3_k1 - Akt * pEGFR * reaction_2_k1"),
            "pEGFR_Akt": "Akt * pEGFR * reaction_2_k1 - pEGFR_Akt * reaction_3_k1 - pEGFR_Akt * reaction_2_k2",
            "Akt": "pAkt * reaction_7_k1 + pEGFR_Akt * reaction_2_k2 - Akt * pEGFR * reaction_2_k1",
            "pAkt": ("pAkt_S6 * reaction_5_k2 - pAkt * reaction_7_k1 + pAkt_S6 * reaction_6_k1 + pEGFR_Akt * "
                     "reaction_3_k1 - S6 * pAkt * reaction_5_k1"),
            "S6": "pAkt_S6 * reaction_5_k2 + pS6 * reaction_8_k1 - S6 * pAkt * reaction_5_k1",
            "pAkt_S6": "S6 * pAkt * reaction_5_k1 - pAkt_S6 * reaction_6_k1 - pAkt_S6 * reaction_5_k2",
            "pS6": "pAkt_S6 * reaction_6_k1 - pS6 * reaction_8_k1",
            "EGF_EGFR": "EGF_EGFR * reaction_1_k1 - EGF_EGFR * reaction_9_k1 - EGF_EGFR * reaction_1_k2",
        },
        "outputs": {
            "y1": "a1 * (pEGFR + pEGFR_Akt)",
            "y2": "a2 * (pAkt + pAkt_S6)",
            "y3": "a3 * pS6",
        },
        "params": ("EGFR_turnover", "reaction_1_k2", "reaction_1_k1", "reaction_9_k1", "reaction_4_k1",
                   "reaction_2_k2", "reaction_3_k1", "reaction_2_k1", "reaction_7_k1", "reaction_5_k2",
                   "reaction_6_k1", "reaction_5_k1", "reaction_8_k1", "a1", "a2", "a3"),
        "inputs": ("pro_EGFR",),
        "si_functions_seconds": 2.5, "skip": False, "renamed": {},
        "fixed": {},
        "note": "pro_EGFR(t) has no equation: an input, as SI.jl's macro makes it.",
    },
    "llw1987": {
        "name": "LLW1987_io", "key": ":LLW", "line": 425,
        "states": {
            "x1": "-p1 * x1 + p2 * u",
            "x2": "-p3 * x2 + p4 * u",
            "x3": "-(p1 + p3) * x3 + (p4 * x1 + p2 * x2) * u",
        },
        "outputs": {
            "y1": "x3",
        },
        "params": ("p1", "p2", "p3", "p4"),
        "inputs": ("u",),
        "si_functions_seconds": 0.25, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "bilirubin2": {
        "name": "Bilirubin2_io", "key": ":Bilirubin", "line": 436,
        "states": {
            "x1": "-(k21 + k31 + k41 + k01) * x1 + k12 * x2 + k13 * x3 + k14 * x4 + u",
            "x2": "k21 * x1 - k12 * x2",
            "x3": "k31 * x1 - k13 * x3",
            "x4": "k41 * x1 - k14 * x4",
        },
        "outputs": {
            "y1": "x1",
        },
        "params": ("k21", "k31", "k41", "k01", "k12", "k13", "k14"),
        "inputs": ("u",),
        "si_functions_seconds": 4.08, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "hiv2": {
        "name": "HIV2_io", "key": ":HIV2", "line": 453,
        "states": {
            "x1": "-b * x1 * x4 - d * x1 + s",
            "x2": "b * q1 * x1 * x4 - k1 * x2 - w1 * x2",
            "x3": "b * q2 * x1 * x4 + k1 * x2 - w2 * x3",
            "x4": "-c * x4 + k2 * x3",
        },
        "outputs": {
            "y1": "x1",
            "y2": "x4",
        },
        "params": ("b", "d", "s", "q1", "k1", "w1", "q2", "w2", "c", "k2"),
        "inputs": (),
        "si_functions_seconds": 2.0, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "biohydrogenation": {
        "name": "Biohydrogenation_io", "key": ":Biohydrogenation", "line": 466,
        "states": {
            "x4": "-k5 * x4 / (k6 + x4)",
            "x5": "k5 * x4 / (k6 + x4) - k7 * x5 / (k8 + x5 + x6)",
            "x6": "k7 * x5 / (k8 + x5 + x6) - k9 * x6 * (k10 - x6) / k10",
            "x7": "k9 * x6 * (k10 - x6) / k10",
        },
        "outputs": {
            "y1": "x4",
            "y2": "x5",
        },
        "params": ("k5", "k6", "k7", "k8", "k9", "k10"),
        "inputs": (),
        "si_functions_seconds": 0.44, "skip": False, "renamed": {},
        "fixed": {},
        "note": "Julia `//` written `/` (same value: no `a / b // c` chain).",
    },
    "treatment": {
        "name": "Treatment_io", "key": ":Treatment", "line": 480,
        "states": {
            "S": "-b * S * In / N - d * b * S * Tr / N",
            "In": "b * S * In / N + d * b * S * Tr / N - (a + g) * In",
            "Tr": "g * In - nu * Tr",
            "N": "0",
        },
        "outputs": {
            "y1": "Tr",
            "y2": "N",
        },
        "params": ("b", "d", "a", "g", "nu"),
        "inputs": (),
        "si_functions_seconds": 0.44, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "seir_1": {
        "name": "SEIR_1_io", "key": ":SEIR1", "line": 494,
        "states": {
            "S": "-beta * S * I",
            "E": "beta * S * I - v * E",
            "I": "v * E - psi * I - (1 - psi) * gamma * I",
            "R": "gamma * Q + (1 - psi) * gamma * I",
            "Q": "-gamma * Q + psi * I",
        },
        "outputs": {
            "y1": "Q",
        },
        "params": ("beta", "v", "psi", "gamma"),
        "inputs": (),
        "si_functions_seconds": 0.56, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "jak_stat": {
        "name": "JAK-STAT 1", "key": ":JAK_STAT", "line": 507,
        "states": {
            "x1": "-t1 * x1 * 2 * u - t5 * x1 + t6 * x2",
            "x2": "t5 * x1 - t6 * x2",
            "x3": "t1 * 2 * u * x1 - t2 * x3 * (-x6 + 3)",
            "x4": "t2 * x3 * (-x6 + 3) - t3 * x4",
            "x5": "t3 * x4 - t4 * x5",
            "x6": "-t7 * x3 * x6 / (1 + t13 * x1) - t7 * x4 * x6 / (1 + t13 * x10) + t8 * (-x6 + 3) * 92",
            "x7": "-t9 * x7 * (-x6 + 3) + t10 * (-x7 + 165) * 92",
            "x8": "t11 * (-x7 + 165)",
            "x9": "-t12 * 2 * u * x9",
            "x10": "x8 * t14 / (t15 + x8) - t16 * x10",
        },
        "outputs": {
            "y1": "x1 + x3 + x4",
            "y2": "t18 * (x3 + x4 + x5 + (1 / 3 - x9))",
            "y3": "t19 * (x4 + x5)",
            "y4": "t20 * (-x6 + 3)",
            "y5": "t21 * x8",
            "y6": "t22 * x8 * t17 / t11",
            "y7": "x10",
            "y8": "-x7 + 165",
        },
        "params": ("t1", "t5", "t6", "t2", "t3", "t4", "t7", "t13", "t8", "t9", "t10", "t11", "t12", "t14", "t15",
                   "t16", "t18", "t19", "t20", "t21", "t22", "t17"),
        "inputs": ("u",),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "sir24": {
        "name": "SIR 24", "key": ":SIR24", "line": 536,
        "states": {
            "A": "0",
            "S": "A - mu + S - c * phi * I * S / (I + S)",
            "I": "-mu * I + c * phi * I * S / (I + S) - gamma * I - I * u1 / (S + I)",
            "R": "-mu * R + gamma * I + I * u1 / (S + I)",
        },
        "outputs": {
            "y1": "K * I",
        },
        "params": ("mu", "c", "phi", "gamma", "K"),
        "inputs": ("u1",),
        "si_functions_seconds": 0.36, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "sir21": {
        "name": "SIR 21", "key": ":SIR21", "line": 549,
        "states": {
            "S": "-beta * S * I / N - pp * S + q * C",
            "I": "beta * S * I / N - (r + mu) * I",
            "R": "r * I",
            "C": "pp * S - q * C",
            "D": "mu * I",
        },
        "outputs": {
            "y1": "N",
            "y2": "D",
            "y3": "C",
        },
        "params": ("beta", "N", "pp", "q", "r", "mu"),
        "inputs": (),
        "si_functions_seconds": 0.3, "skip": False, "renamed": {},
        "fixed": {},
        "note": ("SI.jl's 2023 model file (results/SIR 21/SIR 21.jl), on which the published time was measured, "
                 "is not this model: there states ['C', 'D', 'I', 'N', 'R', 'S'] where here ['C', 'D', 'I', 'R', "
                 "'S']; params ['beta', 'mu', 'pp', 'q', 'r'] where here ['N', 'beta', 'mu', 'pp', 'q', 'r']."),
    },
    "sir19": {
        "name": "SIR 19", "key": ":SIR19", "line": 564,
        "states": {
            "S": "-alpha * (I + J) * S",
            "I": "alpha * xi * S * (I + J) - beta * I",
            "J": "alpha * (1 - xi) * S * (I + J) - eta * J",
            "R": "beta * I",
            "U": "eta * J",
        },
        "outputs": {
            "y1": "R",
        },
        "params": ("alpha", "xi", "beta", "eta"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": ("SI.jl's 2023 model file results/SIR 19/SIR 19.jl holds the SIR 21 model (no published time "
                 "either way)."),
    },
    "sir6": {
        "name": "SIR 6", "key": ":SIR6", "line": 577,
        "states": {
            "S": "-beta * I * S / N",
            "I": "beta * I * S / N - gamma * I",
        },
        "outputs": {
            "y1": "I * K",
            "y2": "N",
        },
        "params": ("beta", "N", "gamma", "K"),
        "inputs": (),
        "si_functions_seconds": 0.2, "skip": False, "renamed": {},
        "fixed": {},
        "note": ("SI.jl's 2023 model file (results/SIR 6/SIR 6.jl), on which the published time was measured, is "
                 "not this model: there states ['I', 'N', 'R', 'S'] where here ['I', 'S']; params ['K', 'beta', "
                 "'gamma'] where here ['K', 'N', 'beta', 'gamma']."),
    },
    "seir34": {
        "name": "SEIR 34", "key": ":SEIR34", "line": 589,
        "states": {
            "A": "0",
            "S": "A - r * beta * S * I / N - mu * S",
            "E": "r * beta * S * I / N - epsilon * E - mu * E",
            "I": "epsilon * E - gamma * I - mu * I",
        },
        "outputs": {
            "y1": "K * I",
            "y2": "A",
            "y3": "N",
        },
        "params": ("r", "beta", "N", "mu", "epsilon", "gamma", "K"),
        "inputs": (),
        "si_functions_seconds": 0.39, "skip": False, "renamed": {},
        "fixed": {},
        "note": ("SI.jl's 2023 model file (results/SEIR 34/SEIR 34.jl), on which the published time was measured, "
                 "is not this model: there states ['A', 'E', 'I', 'N', 'R', 'S'] where here ['A', 'E', 'I', 'S']; "
                 "params ['K', 'beta', 'epsilon', 'gamma', 'mu', 'r'] where here ['K', 'N', 'beta', 'epsilon', "
                 "'gamma', 'mu', 'r']."),
    },
    "seir36_ref": {
        "name": "SEIR 36 ref", "key": ":SEIR36_ref", "line": 604,
        "states": {
            "S": "-beta * S * I / N - q * beta_d * S * Di / N + nu * N - mu_0 * S",
            "E": "beta * S * I / N + q * beta_d * S * Di / N - s * E - phi_e * E - mu_0 * E",
            "I": "s * E - gamma * I - mu_i * I - phi * I - mu_0 * I",
            "De": "phi_e * E - s_d * De - mu_0 * De",
            "Di": "phi * I + s_d * De - gamma_d * Di - mu_d * Di - mu_0 * Di",
            "F": "mu_i * I + mu_d * Di",
        },
        "outputs": {
            "y1": "De",
            "y2": "Di",
            "y5": "F",
            "y3": "N",
            "y4": "nu",
            "y6": "q",
        },
        "params": ("beta", "N", "beta_d", "nu", "mu_0", "s", "phi_e", "gamma", "mu_i", "phi", "s_d", "gamma_d",
                   "mu_d"),
        "inputs": ("q",),
        "si_functions_seconds": 0.78, "skip": False, "renamed": {},
        "fixed": {},
        "note": ("`q` appears as q(t) in E' (so SI.jl makes it an input) and bare in S' and y6; SI.jl maps the "
                 "bare name to the same input. SI.jl's 2023 model file (results/SEIR 36 ref/SEIR 36 ref.jl), on "
                 "which the published time was measured, is not this model: there states ['De', 'Di', 'E', 'F', "
                 "'I', 'N', 'R', 'S', 'nu', 'q'] where here ['De', 'Di', 'E', 'F', 'I', 'S']; params ['beta', "
                 "'beta_d', 'gamma', 'gamma_d', 'mu_0', 'mu_d', 'mu_i', 'phi', 'phi_e', 's', 's_d'] where here "
                 "['N', 'beta', 'beta_d', 'gamma', 'gamma_d', 'mu_0', 'mu_d', 'mu_i', 'nu', 'phi', 'phi_e', 's', "
                 "'s_d']; inputs [] where here ['q']."),
    },
    "tumor_hu": {
        "name": "TumorHu2019", "key": ":TumorHu", "line": 627,
        "states": {
            "x": "(r1 + b1 * y) * x * (1 - b1 * x) - d1 * x * z / (m1 + w)",
            "y": "(r2 + b2 * w / (k2 + w)) * y * (1 - b2 * y) - mu2 * y",
            "z": "b3 * z * v / ((k3 + v) * (m3 + w)) - mu3 * z + r3",
            "w": "b4 * x * z / (k4 + x) - mu4 * w + r4 * x * y / (m4 + v)",
            "v": "b5 * x * z / (k5 + x) - mu5 * v",
        },
        "outputs": {
            "y1": "z",
        },
        "params": ("r1", "b1", "d1", "m1", "r2", "b2", "k2", "mu2", "b3", "k3", "m3", "mu3", "r3", "b4", "k4", "mu4",
                   "r4", "m4", "b5", "k5", "mu5"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "tumor_pillis": {
        "name": "TumorPillis2007", "key": ":TumorPillis", "line": 644,
        "states": {
            "T": "a * T * (1 - b * T) - c1 * N * T - D * T - KT * M * T",
            "L": "-m * L - q * L * T - ucte * L**2 + r2 * C * T + pI * L * I / (gI + I) + u1 - KL * M * L",
            "N": "alpha1 - f * N + g * T * N / (h + T) - p * N * T - KN * M * N",
            "C": "alpha2 - beta * C - KC * M * C",
            "I": "pt * T * L / (gt + T) + w * L * I - muI * I + u2",
            "M": "-gamma * M + u1",
        },
        "outputs": {
            "y1": "L",
            "y2": "N",
            "y3": "M",
        },
        "params": ("a", "b", "c1", "KT", "m", "q", "ucte", "r2", "pI", "gI", "KL", "alpha1", "f", "g", "h", "p", "KN",
                   "alpha2", "beta", "KC", "pt", "gt", "w", "muI", "gamma"),
        "inputs": ("D", "u1", "u2"),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "D(t) has no equation: an input, as SI.jl's macro makes it.",
    },
    "seir2t": {
        "name": "SEIR2T", "key": ":SEIR2T", "line": 668,
        "states": {
            "S": "-b * S * In / N",
            "E": "b * S * In / N - nu * E",
            "In": "nu * E - a * In",
            "Cu": "nu * E",
        },
        "outputs": {
            "y1": "Cu",
            "y2": "N",
        },
        "params": ("b", "N", "nu", "a"),
        "inputs": (),
        "si_functions_seconds": 0.23, "skip": False, "renamed": {},
        "fixed": {},
        "note": ("SI.jl's 2023 model file (results/SEIR2T/SEIR2T.jl), on which the published time was measured, "
                 "is not this model: there states ['Cu', 'E', 'In', 'N', 'S'] where here ['Cu', 'E', 'In', 'S']; "
                 "params ['a', 'b', 'nu'] where here ['N', 'a', 'b', 'nu']."),
    },
    "seirt": {
        "name": "SEIRT", "key": ":SEIRT", "line": 681,
        "states": {
            "S": "-beta * I * (S / N)",
            "E": "beta * I * (S / N) - alpha * E",
            "I": "alpha * E - lam * I",
        },
        "outputs": {
            "y1": "I",
            "y2": "N",
        },
        "params": ("beta", "N", "alpha", "lam"),
        "inputs": (),
        "si_functions_seconds": 0.36, "skip": False, "renamed": {"lambda": "lam"},
        "fixed": {},
        "note": ("SI.jl's 2023 model file (results/SEIRT/SEIRT.jl), on which the published time was measured, is "
                 "not this model: there states ['E', 'I', 'N', 'R', 'S'] where here ['E', 'I', 'S']; params "
                 "['alpha', 'beta', 'lambda'] where here ['N', 'alpha', 'beta', 'lam']."),
    },
    "seuir": {
        "name": "SEUIR", "key": ":SEUIR", "line": 693,
        "states": {
            "S": "-beta * (U + I) * (S / N)",
            "E": "beta * (U + I) * (S / N) - E * z",
            "U": "(z - w) * E - U * d",
            "I": "w * E - I * d",
        },
        "outputs": {
            "y1": "I",
        },
        "params": ("beta", "N", "z", "w", "d"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": ("SI.jl's 2023 model file (results/SEUIR/SEUIR.jl), on which the published time was measured, is "
                 "not this model: there states ['E', 'I', 'R', 'S', 'U'] where here ['E', 'I', 'S', 'U']."),
    },
    "bruno2016": {
        "name": "Bruno2016", "key": ":Bruno2016", "line": 705,
        "states": {
            "beta": "-kbeta * beta",
            "cry": "-kcryOH * cry - kcrybeta * cry",
            "zea": "-kzea * zea",
            "beta10": "kbeta * beta + kcryOH * cry - kbeta10 * beta10",
            "OHbeta10": "kcrybeta * cry + kzea * zea - kOHbeta10 * OHbeta10",
            "betaio": "kbeta * beta + kcrybeta * cry + kbeta10 * beta10",
            "OHbetaio": "kcryOH * cry + kzea * zea + kOHbeta10 * OHbeta10",
        },
        "outputs": {
            "y1": "beta",
            "y2": "beta10",
        },
        "params": ("kbeta", "kcryOH", "kcrybeta", "kzea", "kbeta10", "kOHbeta10"),
        "inputs": (),
        "si_functions_seconds": 0.19, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "transfection": {
        "name": "Transfection_4State", "key": ":Transfection", "line": 721,
        "states": {
            "mRNA": "-d1 * mRNA - d2 * mRNA * enz",
            "GFP": "kTL * mRNA - b * GFP",
            "enz": "d3 * mRNAenz - d2 * mRNA * enz",
            "mRNAenz": "-d3 * mRNAenz + d2 * mRNA * enz",
        },
        "outputs": {
            "y1": "GFP",
        },
        "params": ("d1", "d2", "kTL", "b", "d3"),
        "inputs": (),
        "si_functions_seconds": 0.23, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "p53": {
        "name": "p53", "key": ":p53", "line": 733,
        "states": {
            "x1": "(p1 * x4) - (p3 * x1) - p4 * ((x1**2 / (p5 + x1)) * (1 + (p6 * u1 / (p7 + u1))))",
            "x2": "p8 - (p9 * x2) - p10 * ((x1 * x2 / (p11 + x2)) * (1 + (p12 * u1 / (p13 + u1))))",
            "x3": "p14 - (p15 * x3) - p16 * x1 * x3 * (1 - p18 * u1) / (p17 + x3)",
            "x4": ("p20 - p21 * (1 - p24) * (1 - p25) / ((p22**4) + 1) - (p20 * x4) + (p21 * (x3**4)) + (1 + p23 * "
                   "u1) * (1 - p24 * x1) * (1 - p25 * x2) / (p22**4 + x3**4)"),
        },
        "outputs": {
            "y1": "x1",
            "y2": "x2",
            "y3": "x3",
            "y4": "x4",
        },
        "params": ("p1", "p3", "p4", "p5", "p6", "p7", "p8", "p9", "p10", "p11", "p12", "p13", "p14", "p15", "p16",
                   "p18", "p17", "p20", "p21", "p24", "p25", "p22", "p23"),
        "inputs": ("u1",),
        "si_functions_seconds": 1.21, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "crauste": {
        "name": "Crauste_SI", "key": ":Crauste", "line": 760,
        "states": {
            "N": "-N * mu_N - N * P * delta_NE",
            "E": "N * P * delta_NE - E**2 * mu_EE - E * delta_EL + E * P * rho_E",
            "S": "S * delta_EL - S * delta_LM - S**2 * mu_LL - E * S * mu_LE",
            "M": "S * delta_LM - mu_M * M",
            "P": "P**2 * rho_P - P * mu_P - E * P * mu_PE - S * P * mu_PL",
        },
        "outputs": {
            "y1": "N",
            "y2": "E + S",
            "y3": "M",
        },
        "params": ("mu_N", "delta_NE", "mu_EE", "delta_EL", "rho_E", "delta_LM", "mu_LL", "mu_LE", "mu_M", "rho_P",
                   "mu_P", "mu_PE", "mu_PL"),
        "inputs": (),
        "si_functions_seconds": 0.47, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "hdnl": {
        "name": "HighDimNonLin", "key": ":HDNL", "line": 779,
        "states": {
            "x1": "-vm * x1 / (km + x1) - p1 * x1 + u",
            "x2": "p1 * x1 - p2 * x2",
            "x3": "p2 * x2 - p3 * x3",
            "x4": "p3 * x3 - p4 * x4",
            "x5": "p4 * x4 - p5 * x5",
            "x6": "p5 * x5 - p6 * x6",
            "x7": "p6 * x6 - p7 * x7",
            "x8": "p7 * x7 - p8 * x8",
            "x9": "p8 * x8 - p9 * x9",
            "x10": "p9 * x9 - p10 * x10",
            "x11": "p10 * x10 - p11 * x11",
            "x12": "p11 * x11 - p12 * x12",
            "x13": "p12 * x12 - p13 * x13",
            "x14": "p13 * x13 - p14 * x14",
            "x15": "p14 * x14 - p15 * x15",
            "x16": "p15 * x15 - p16 * x16",
            "x17": "p16 * x16 - p17 * x17",
            "x18": "p17 * x17 - p18 * x18",
            "x19": "p18 * x18 - p19 * x19",
            "x20": "p19 * x19 - p20 * x20",
        },
        "outputs": {
            "y1": "x1",
            "y2": "x2",
            "y3": "x3",
            "y4": "x4",
            "y5": "x5",
            "y6": "x6",
            "y7": "x7",
            "y8": "x8",
            "y9": "x9",
            "y10": "x10",
            "y11": "x11",
            "y12": "x12",
            "y13": "x13",
            "y14": "x14",
            "y15": "x15",
            "y16": "x16",
            "y17": "x17",
            "y18": "x18",
            "y19": "x19",
            "y20": "x20",
        },
        "params": ("vm", "km", "p1", "p2", "p3", "p4", "p5", "p6", "p7", "p8", "p9", "p10", "p11", "p12", "p13",
                   "p14", "p15", "p16", "p17", "p18", "p19", "p20"),
        "inputs": ("u",),
        "si_functions_seconds": 20.55, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "kd1999": {
        "name": "KD1999", "key": ":KD1999", "line": 826,
        "states": {
            "Ca": "u1 * (Ca0 - Ca) / V - k0 * Arr * Ca",
            "Cb": "-u1 * Cb / V + k0 * Arr * Ca",
            "T": "u1 * (Ta - T) / V - (k0 * Arr * Ca * DH + UA * (Tj - T) / V) / (ro * cp)",
            "Tj": "u2 * (Th - Tj) / Vh - UA / (roh * cph) * (Tj - T) / Vh",
            "Arr": ("E * Arr / (R * T**2) * (u1 * (Ta - T) / V - (k0 * Arr * Ca * DH + UA * (Tj - T) / V) / (ro * "
                    "cp))"),
        },
        "outputs": {
            "y1": "Cb",
            "y2": "T",
        },
        "params": ("Ca0", "V", "k0", "Ta", "DH", "UA", "ro", "cp", "Th", "Vh", "roh", "cph", "E", "R"),
        "inputs": ("u1", "u2"),
        "si_functions_seconds": 0.97, "skip": False, "renamed": {},
        "fixed": {},
        "note": ("Ca' uses a bare `Arr` (no (t)); SI.jl's macro maps a bare name of a time-dependent variable to "
                 "that variable, so it is the state Arr."),
    },
    "cgv1990": {
        "name": "CGV1990", "key": ":CGV1990", "line": 846,
        "states": {
            "q1": "k4 * q3 - (k3 + k7) * q1 + u",
            "q3": ("k3 * q1 - k4 * q3 - k5 * q3 * (R * V3 - q35) + k6 * q35 - k5 * q3 * (5 * V36 / V3) * (S * V36 - "
                   "q36) + k6 * q36"),
            "q35": "k5 * q3 * (R * V3 - q35) - k6 * q35",
            "q36": "k5 * q3 * (5 * V36 / V3) * (S * V36 - q36) - k6 * q36",
            "q7": "k7 * q1",
        },
        "outputs": {
            "y1": "q7",
        },
        "params": ("k4", "k3", "k7", "k5", "R", "V3", "k6", "V36", "S"),
        "inputs": ("u",),
        "si_functions_seconds": 2.25, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "leukaemia_leon2021": {
        "name": "LeukaemiaLeon2021", "key": ":LeukaemiaLeon2021", "line": 861,
        "states": {
            "C": "rhoc * (L + B) * C + rhob * I * C - C / taoc",
            "L": "rhol * L - alpha * L * C",
            "B": "I / taoi - alpha * B * C - B / taob",
            "P": "rhop * (2 * ap * (1 / (1 + ks * (P + I))) - 1) * P - P / taop",
            "I": "rhoi * (2 * ai * (1 / (1 + ks * (P + I))) - 1) * I - I / taoi + P / taop - alpha * beta * I * C",
        },
        "outputs": {
            "y1": "C",
            "y2": "L",
            "y3": "P + B + I",
        },
        "params": ("rhoc", "rhob", "taoc", "rhol", "alpha", "taoi", "taob", "rhop", "ap", "ks", "taop", "rhoi", "ai",
                   "beta"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "lipolysis": {
        "name": "Ruminal lipolysis", "key": ":Lipolysis", "line": 878,
        "states": {
            "x1": "-x1 * x5 / (k2 + x1)",
            "x2": "2 * x1 * x5 / ((k2 + x1) * 3) - k4 * x2",
            "x3": "k4 * (x2) / 2 - k4 * x3",
            "x4": "x1 * x5 / (3 * (k2 + x1)) + k4 * (x2) / 2 + k4 * x3",
            "x5": "-k3 * x5",
        },
        "outputs": {
            "y1": "x1",
            "y2": "x2 + x3",
            "y3": "x4",
        },
        "params": ("k2", "k4", "k3"),
        "inputs": (),
        "si_functions_seconds": 0.21, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "clv1_2o": {
        "name": "cLV1 (2o)", "key": ":cLV1", "line": 893,
        "states": {
            "pi1": ("pi1 * ((g1 + A11 * pi1 + A12 * pi2 + A13 * pi3 + B11 * u1) - pi1 * (g1 + A11 * pi1 + A12 * pi2 "
                    "+ A13 * pi3 + B11 * u1) + pi2 * (g2 + A21 * pi1 + A22 * pi2 + A23 * pi3 + B21 * u1))"),
            "pi2": ("pi2 * ((g2 + A21 * pi1 + A22 * pi2 + A23 * pi3 + B21 * u1) - pi1 * (g1 + A11 * pi1 + A12 * pi2 "
                    "+ A13 * pi3 + B11 * u1) + pi2 * (g2 + A21 * pi1 + A22 * pi2 + A23 * pi3 + B21 * u1))"),
            "pi3": ("pi3 * ((g3 + A31 * pi1 + A32 * pi2 + A33 * pi3 + B31 * u1) - pi1 * (g1 + A11 * pi1 + A12 * pi2 "
                    "+ A13 * pi3 + B11 * u1) + pi2 * (g2 + A21 * pi1 + A22 * pi2 + A23 * pi3 + B21 * u1))"),
        },
        "outputs": {
            "y1": "pi1",
            "y2": "pi2",
        },
        "params": ("g1", "A11", "A12", "A13", "B11", "g2", "A21", "A22", "A23", "B21", "g3", "A31", "A32", "A33",
                   "B31"),
        "inputs": ("u1",),
        "si_functions_seconds": 0.8, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "clv1_1o": {
        "name": "cLV1 (1o)", "key": ":cLV2", "line": 932,
        "states": {
            "pi1": ("pi1 * ((g1 + A11 * pi1 + A12 * pi2 + A13 * pi3 + B11 * u1) - pi1 * (g1 + A11 * pi1 + A12 * pi2 "
                    "+ A13 * pi3 + B11 * u1) + pi2 * (g2 + A21 * pi1 + A22 * pi2 + A23 * pi3 + B21 * u1))"),
            "pi2": ("pi2 * ((g2 + A21 * pi1 + A22 * pi2 + A23 * pi3 + B21 * u1) - pi1 * (g1 + A11 * pi1 + A12 * pi2 "
                    "+ A13 * pi3 + B11 * u1) + pi2 * (g2 + A21 * pi1 + A22 * pi2 + A23 * pi3 + B21 * u1))"),
            "pi3": ("pi3 * ((g3 + A31 * pi1 + A32 * pi2 + A33 * pi3 + B31 * u1) - pi1 * (g1 + A11 * pi1 + A12 * pi2 "
                    "+ A13 * pi3 + B11 * u1) + pi2 * (g2 + A21 * pi1 + A22 * pi2 + A23 * pi3 + B21 * u1))"),
        },
        "outputs": {
            "y1": "pi1",
        },
        "params": ("g1", "A11", "A12", "A13", "B11", "g2", "A21", "A22", "A23", "B21", "g3", "A31", "A32", "A33",
                   "B31"),
        "inputs": ("u1",),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "gen_lv_1o": {
        "name": "generalizedLoktaVolterra (1o)", "key": ":genLV", "line": 969,
        "states": {
            "x1": "r1 * x1 + beta11 * x1**2 + beta12 * x1 * x2",
            "x2": "r2 * x2 + beta21 * x1 * x2 + beta22 * x2**2",
        },
        "outputs": {
            "y1": "x1",
        },
        "params": ("r1", "beta11", "beta12", "r2", "beta21", "beta22"),
        "inputs": (),
        "si_functions_seconds": 0.18, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "pivastatin": {
        "name": "Pivastatin", "key": ":Pivastatin", "line": 979,
        "states": {
            "x1": "k3 * x3 - r3 * x1 - k1 * x1 * (T0 - x2) + r1 * x2",
            "x2": "k1 * x1 * (T0 - x2) - (r1 + k2) * x2",
            "x3": "r3 * x1 - (k3 + k4) * x3 + k2 * x2",
        },
        "outputs": {
            "y1": "k * (x2 + x3)",
        },
        "params": ("k3", "r3", "k1", "T0", "r1", "k2", "k4", "k"),
        "inputs": (),
        "si_functions_seconds": 8.44, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "lincomp1": {
        "name": "Linear_compartment_hard_1", "key": ":Lincomp1", "line": 991,
        "states": {
            "x1": "-a_2_1*x1 + u1 + a_1_5*x5",
            "x2": "a_2_1*x1 - a_3_2*x2 - a_0_2*x2",
            "x3": "a_3_2*x2 - a_4_3*x3 - a_0_3*x3",
            "x4": "a_4_3*x3 - a_5_4*x4",
            "x5": "a_5_4*x4 - a_1_5*x5",
        },
        "outputs": {
            "y5": "x5",
        },
        "params": ("a_2_1", "a_3_2", "a_4_3", "a_5_4", "a_1_5", "a_0_2", "a_0_3"),
        "inputs": ("u1",),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": ("linear_compartment_model([[2], [3], [4], [5], [1]], inputs = [1], outputs = [5], leaks = [2, "
                 "3]) (src/lincomp.jl) written out: rate a_j_i on the edge i -> j, a_0_i a leak, u1 the input."),
    },
    "lincomp2": {
        "name": "Linear_compartment_hard_2", "key": ":Lincomp2", "line": 1001,
        "states": {
            "x1": "-a_2_1*x1 + u1 + a_1_5*x5",
            "x2": "a_2_1*x1 - a_3_2*x2 - a_0_2*x2",
            "x3": "a_3_2*x2 - a_4_3*x3",
            "x4": "a_4_3*x3 - a_5_4*x4 - a_0_4*x4",
            "x5": "a_5_4*x4 - a_1_5*x5",
        },
        "outputs": {
            "y5": "x5",
        },
        "params": ("a_2_1", "a_3_2", "a_4_3", "a_5_4", "a_1_5", "a_0_2", "a_0_4"),
        "inputs": ("u1",),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": ("linear_compartment_model([[2], [3], [4], [5], [1]], inputs = [1], outputs = [5], leaks = [2, "
                 "4]) (src/lincomp.jl) written out: rate a_j_i on the edge i -> j, a_0_i a leak, u1 the input."),
    },
    "covid1": {
        "name": "Covid model (Gevertz et al)", "key": ":Covid1", "line": 1012,
        "states": {
            "Sd": "-es * ba * (An + ea * Ad) * Sd - h1 * Sd + h2 * Sn - es * bi * Sd * I",
            "Sn": "-bi * Sn * I - ba * (An + ea * Ad) * Sn + h1 * Sd - h2 * Sn",
            "Ad": "es * bi * Sd * I + es * ba * (An + ea * Ad) * Sd + h2 * An - gai * Ad - h1 * Ad",
            "An": "bi * Sn * I + ba * (An + ea * Ad) * Sn + h1 * Ad - gai * An - h2 * An",
            "I": "f * gai * (Ad + An) - delta * I - gir * I",
        },
        "outputs": {
            "y1": "Sd",
            "y2": "I",
        },
        "params": ("es", "ba", "ea", "h1", "h2", "bi", "gai", "f", "delta", "gir"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "covid2": {
        "name": "Covid model (Gallina)", "key": ":Covid2", "line": 1031,
        "states": {
            "S": "b * (S + I + A + Q + J + R) - S * (l * I + l * ea * eq * Q + l * ea * A + l * ej * J + d1)",
            "I": "k1 * A - (g1 + m2 + d2) * I",
            "A": "S * (l * I + l * ea * eq * Q + l * ea * A + l * ej * J) - (k1 + m1 + d4) * A",
            "Q": "m1 * A - (k2 + d5) * Q",
            "J": "k2 * Q + m2 * I - (g2 + d6) * J",
            "R": "g1 * I + g2 * J - d3 * R",
        },
        "outputs": {
            "y1": "Q",
            "y2": "J",
        },
        "params": ("b", "l", "ea", "eq", "ej", "d1", "k1", "g1", "m2", "d2", "m1", "d4", "k2", "d5", "g2", "d6", "d3"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "covid3": {
        "name": "Covid model (Chitnis)", "key": ":Covid3", "line": 1048,
        "states": {
            "S": "L - r * b * S * I / N - m * S",
            "E": "b * S * I / N - e * E - m * E",
            "I": "e * E - g * I - m * I",
        },
        "outputs": {
            "y": "K * I",
        },
        "params": ("L", "r", "b", "N", "m", "e", "g", "K"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "ovarian_follicle": {
        "name": "Ovarian follicle population dynamics", "key": ":Ovarian_follicle", "line": 1058,
        "states": {
            "Y2": "m1 * Y1 - D2 * Y2",
            "Y1": "Y0 - D1 * Y1",
            "Y3": "m2 * Y2 - D3 * Y3",
            "Y4": "m3 * Y3 - D4 * Y4",
            "Z0": "-E0 * Z0",
            "Y0": "-D0 * Y0",
            "Z1": "Z0 - E1 * Z1 - (n1 + f1 * w1) * (w2**20 / (Tau + w2**20)) * Z1",
            "Z2": "(n1 + f1 * w1) * (w2**20 / (Tau + w2**20)) * Z1 - E2 * Z2",
            "Z3": "n2 * Z2 - E3 * Z3",
            "w1": ("-n * w1 * (1 - w1) * (m2 * Y2 + (m3 - D3) * Y3 - D4 * Y4 + n2 * Z2 + (n3 - E3) * Z3 - E4 * (-E0 "
                   "* Y2 * D1 * E2 * m2 * E4 * D0 * m3 * E3 - E0 * n3 * D2 * E1 * D1 * I1 * n2 * D4 * D0 * D3 - E0 "
                   "* n3 * D2 * E1 * Y1 * n2 * D4 * D0 * D3 - E0 * n3 * D2 * E1 * Y0 * n2 * D4 * D3 - E0 * n3 * D2 "
                   "* D1 * Z2 * n2 * D4 * D0 * D3 - E0 * n3 * D2 * D1 * Z1 * n2 * D4 * D0 * D3 - E0 * n3 * D2 * D1 "
                   "* Z3 * E2 * D4 * D0 * D3 - E0 * D2 * D1 * I4 * E2 * E4 * D4 * D0 * D3 * E3 - E0 * D2 * D1 * Y3 "
                   "* E2 * E4 * D0 * m3 * E3 + E0 * D2 * D1 * E2 * J3 * E4 * D4 * D0 * D3 * E3 - E0 * D2 * D1 * E2 "
                   "* E4 * Y4 * D0 * D3 * E3 - E0 * Y1 * m1 * E2 * m2 * E4 * D0 * m3 * E3 - E0 * Y0 * m1 * E2 * m2 "
                   "* E4 * m3 * E3 - n3 * D2 * D1 * Z0 * n2 * D4 * D0 * D3) / (E0 * D2 * D1 * E2 * D4 * D0 * D3 * "
                   "E3)) / (Y3 + Y4 + Z3 + (-E0 * Y2 * D1 * E2 * m2 * E4 * D0 * m3 * E3 - E0 * n3 * D2 * E1 * D1 * "
                   "I1 * n2 * D4 * D0 * D3 - E0 * n3 * D2 * E1 * Y1 * n2 * D4 * D0 * D3 - E0 * n3 * D2 * E1 * Y0 * "
                   "n2 * D4 * D3 - E0 * n3 * D2 * D1 * Z2 * n2 * D4 * D0 * D3 - E0 * n3 * D2 * D1 * Z1 * n2 * D4 * "
                   "D0 * D3 - E0 * n3 * D2 * D1 * Z3 * E2 * D4 * D0 * D3 - E0 * D2 * D1 * I4 * E2 * E4 * D4 * D0 * "
                   "D3 * E3 - E0 * D2 * D1 * Y3 * E2 * E4 * D0 * m3 * E3 + E0 * D2 * D1 * E2 * J3 * E4 * D4 * D0 * "
                   "D3 * E3 - E0 * D2 * D1 * E2 * E4 * Y4 * D0 * D3 * E3 - E0 * Y1 * m1 * E2 * m2 * E4 * D0 * m3 * "
                   "E3 - E0 * Y0 * m1 * E2 * m2 * E4 * m3 * E3 - n3 * D2 * D1 * Z0 * n2 * D4 * D0 * D3) / (E0 * D2 "
                   "* D1 * E2 * D4 * D0 * D3 * E3))"),
            "w2": "1",
            "I1": "Y1 + Z1",
            "I4": ("Y4 + (-E0 * Y2 * D1 * E2 * m2 * E4 * D0 * m3 * E3 - E0 * n3 * D2 * E1 * D1 * I1 * n2 * D4 * D0 "
                   "* D3 - E0 * n3 * D2 * E1 * Y1 * n2 * D4 * D0 * D3 - E0 * n3 * D2 * E1 * Y0 * n2 * D4 * D3 - E0 "
                   "* n3 * D2 * D1 * Z2 * n2 * D4 * D0 * D3 - E0 * n3 * D2 * D1 * Z1 * n2 * D4 * D0 * D3 - E0 * n3 "
                   "* D2 * D1 * Z3 * E2 * D4 * D0 * D3 - E0 * D2 * D1 * I4 * E2 * E4 * D4 * D0 * D3 * E3 - E0 * D2 "
                   "* D1 * Y3 * E2 * E4 * D0 * m3 * E3 + E0 * D2 * D1 * E2 * J3 * E4 * D4 * D0 * D3 * E3 - E0 * D2 "
                   "* D1 * E2 * E4 * Y4 * D0 * D3 * E3 - E0 * Y1 * m1 * E2 * m2 * E4 * D0 * m3 * E3 - E0 * Y0 * m1 "
                   "* E2 * m2 * E4 * m3 * E3 - n3 * D2 * D1 * Z0 * n2 * D4 * D0 * D3) / (E0 * D2 * D1 * E2 * D4 * "
                   "D0 * D3 * E3)"),
        },
        "outputs": {
            "O1": "Y1 + Z1",
            "O2": "Y2 + Z2",
            "O3": "Y3 + Z3",
            "O4": ("Y4 + (-E0 * Y2 * D1 * E2 * m2 * E4 * D0 * m3 * E3 - E0 * n3 * D2 * E1 * D1 * I1 * n2 * D4 * D0 "
                   "* D3 - E0 * n3 * D2 * E1 * Y1 * n2 * D4 * D0 * D3 - E0 * n3 * D2 * E1 * Y0 * n2 * D4 * D3 - E0 "
                   "* n3 * D2 * D1 * Z2 * n2 * D4 * D0 * D3 - E0 * n3 * D2 * D1 * Z1 * n2 * D4 * D0 * D3 - E0 * n3 "
                   "* D2 * D1 * Z3 * E2 * D4 * D0 * D3 - E0 * D2 * D1 * I4 * E2 * E4 * D4 * D0 * D3 * E3 - E0 * D2 "
                   "* D1 * Y3 * E2 * E4 * D0 * m3 * E3 + E0 * D2 * D1 * E2 * J3 * E4 * D4 * D0 * D3 * E3 - E0 * D2 "
                   "* D1 * E2 * E4 * Y4 * D0 * D3 * E3 - E0 * Y1 * m1 * E2 * m2 * E4 * D0 * m3 * E3 - E0 * Y0 * m1 "
                   "* E2 * m2 * E4 * m3 * E3 - n3 * D2 * D1 * Z0 * n2 * D4 * D0 * D3) / (E0 * D2 * D1 * E2 * D4 * "
                   "D0 * D3 * E3)"),
            "O6": "w2",
            "O7": "I1",
            "O8": ("J1 - (E1 * D1 * D2 * I1 + D1 * D2 * (Z1 + Z2 + Z0 / E0) + D1 * E2 * Y2 + (D2 * E1 + m1 * E2) * "
                   "(Y1 + Y0 / D0)) / (D1 * E2 * D2)"),
            "O9": ("J2 - (E1 * n2 * D1 * D2 * D3 * I1 + n2 * D1 * D2 * D3 * (Z0 / E0 + Z1 + Z2 + E2 * Z3 / n2) + "
                   "(n2 * E1 * D2 * D3 + m1 * m2 * E2 * E3) * (Y1 + Y0 / D0) + (m2 * D1 * E2 * E3) * (Y2 + D2 * Y3 "
                   "/ m2)) / (D1 * E2 * D2 * E3 * D3)"),
            "O10": "I4",
        },
        "params": ("m1", "D2", "D1", "m2", "D3", "m3", "D4", "E0", "D0", "E1", "n1", "f1", "Tau", "E2", "n2", "E3",
                   "n", "n3", "E4", "J3", "J1", "J2"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": ("Julia `//` written `/`: `//` binds tighter than `*` in Julia, but no `a / b // c` chain occurs, "
                 "so the value is unchanged."),
    },
    "influenza_mb1": {
        "name": "Immune response to influenza (MB1 model)", "key": ":Influenza_MB1", "line": 1170,
        "states": {
            "U": "-beta * U * V",
            "I": "beta * U * V - d_I * T * I",
            "V": "p * I - c * V",
            "T": "s_T - 0.011 * T + r * T * (V / (V + k_T))",
        },
        "outputs": {
            "y1": "V",
            "y2": "T",
        },
        "params": ("beta", "d_I", "p", "c", "s_T", "r", "k_T"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "0.011 is a decimal literal: SI.jl rationalizes it to 11//1000, nlobs parses it to 11/1000.",
    },
    "influenza_mb2": {
        "name": "Immune response to influenza (MB2 model)", "key": ":Influenza_MB2", "line": 1183,
        "states": {
            "U": "-beta * U * V",
            "I": "beta * U * V - d_I * T * I",
            "V": "p * I - c * V",
            "T": "s_T - 0.011 * T + r * T * (V / (V + k_T)) - c_T * (1 / (1 + V**2))",
        },
        "outputs": {
            "y1": "V",
            "y2": "T",
        },
        "params": ("beta", "d_I", "p", "c", "s_T", "r", "k_T", "c_T"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "0.011 -> 11/1000 (as SI.jl's rationalize and nlobs's parser).",
    },
    "influenza_mb3": {
        "name": "Immune response to influenza (MB3 model)", "key": ":Influenza_MB3", "line": 1195,
        "states": {
            "U": "-beta * U * V",
            "I": "beta * U * V - d_I * T * I",
            "V": "p * I - c * V",
            "T": "s_T - d_T * T + r * T * (V / (V + k_T))",
        },
        "outputs": {
            "y1": "V",
            "y2": "T",
        },
        "params": ("beta", "d_I", "p", "c", "s_T", "d_T", "r", "k_T"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "influenza_mb4": {
        "name": "Immune response to influenza (MB4 model)", "key": ":Influenza_MB4", "line": 1207,
        "states": {
            "U": "-beta * U * V",
            "I": "beta * U * V - d_I * T * I",
            "V": "p * I - c * V",
            "T": "s_T - d_T * T + r * T * (V / (V + k_T)) - c_T * (1 / (1 + V**2))",
        },
        "outputs": {
            "y1": "V",
            "y2": "T",
        },
        "params": ("beta", "d_I", "p", "c", "s_T", "d_T", "r", "k_T", "c_T"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "influenza_md1": {
        "name": "Immune response to influenza (MD1 model)", "key": ":Influenza_MD1", "line": 1219,
        "states": {
            "U": "-beta * U * V",
            "I": "beta * U * V - d_I * T * I",
            "V": "p * I - c * V",
            "T": "s_T - 0.011 * T + r * T * V",
        },
        "outputs": {
            "y1": "V",
            "y2": "T",
        },
        "params": ("beta", "d_I", "p", "c", "s_T", "r"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "0.011 -> 11/1000 (as SI.jl's rationalize and nlobs's parser).",
    },
    "influenza_md2": {
        "name": "Immune response to influenza (MD2 model)", "key": ":Influenza_MD2", "line": 1231,
        "states": {
            "U": "-beta * U * V",
            "I": "beta * U * V - d_I * T * I",
            "V": "p * I - c * V",
            "T": "s_T - 0.011 * T + r * T * V - c_T * (1 / (1 + V**2))",
        },
        "outputs": {
            "y1": "V",
            "y2": "T",
        },
        "params": ("beta", "d_I", "p", "c", "s_T", "r", "c_T"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "0.011 -> 11/1000 (as SI.jl's rationalize and nlobs's parser).",
    },
    "influenza_md3": {
        "name": "Immune response to influenza (MD3 model)", "key": ":Influenza_MD3", "line": 1243,
        "states": {
            "U": "-beta * U * V",
            "I": "beta * U * V - d_I * T * I",
            "V": "p * I - c * V",
            "T": "s_T - d_T * T + r * T * V",
        },
        "outputs": {
            "y1": "V",
            "y2": "T",
        },
        "params": ("beta", "d_I", "p", "c", "s_T", "d_T", "r"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "influenza_md4": {
        "name": "Immune response to influenza (MD4 model)", "key": ":Influenza_MD4", "line": 1255,
        "states": {
            "U": "-beta * U * V",
            "I": "beta * U * V - d_I * T * I",
            "V": "p * I - c * V",
            "T": "s_T - d_T * T + r * T * V - c_T * (1 / (1 + V**2))",
        },
        "outputs": {
            "y1": "V",
            "y2": "T",
        },
        "params": ("beta", "d_I", "p", "c", "s_T", "d_T", "r", "c_T"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "eaihrd": {
        "name": "EIHRD epidemiological model (from https://arxiv.org/pdf/2406.17827)", "key": ":EAIHRD", "line": 1267,
        "states": {
            "A": "a * E - r1 * A",
            "I": "s * E - (h + r2) * I",
            "H": "h * I - (r3 + d) * H",
            "R": "r1 * A + r2 * I + r3 * H",
            "D": "d * H",
            "E": "(N - A - I - H - R - D - E) * (c1 * A + c2 * I) - (a + s) * E",
        },
        "outputs": {
            "y": "D",
        },
        "params": ("a", "r1", "s", "h", "r2", "r3", "d", "N", "c1", "c2"),
        "inputs": (),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "chemotherapy": {
        "name": "Chemotherapy model", "key": ":TranAlRadhawi", "line": 1282,
        "states": {
            "C": "u - k1 * C / (k2 + C)",
            "T": "ka * T - kb * C * T / (kc + T) - kd * T * I",
            "I": "X - ke * T * I - kf * C * I - kg * I * Y - kh * I",
            "X": "C / (1 + C * ki_inv) - kj * X - kk * X * Y",
            "Y": "I / (1 + C * kl_inv) - km * Y * C",
        },
        "outputs": {
            "y": "T",
        },
        "params": ("k1", "k2", "ka", "kb", "kc", "kd", "ke", "kf", "kg", "kh", "ki_inv", "kj", "kk", "kl_inv", "km"),
        "inputs": ("u",),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "nfkb": {
        "name": "NFkB", "key": ":NFkB", "line": 1351,
        "states": {
            "x1": "k_prod - k_deg * x1 - k1 * x1 * u",
            "x2": ("-k3 * x2 - k_deg * x2 - (1/5) * x2 * x10 + t1 * x4 - 1 * x2 * x13 + t2 * x5 + (k1 * x1 - k2 * "
                   "x2 * x8) * u"),
            "x3": "k3 * x2 - k_deg * x3 + k2 * x2 * x8 * u",
            "x4": "(1/5) * x2 * x10 - t1 * x4",
            "x5": "1 * x2 * x13 - t2 * x5",
            "x6": "(2/10**5) * x13 - (1/2) * x6 * x10 + t2 * x5 - i1 * x6",
            "x7": "i1 * 5 * x6 - (1/2) * x11 * x7",
            "x8": "(1/2) * x9 - c5 * x8",
            "x9": "0 - (5/10**7) * x7 - (4/10**4) * x9",
            "x10": "-(1/5) * x2 * x10 - (1/2) * x10 * x6 + c4a * x12 - (1/10**4) * x10 - i1a * x10 + (5/10**4) * x11",
            "x11": "-(1/2) * x11 * x7 + i1a * 5 * x10 - (5/10**4) * 5 * x11",
            "x12": "0 + (5/10**7) * x7 - c3a * x12",
            "x13": "(1/2) * x10 * x6 - (2/10**5) * x13 - 1 * x2 * x13 + e2a * x14",
            "x14": "(1/2) * x11 * x7 - e2a * 5 * x14",
            "x15": "0 + (5/10**7) * x7 - (4/10**4) * x15",
        },
        "outputs": {
            "y1": "x7",
            "y2": "x10 + x13",
            "y3": "x9",
            "y4": "x1 + x2 + x3",
            "y5": "x2",
            "y6": "x12",
        },
        "params": ("k_prod", "k_deg", "k1", "k3", "t1", "t2", "k2", "i1", "c5", "c4a", "i1a", "c3a", "e2a"),
        "inputs": ("u",),
        "si_functions_seconds": None, "skip": False, "renamed": {},
        "fixed": {"a1": "1/2", "a2": "1/5", "a3": "1", "c1a": "5/10**7", "c2a": "0", "c5a": "1/10**4",
                  "c6a": "2/10**5", "c1": "5/10**7", "c2": "0", "c3": "4/10**4", "c4": "1/2", "kv": "5",
                  "e1a": "5/10**4", "c1c": "5/10**7", "c2c": "0", "c3c": "4/10**4"},
        "note": ("the ode of lines 1297-1325 with set_parameter_values (lines 1329-1349) substituted: the values "
                 "in `fixed` are written in place of those parameters."),
    },
    "akt": {
        "name": "Akt pathway", "key": None, "line": None,
        "file": "results/Akt pathway/Akt pathway.jl",
        "states": {
            "EGFR": "-reaction_1_k1*EGF_EGFR + reaction_1_k2*EGF_EGFR - EGFR*EGFR_turnover + EGFR_turnover*pro_EGFR",
            "pEGFR": ("-reaction_4_k1*pEGFR + reaction_9_k1*EGF_EGFR - pEGFR*Akt*reaction_2_k1 "
                      "+ reaction_3_k1*pEGFR_Akt + pEGFR_Akt*reaction_2_k2"),
            "pEGFR_Akt": "pEGFR*Akt*reaction_2_k1 - reaction_3_k1*pEGFR_Akt - pEGFR_Akt*reaction_2_k2",
            "Akt": "pAkt*reaction_7_k1 - pEGFR*Akt*reaction_2_k1 + pEGFR_Akt*reaction_2_k2",
            "pAkt": ("-pAkt*reaction_7_k1 - pAkt*reaction_5_k1*S6 + reaction_6_k1*pAkt_S6 "
                     "+ reaction_3_k1*pEGFR_Akt + pAkt_S6*reaction_5_k2"),
            "S6": "pS6*reaction_8_k1 - pAkt*reaction_5_k1*S6 + pAkt_S6*reaction_5_k2",
            "pAkt_S6": "pAkt*reaction_5_k1*S6 - reaction_6_k1*pAkt_S6 - pAkt_S6*reaction_5_k2",
            "pS6": "-pS6*reaction_8_k1 + reaction_6_k1*pAkt_S6",
            "EGF_EGFR": "reaction_1_k1*EGF_EGFR - reaction_9_k1*EGF_EGFR - reaction_1_k2*EGF_EGFR",
        },
        "outputs": {
            "y1": "pEGFR*a1 + a1*pEGFR_Akt",
            "y2": "a2*pAkt + a2*pAkt_S6",
            "y3": "pS6*a3",
        },
        "params": ("reaction_1_k1", "reaction_1_k2", "EGFR_turnover", "reaction_4_k1", "reaction_9_k1",
                   "reaction_2_k1", "reaction_3_k1", "reaction_2_k2", "reaction_7_k1", "reaction_5_k1",
                   "reaction_6_k1", "reaction_5_k2", "reaction_8_k1", "a1", "a2", "a3"),
        "inputs": ("pro_EGFR",),
        "si_functions_seconds": 2.44, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "cd8": {
        "name": "CD8 T cell differentiation", "key": None, "line": None,
        "file": "results/CD8 T cell differentiation/CD8 T cell differentiation.jl",
        "states": {
            "N": "-delta_NE*N*P - mu_N*N",
            "E": "-mu_EE*E**2 + delta_NE*N*P - delta_EL*E + E*P*rho_E",
            "S": "-mu_LE*S*E + delta_EL*S - S**2*mu_LL - S*delta_LM",
            "M": "S*delta_LM - M*mu_M",
            "P": "rho_P*P**2 - S*P*mu_PL - E*mu_PE*P - P*mu_P",
        },
        "outputs": {
            "y1": "N",
            "y2": "S + E",
            "y3": "M",
        },
        "params": ("delta_NE", "mu_N", "mu_EE", "delta_EL", "rho_E", "mu_LE", "mu_LL", "delta_LM", "mu_M", "rho_P",
                   "mu_PL", "mu_PE", "mu_P"),
        "inputs": (),
        "si_functions_seconds": 0.72, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "pk1": {
        "name": "PK1", "key": None, "line": None,
        "file": "results/PK1/PK1.jl",
        "states": {
            "x1": "u1 - k2*x1 - k1*x1",
            "x2": "k5*x4 - k3*x2 - k6*x2 + k1*x1 - k7*x2",
            "x3": "k3*x2 - k4*x3 + k2*x1",
            "x4": "-k5*x4 + k6*x2",
        },
        "outputs": {
            "y1": "s2*x2",
            "y2": "s3*x3",
        },
        "params": ("k2", "k1", "k5", "k3", "k6", "k7", "k4", "s2", "s3"),
        "inputs": ("u1",),
        "si_functions_seconds": 0.74, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "pk2": {
        "name": "PK2", "key": None, "line": None,
        "file": "results/PK2/PK2.jl",
        "states": {
            "x0": ("(-ka*n*x0 - ka*kc*a1*x0 + ka*kc*a1*x1 - ka*a1*x0**2 + ka*a1*x0*x1 - kc*a1*x0*x2 "
                   "+ kc*a1*x1*x2)/(ka*kc + ka*x0 + kc*x2)"),
            "x1": "a2*x0 - a2*x1",
            "x2": ("(ka*kc*b1*x3 - ka*kc*b1*x2 + ka*b1*x0*x3 - ka*b1*x0*x2 - n*kc*x2 "
                   "+ kc*b1*x3*x2 - kc*b1*x2**2)/(ka*kc + ka*x0 + kc*x2)"),
            "x3": "-b2*x3 + b2*x2",
        },
        "outputs": {
            "y1": "x0",
        },
        "params": ("ka", "n", "kc", "a1", "a2", "b1", "b2"),
        "inputs": (),
        "si_functions_seconds": 130.96, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "phos": {
        "name": "Phosphorylation", "key": None, "line": None,
        "file": "results/Phosphorylation/Phosphorylation.jl",
        "states": {
            "x5": "k5*x6 + k4*x6 - k6*x5*x3",
            "x6": "-k5*x6 - k4*x6 + k6*x5*x3",
            "x4": "-k3*x4 - k2*x4 + k1*x1*x2",
            "x2": "k3*x4 + k2*x4 + k1*x1*x2",
            "x1": "k4*x6 + k2*x4 - k1*x1*x2",
            "x3": "k5*x6 + k3*x4 - k6*x5*x3",
        },
        "outputs": {
            "y1": "x3",
            "y2": "x2",
        },
        "params": ("k5", "k4", "k6", "k3", "k2", "k1"),
        "inputs": (),
        "si_functions_seconds": 0.45, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "cholera": {
        "name": "cholera", "key": None, "line": None,
        "file": "results/cholera/cholera.jl",
        "states": {
            "S": "-bi*S*I - S*mu - S*bw*W + R*a + mu",
            "I": "bi*S*I - gam*I + S*bw*W - mu*I",
            "W": "xi*I - xi*W",
            "R": "gam*I - R*mu - R*a",
        },
        "outputs": {
            "y1": "k*I",
            "y2": "S + R + I",
        },
        "params": ("bi", "mu", "bw", "a", "gam", "xi", "k"),
        "inputs": (),
        "si_functions_seconds": 0.66, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
    "glv2": {
        "name": "generalizedLoktaVolterra (2o)", "key": None, "line": None,
        "file": "results/generalizedLoktaVolterra (2o)/generalizedLoktaVolterra (2o).jl",
        "states": {
            "x1": "r1*x1 + beta11*x1**2 + x2*beta12*x1",
            "x2": "beta22*x2**2 + beta21*x2*x1 + x2*r2",
        },
        "outputs": {
            "y1": "x1",
            "y2": "x2",
        },
        "params": ("r1", "beta11", "beta12", "beta22", "beta21", "r2"),
        "inputs": (),
        "si_functions_seconds": 0.09, "skip": False, "renamed": {},
        "fixed": {},
        "note": "",
    },
}


def system(key: str):
    """The nlobs System of MODELS[key] (every parameter valued 1.0; the analyses treat them as unknown)."""
    from nlobs import System

    m = MODELS[key]
    return System(states=list(m["states"]), f=list(m["states"].values()), outputs=list(m["outputs"]),
                  h=list(m["outputs"].values()), inputs=list(m["inputs"]), params={p: 1.0 for p in m["params"]},
                  name=key)
