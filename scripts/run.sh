#!/usr/bin/env bash
# Usage: bash scripts/run.sh demo|test|bench [args...]
#   demo   solve the 2D Hertz contact demo (extra args go to demos/demo_hertz2d.py)
#   test   ruff, then pytest serially, then pytest under mpirun -n 2 (extra args go to pytest);
#          ends with one line "N passed, N failed" (both runs together), exits non-zero on any
#          failure, including a pytest run that executed no test
#   bench  run bench/run.py (extra args go to it)
set -uo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

usage() { echo "usage: bash scripts/run.sh demo|test|bench [args...]" >&2; exit 2; }
[ $# -ge 1 ] || usage
cmd="$1"
shift
case "$cmd" in demo | test | bench) ;; *) usage ;; esac

bash scripts/setup.sh || { echo "run: setup failed" >&2; exit 1; }

export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
PY="$root/.venv/bin/python"
NPROCS=2

case "$cmd" in
demo) exec "$PY" demos/demo_hertz2d.py "$@" ;;
bench)
    [ -f bench/run.py ] || { echo "run: bench/run.py does not exist yet" >&2; exit 1; }
    exec "$PY" bench/run.py "$@"
    ;;
esac

# ---- test -------------------------------------------------------------------------------------
reports="$root/output/test-reports"
rm -rf "$reports"
mkdir -p "$reports"
status=0

lint_paths=()
for d in dolfinx_feti tests demos bench meshes scripts; do [ -e "$d" ] && lint_paths+=("$d"); done
echo "== ruff check ${lint_paths[*]}"
if [ ${#lint_paths[@]} -eq 0 ]; then
    echo "ruff: nothing to check"
elif ! .venv/bin/ruff check --no-cache --output-format=concise "${lint_paths[@]}"; then
    echo "ruff: FAILED"
    status=1
fi

echo "== pytest (serial)"
"$PY" -m pytest -q --junitxml="$reports/serial.xml" "$@"
rc=$?
if [ $rc -ne 0 ]; then
    [ $rc -eq 5 ] && echo "pytest (serial): no test was run"
    echo "pytest (serial): FAILED (exit code $rc)"
    status=1
fi

# mpirun gives the ranks a pseudo-terminal: colour only if run.sh itself writes to one.
color=no
[ -t 1 ] && color=yes

# Under mpirun every rank runs pytest; rank 0 prints to the terminal, the other ranks write their
# output to output/test-reports/mpi-rank<r>.log. Each rank writes its own JUnit XML report.
echo "== pytest (mpirun -n $NPROCS, -m 'not serial')"
timeout --signal=TERM "${MPI_TEST_TIMEOUT:-1800}" \
    mpirun -n "$NPROCS" --allow-run-as-root --oversubscribe \
    bash -c '
        rank="${OMPI_COMM_WORLD_RANK:-${PMI_RANK:-0}}"
        reports="$1"; shift
        if [ "$rank" = 0 ]; then
            exec "$@" --junitxml="$reports/mpi-rank$rank.xml"
        else
            exec "$@" --junitxml="$reports/mpi-rank$rank.xml" >"$reports/mpi-rank$rank.log" 2>&1
        fi' _ "$reports" \
    "$PY" -m pytest -q -p no:cacheprovider --color="$color" -m "not serial" "$@"
rc=$?
if [ $rc -ne 0 ]; then
    [ $rc -eq 5 ] && echo "pytest (mpirun): no test was run"
    [ $rc -eq 124 ] && echo "pytest (mpirun): timed out after ${MPI_TEST_TIMEOUT:-1800} s"
    grep -h -E '^(FAILED|ERROR) ' "$reports"/mpi-rank*.log 2>/dev/null | sed 's/^/rank > 0: /'
    echo "pytest (mpirun): FAILED (exit code $rc); the other ranks' output: $reports/mpi-rank*.log"
    status=1
fi

# The last line: "N passed, N failed" over both runs (rank 0's view merged with the others').
"$PY" scripts/junit_summary.py "$reports" "$NPROCS" || status=1
exit $status
