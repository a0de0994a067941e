#!/bin/bash
# The GPU and many-core figures in one command, on a machine without network access (pack.py beside says what it
# carries): installs .offline/ into a scratch folder, then runs
#   1. bench_jax.py: the JAX engine on the GPU (Monte Carlo 16,000 .. 1,000,000 runs, particle filter 10^5, 10^6;
#      noise drawn on the host only up to 16,000 runs: at 160,000 it is 13 GB drawn and sent, at each of 3 calls),
#   2. bench_cores.py --dask: montecarlo on 1, 2, 4, 8, 16 threads and on Dask LocalClusters of as many workers,
# each within its own time limit, and copies each results file to $OUT (default ./offline-results) as soon as it is
# written, so a stage cut short still leaves the ones before it. Sizes and limits can be changed through the
# environment: JAX_ARGS, CORES_ARGS, JAX_S, CORES_S (seconds), PYTHON.
#
# Usage (in the checkout):  bash benchmarks/offline/run.sh
set -u
cd "$(dirname "$0")/../.." || exit 1
OUT=${OUT:-$PWD/offline-results}
PY=${PYTHON:-python3}
SITE=${SITE:-/tmp/nlobs-offline-site}
mkdir -p "$OUT" "$SITE"
[ -f .offline/casadi.tar.xz ] || { echo "no .offline/: run python benchmarks/offline/pack.py on a machine with network access first"; exit 2; }
"$PY" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target "$SITE" .offline/wheels/*.whl || exit 3
tar -xJf .offline/casadi.tar.xz -C "$SITE" || exit 3
export PYTHONPATH="$SITE:$PWD/src" PYTHONUNBUFFERED=1
{
  date -u; uname -m; nproc; (nvidia-smi -L 2>/dev/null || echo "no nvidia-smi"); (gcc --version 2>/dev/null | head -1 || echo "no gcc")
  "$PY" -c "import sys, casadi, dask, numpy, jax, nlobs; from nlobs.engine import usable_cores; print(sys.version.split()[0], 'casadi', casadi.__version__, 'dask', dask.__version__, 'numpy', numpy.__version__, 'jax', jax.__version__, jax.devices(), 'cores', usable_cores())"
} 2>&1 | tee "$OUT/env.txt"
[ "${PIPESTATUS[0]}" = 0 ] || exit 4

stage() {   # stage NAME SECONDS COMMAND...: run it within SECONDS, log to $OUT/NAME.log, copy its results file
  local name=$1 limit=$2
  shift 2
  echo "== $name (at most $limit s): $*" | tee -a "$OUT/stages.txt"
  local t0=$SECONDS mark="$OUT/.start-$name"
  touch "$mark"; sleep 1
  timeout "$limit" "$@" > "$OUT/$name.log" 2>&1
  local rc=$?
  echo "   rc $rc after $((SECONDS - t0)) s" | tee -a "$OUT/stages.txt"
  tail -n 40 "$OUT/$name.log"
  if [ "benchmarks/results/$name.json" -nt "$mark" ]; then   # written by this stage, not the checkout's old one
    cp "benchmarks/results/$name.json" "$OUT/"
  else
    echo "   (no results file written)" | tee -a "$OUT/stages.txt"
  fi
  rm -f "$mark"
}

# shellcheck disable=SC2086
stage bench_jax "${JAX_S:-240}" "$PY" benchmarks/bench_jax.py ${JAX_ARGS:---rounds 2 --noise-max 16000}
# shellcheck disable=SC2086
stage bench_cores "${CORES_S:-240}" "$PY" benchmarks/bench_cores.py ${CORES_ARGS:---rounds 2 --sizes 16000,160000 --workers 1,2,4,8,16 --noise-max 16000 --dask}
echo "results in $OUT: $(ls "$OUT" | tr '\n' ' ')"
