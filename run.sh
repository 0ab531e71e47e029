#!/usr/bin/env bash
# fabricsurf set-up and entry point (idempotent).
#   bash run.sh main [--out DIR]   install what is missing, then run the main job on 2 MPI ranks
#   bash run.sh test               install what is missing, then ruff check, ruff format --check
#                                  and the whole test suite:
#                                  1 rank per test (two test processes), then on 2 ranks
set -euo pipefail
cd "$(dirname "$0")"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
export MPLBACKEND=Agg
DEBS="python3-dolfinx python3-petsc4py python3-mpi4py python3-gmsh python3-numpy python3-scipy
      python3-matplotlib python3-h5py python3-venv python3-pytest"
VENV=.venv
PY=$VENV/bin/python

# Debian's optimised BLAS/LAPACK (no threads of its own): its alternatives put it behind
# libblas.so.3 and liblapack.so.3, where MUMPS's dense fronts and numpy find it; it halves
# the forming runs' time (docs/usage.md, "BLAS"). Speed only: without it every answer is the
# same to round-off, so a machine that cannot install it is warned, not stopped.
FAST_BLAS=libopenblas0-serial

installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "ok installed"; }

APT_UPDATED=""
apt_update() {  # the package lists once per run, however many installs follow
  [ -n "$APT_UPDATED" ] || { apt-get update -qq && APT_UPDATED=1; }
}

ensure_debs() {
  if ! /usr/bin/python3 -c "import dolfinx, gmsh, scipy, matplotlib, h5py, pytest" 2>/dev/null \
     || ! [ -x /usr/bin/mpirun ]; then
    echo "[run.sh] installing Debian packages"
    apt_update
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $DEBS
  fi
  if ! installed "$FAST_BLAS"; then
    echo "[run.sh] installing $FAST_BLAS (optimised BLAS for MUMPS and numpy)"
    { apt_update && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$FAST_BLAS"; } \
      || echo "[run.sh] warning: $FAST_BLAS could not be installed; running on the reference" \
              "BLAS (same answers, forming about twice as slow)" >&2
  fi
}

ensure_venv() {
  [ -x "$PY" ] || /usr/bin/python3 -m venv --system-site-packages "$VENV"
  if ! "$PY" -c "import pytest, xdist, fabricsurf.geometry" 2>/dev/null || ! [ -x "$VENV/bin/ruff" ]; then
    echo "[run.sh] installing fabricsurf (editable) and dev tools into $VENV"
    "$PY" -m pip install -q --upgrade "pip>=23"
    "$PY" -m pip install -q -e ".[dev]"
  fi
}

# pytest exit 5 (no tests collected) is a failure here, as is any other non-zero code.
run_pytest() {
  local rc=0
  "$@" || rc=$?
  if [ "$rc" -eq 5 ]; then echo "[run.sh] pytest collected no tests: failing"; return 1; fi
  return "$rc"
}

cmd=${1:-main}; shift || true
ensure_debs
ensure_venv
case "$cmd" in
  main)
    mpirun -n 2 "$PY" demos/demo_hidden_effect.py "$@" ;;
  test)
    echo "[run.sh] ruff check (the rule set of pyproject.toml) and ruff format --check"
    "$VENV/bin/ruff" check .
    "$VENV/bin/ruff" format --check .
    # 1 rank per test, two test processes (pytest-xdist, a file's tests in one process): the
    # demos' 2-rank subprocesses and the serial tests share the two cores (docs/verification.md)
    echo "[run.sh] test suite, 1 rank (two test processes)"
    run_pytest "$PY" -m pytest -q -ra --durations=15 -n 2 --dist loadfile tests "$@"
    echo "[run.sh] test suite, 2 ranks"
    run_pytest mpirun -n 2 "$PY" -m mpi4py -m pytest -q -ra -p no:cacheprovider tests "$@" ;;
  *)
    echo "usage: bash run.sh main [--out DIR] | bash run.sh test [pytest args]" >&2; exit 2 ;;
esac
