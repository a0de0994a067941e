#!/usr/bin/env bash
# The two commands of the README:
#   ./dev.sh demo   set up (virtualenv in .venv) and run the main job: `nlobs demo`
#   ./dev.sh test   set up and run the test suite (which also builds the documentation), on up to 4 cores
# and three helpers:
#   ./dev.sh nlobs ARGS   any nlobs command, from the project's .venv
#   ./dev.sh docs         build the documentation site into site/ (warnings are errors)
#   ./dev.sh python ARGS  the project's Python
# Needs only Python 3.11+ (and, for the fast compiled engine, a C compiler; without one nlobs
# falls back to CasADi's virtual machine).
set -euo pipefail
caller=$(pwd)
cd "$(dirname "$0")"
project=$(pwd)
PY=${PYTHON:-}
if [ -z "$PY" ]; then
  for cand in python3.11 python3.12 python3.13 python3; do
    if command -v "$cand" >/dev/null 2>&1 && "$cand" -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then PY=$cand; break; fi
  done
fi
[ -n "$PY" ] || { echo "dev.sh: Python 3.11 or newer is required" >&2; exit 1; }
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
# what each command needs, installed once (again when pyproject.toml or the spec changes): the demo and the nlobs and
# python helpers the library and pandas (pip install -e '.[pandas]': the README's example makes DataFrames); test and
# docs the test extra too (pytest, Sphinx, Dask, JAX, python-control). Each has its stamp, holding the spec it
# installed: `./dev.sh demo` never pulls in the test tools.
case "${1:-}" in
  test|docs) need=test; spec='.[test]' ;;
  *) need=demo; spec='.[pandas]' ;;
esac
stamp=.venv/.nlobs-installed-$need
if [ "$need" = demo ] && [ -f .venv/.nlobs-installed-test ] && [ ! pyproject.toml -nt .venv/.nlobs-installed-test ]; then
  stamp=.venv/.nlobs-installed-test; spec='.[test]'   # the test install holds the demo's
fi
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || [ "$(cat "$stamp")" != "$spec" ]; then
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet -e "$spec"
  echo "$spec" > "$stamp"
fi
case "${1:-}" in
  demo) shift; exec .venv/bin/nlobs demo "$@" ;;
  test) shift; exec .venv/bin/python -m pytest -q -n auto --maxprocesses 4 "$@" ;;   # -n 0: one process
  nlobs) shift; cd "$caller"; exec "$project/.venv/bin/nlobs" "$@" ;;   # paths relative to where you are
  python) shift; cd "$caller"; exec "$project/.venv/bin/python" "$@" ;;
  docs) shift; exec .venv/bin/python -m sphinx -W --keep-going -q -b html docs site "$@" ;;
  *) echo "usage: ./dev.sh demo|test|docs|nlobs|python [args]" >&2; exit 2 ;;
esac
