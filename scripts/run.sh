#!/usr/bin/env bash
# Usage: bash scripts/run.sh demo|test|bench [--dolfinx 0.5|0.11] [--part serial|mpi] [args...]
#   demo   solve the 2D Hertz contact demo (extra args go to demos/demo_hertz2d.py)
#   test   ruff, then pytest serially, then pytest under mpirun -n 2 (extra args go to pytest);
#          ends with one line "N passed, N failed" (both runs together), exits non-zero on any
#          failure, including a pytest run that executed no test
#   bench  run bench/run.py (extra args go to it)
#   --dolfinx 0.5   (the default) Debian 12's DOLFINx 0.5.2 in .venv (scripts/setup.sh)
#   --dolfinx 0.11  DOLFINx 0.11 from its PyPI wheel in .venv-dx011 of a Python >= 3.12
#                   (scripts/setup_dolfinx011.sh), under that wheel's MPICH mpiexec; the tests
#                   skip ruff there (the code is the same: the default run lints it)
#   --part serial   test only: ruff and the serial run; --part mpi: only the mpirun run (.ci/run
#                   runs the two versions' serial parts side by side, each on one core); the last
#                   line then counts that part alone
set -uo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

usage() { echo "usage: bash scripts/run.sh demo|test|bench [--dolfinx 0.5|0.11] [--part serial|mpi] [args...]" >&2
          exit 2; }
[ $# -ge 1 ] || usage
cmd="$1"
shift
case "$cmd" in demo | test | bench) ;; *) usage ;; esac
dolfinx=0.5
if [ "${1:-}" = "--dolfinx" ]; then
    [ $# -ge 2 ] || usage
    dolfinx="$2"
    shift 2
elif [[ "${1:-}" == --dolfinx=* ]]; then
    dolfinx="${1#--dolfinx=}"
    shift
fi
part=all
if [ "$cmd" = test ] && [ "${1:-}" = "--part" ]; then
    [ $# -ge 2 ] || usage
    part="$2"
    shift 2
    case "$part" in serial | mpi) ;; *) usage ;; esac
fi

export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
NPROCS=2
case "$dolfinx" in
0.5 | 0.5.2)
    bash scripts/setup.sh || { echo "run: setup failed" >&2; exit 1; }
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
    PY="$root/.venv/bin/python"
    MPIEXEC=(mpirun -n "$NPROCS" --allow-run-as-root --oversubscribe)
    reports="$root/output/test-reports"
    lint=yes
    ;;
0.11 | 0.11.0)
    PY="$(bash scripts/setup_dolfinx011.sh)" || { echo "run: setup failed" >&2; exit 1; }
    MPIEXEC=("$(dirname "$PY")/mpiexec" -n "$NPROCS")
    reports="$root/output/test-reports-dolfinx0.11"
    lint=no
    ;;
*)
    echo "run: unknown DOLFINx version '$dolfinx' (known: 0.5 = Debian 12's 0.5.2, 0.11)" >&2
    exit 2
    ;;
esac

case "$cmd" in
demo) exec "$PY" demos/demo_hertz2d.py "$@" ;;
bench)
    [ -f bench/run.py ] || { echo "run: bench/run.py does not exist yet" >&2; exit 1; }
    exec "$PY" bench/run.py "$@"
    ;;
esac

# ---- test -------------------------------------------------------------------------------------
status=0

# ruff, then pytest serially
run_serial() {
    local lint_paths=() d rc
    for d in dolfinx_feti tests demos bench meshes scripts; do [ -e "$d" ] && lint_paths+=("$d"); done
    echo "== ruff check ${lint_paths[*]}"
    if [ "$lint" = no ]; then
        echo "ruff: skipped with DOLFINx $dolfinx (the default run lints the same code)"
    elif [ ${#lint_paths[@]} -eq 0 ]; then
        echo "ruff: nothing to check"
    elif ! .venv/bin/ruff check --no-cache --output-format=concise "${lint_paths[@]}"; then
        echo "ruff: FAILED"
        status=1
    fi

    echo "== pytest (serial, DOLFINx $dolfinx)"
    "$PY" -m pytest -q --junitxml="$reports/serial.xml" "$@"
    rc=$?
    if [ $rc -ne 0 ]; then
        [ $rc -eq 5 ] && echo "pytest (serial): no test was run"
        echo "pytest (serial): FAILED (exit code $rc)"
        status=1
    fi
}

# Under mpirun every rank runs pytest; rank 0 prints to the terminal, the other ranks write their
# output to output/test-reports/mpi-rank<r>.log. Each rank writes its own JUnit XML report.
run_mpi() {
    local color=no rc
    # mpirun gives the ranks a pseudo-terminal: colour only if run.sh itself writes to one.
    [ -t 1 ] && color=yes
    echo "== pytest (${MPIEXEC[0]##*/} -n $NPROCS, -m 'not serial', DOLFINx $dolfinx)"
    timeout --signal=TERM "${MPI_TEST_TIMEOUT:-1800}" \
        "${MPIEXEC[@]}" \
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
}

mkdir -p "$reports"
case "$part" in
serial) rm -f "$reports/serial.xml"; run_serial "$@" ;;
mpi) rm -f "$reports"/mpi-rank*; run_mpi "$@" ;;
*) rm -f "$reports"/serial.xml "$reports"/mpi-rank*; run_serial "$@"; run_mpi "$@" ;;
esac

# The last line: "N passed, N failed" over the runs of this part (rank 0's view merged with the
# others').
"$PY" scripts/junit_summary.py "$reports" "$NPROCS" "$part" || status=1
exit $status
