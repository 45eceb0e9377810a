#!/usr/bin/env bash
# Sets up what is missing for dolfinx_feti on DOLFINx 0.11, beside the Debian 12 set-up:
#   1. a Python >= 3.12 (DOLFINx 0.11's wheel needs it; Debian 12 has 3.11): $DOLFINX_FETI_PYTHON,
#      else python3.13/python3.12 on the PATH, else one that pyenv has installed;
#   2. the virtual environment .venv-dx011 of that Python (isolated: no system site packages, so
#      Debian's DOLFINx 0.5.2 stays out of it);
#   3. the packages pinned in scripts/requirements-dolfinx011.txt from PyPI: the DOLFINx 0.11
#      wheel (with its PETSc 3.25, MPICH and mpiexec), pytest, SciPy, Matplotlib, gmsh;
#   4. the editable install of dolfinx_feti.
# Idempotent: redone only when the requirements or pyproject.toml change; a second run takes
# well under a second. Prints the venv's python on its last line.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

VENV="$root/.venv-dx011"
REQ="$root/scripts/requirements-dolfinx011.txt"
STAMP="$VENV/.dolfinx_feti-install.stamp"

say() { printf 'setup (DOLFINx 0.11): %s\n' "$*" >&2; }

# 1. a Python >= 3.12 -------------------------------------------------------------------------
is_new_python() {
    [ -x "$1" ] && "$1" -c 'import sys, venv; sys.exit(sys.version_info < (3, 12))' 2>/dev/null
}
find_python() {
    local cand
    for cand in "${DOLFINX_FETI_PYTHON:-}" "$(command -v python3.13 || true)" \
            "$(command -v python3.12 || true)"; do
        [ -n "$cand" ] && is_new_python "$cand" && { echo "$cand"; return 0; }
    done
    local pyenv_root="${PYENV_ROOT:-}"
    if [ -z "$pyenv_root" ] && command -v pyenv >/dev/null 2>&1; then
        pyenv_root="$(pyenv root)"
    fi
    [ -z "$pyenv_root" ] && [ -d "$HOME/.pyenv" ] && pyenv_root="$HOME/.pyenv"
    if [ -n "$pyenv_root" ]; then
        # the newest 3.12+ that pyenv has installed
        for cand in $(ls -d "$pyenv_root"/versions/3.* 2>/dev/null | sort -V -r); do
            is_new_python "$cand/bin/python" && { echo "$cand/bin/python"; return 0; }
        done
    fi
    return 1
}

venv_python="$VENV/bin/python"
if ! is_new_python "$venv_python"; then
    if ! py="$(find_python)"; then
        cat >&2 <<'EOF'
setup (DOLFINx 0.11): no Python >= 3.12 found (DOLFINx 0.11's wheel needs one; Debian 12 has 3.11).
  Get one and run again, e.g. with pyenv:  pyenv install 3.12
  or name it:  DOLFINX_FETI_PYTHON=/path/to/python3.12 bash scripts/run.sh test --dolfinx 0.11
EOF
        exit 1
    fi
    say "venv: creating .venv-dx011 with $py ($("$py" -c 'import platform; print(platform.python_version())'))"
    rm -rf "$VENV"
    "$py" -m venv "$VENV"
fi

# 2.-4. pinned packages and the editable install -------------------------------------------------
hash="$(cat "$REQ" pyproject.toml | sha256sum | cut -d' ' -f1)"
package_resolves() {
    local origin
    origin="$(cd / && "$venv_python" -c '
import importlib.util
spec = importlib.util.find_spec("dolfinx_feti")
print(spec.origin if spec else "")' 2>/dev/null)"
    [ "$origin" = "$root/dolfinx_feti/__init__.py" ]
}
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$hash" ] && package_resolves; then
    say "packages: up to date"
else
    say "packages: installing scripts/requirements-dolfinx011.txt (about 200 MB the first time)"
    log="$(mktemp)"
    if ! "$venv_python" -m pip install -q --disable-pip-version-check -r "$REQ" >"$log" 2>&1 \
        || ! "$venv_python" -m pip install -q --disable-pip-version-check --no-deps \
            --no-build-isolation -e . >>"$log" 2>&1; then
        grep -v "is ignored: it is neither a file nor a directory" "$log" >&2 || true
        rm -f "$log"
        exit 1
    fi
    rm -f "$log"
    # the check that the stack works: MPI loads, DOLFINx and PETSc import, a Cholesky package
    "$venv_python" -c '
from mpi4py import MPI
import dolfinx, petsc4py.PETSc
from dolfinx_feti.factor import available_factors
print(f"setup (DOLFINx 0.11): DOLFINx {dolfinx.__version__}, Cholesky packages {available_factors()}")
' >&2
    echo "$hash" >"$STAMP"
fi
echo "$venv_python"
