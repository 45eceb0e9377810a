#!/usr/bin/env bash
# Sets up what is missing for dolfinx_feti on Debian 12, and nothing else:
#   1. the Debian packages (DOLFINx, PETSc, MPI, gmsh, ...) via apt-get, only if one is missing;
#   2. the serial OpenBLAS as the BLAS/LAPACK alternative (no thread oversubscription under MPI);
#   3. the virtual environment .venv (it sees the Debian packages: --system-site-packages);
#   4. the editable install of dolfinx_feti (redone only when pyproject.toml changes);
#   5. the linters (ruff, import-linter), pinned in pyproject.toml's "lint" extra, from PyPI;
#   6. Hypothesis (the property-based tests), pinned in its "test" extra, from PyPI.
# Idempotent; a second run takes well under a second.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

SYS_PYTHON=/usr/bin/python3
VENV="$root/.venv"
STAMP="$VENV/.dolfinx_feti-install.stamp"
# openmpi-bin (mpirun) already comes with python3-dolfinx (through libpetsc-real-dev and
# libopenmpi-dev) but is listed since the test command calls it; python3-wheel provides the
# bdist_wheel that Debian's setuptools 66 needs for the editable install; ca-certificates lets
# pip reach PyPI.
DEB_PACKAGES=(
    python3-dolfinx python3-petsc4py python3-mpi4py python3-gmsh python3-venv
    libopenblas0-serial python3-scipy python3-matplotlib python3-pytest python3-setuptools
    python3-wheel openmpi-bin ca-certificates
)

say() { printf 'setup: %s\n' "$*"; }

as_root() {
    if [ "$(id -u)" -eq 0 ]; then
        "$@"
    elif command -v sudo >/dev/null 2>&1; then
        sudo "$@"
    else
        echo "setup: need root (or sudo) for: $*" >&2
        exit 1
    fi
}

# 1. Debian packages ---------------------------------------------------------------------------
installed="$(dpkg-query -W -f='${Package} ${db:Status-Abbrev}\n' "${DEB_PACKAGES[@]}" 2>/dev/null \
    | awk '$2 == "ii" {print $1}' || true)"
missing=()
for pkg in "${DEB_PACKAGES[@]}"; do
    grep -qx "$pkg" <<<"$installed" || missing+=("$pkg")
done
if [ ${#missing[@]} -eq 0 ]; then
    say "Debian packages: all ${#DEB_PACKAGES[@]} present"
else
    say "Debian packages: installing ${missing[*]}"
    as_root apt-get update -q
    as_root env DEBIAN_FRONTEND=noninteractive \
        apt-get install -y -q --no-install-recommends "${missing[@]}"
fi
command -v mpirun >/dev/null 2>&1 || { echo "setup: mpirun not found after install" >&2; exit 1; }

# 2. serial OpenBLAS as BLAS/LAPACK --------------------------------------------------------------
triplet="$("$SYS_PYTHON" -c 'import sys; print(sys.implementation._multiarch)')"
for lib in libblas.so.3 liblapack.so.3; do
    name="$lib-$triplet"
    want="/usr/lib/$triplet/openblas-serial/$lib"
    current="$(update-alternatives --query "$name" 2>/dev/null | sed -n 's/^Value: //p')"
    if [ "$current" = "$want" ]; then
        say "$lib: openblas-serial selected"
    else
        say "$lib: selecting openblas-serial (was ${current:-none})"
        as_root update-alternatives --set "$name" "$want" >/dev/null
    fi
done

# 3. virtual environment -----------------------------------------------------------------------
venv_ok() {
    [ -x "$VENV/bin/python" ] && [ -f "$VENV/pyvenv.cfg" ] \
        && grep -qx 'home = /usr/bin' "$VENV/pyvenv.cfg" \
        && grep -qx 'include-system-site-packages = true' "$VENV/pyvenv.cfg"
}
if venv_ok; then
    say "venv: .venv present"
else
    say "venv: creating .venv (with system site packages)"
    rm -rf "$VENV"
    "$SYS_PYTHON" -m venv --system-site-packages "$VENV"
fi

# 4. editable install of the package -----------------------------------------------------------
# The editable finder maps the top-level package found at install time, so an install made before
# dolfinx_feti/__init__.py existed must be redone: check where the venv imports it from (from /,
# so that the current directory does not count).
package_resolves() {
    [ ! -f dolfinx_feti/__init__.py ] && return 0
    local origin
    origin="$(cd / && "$VENV/bin/python" -c '
import importlib.util
spec = importlib.util.find_spec("dolfinx_feti")
print(spec.origin if spec else "")' 2>/dev/null)"
    [ "$origin" = "$root/dolfinx_feti/__init__.py" ]
}
hash="$(sha256sum pyproject.toml | cut -d' ' -f1)"
if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$hash" ] && package_resolves; then
    say "dolfinx_feti: editable install up to date"
else
    say "dolfinx_feti: installing editable"
    log="$(mktemp)"
    if ! "$VENV/bin/pip" install -q --disable-pip-version-check --no-build-isolation --no-deps \
            -e . >"$log" 2>&1; then
        cat "$log" >&2
        rm -f "$log"
        exit 1
    fi
    rm -f "$log"
    echo "$hash" >"$STAMP"
fi

# 5. the linters: ruff and import-linter (versions pinned in pyproject.toml's "lint" extra) ---
lint_reqs="$("$SYS_PYTHON" -c '
import tomllib
with open("pyproject.toml", "rb") as f:
    print(" ".join(tomllib.load(f)["project"]["optional-dependencies"]["lint"]))
')"
for req in $lint_reqs; do
    name="${req%%==*}"
    version="${req#*==}"
    have="$("$VENV/bin/pip" show "$name" 2>/dev/null | sed -n 's/^Version: //p')" || have=""
    if [ "$have" = "$version" ]; then
        say "$name: $version present"
    else
        say "$name: installing $req"
        "$VENV/bin/pip" install -q --disable-pip-version-check "$req"
    fi
done

# 6. Hypothesis (pinned in pyproject.toml's "test" extra; pytest itself comes from Debian) -------
hyp_req="$("$SYS_PYTHON" -c '
import tomllib
with open("pyproject.toml", "rb") as f:
    test = tomllib.load(f)["project"]["optional-dependencies"]["test"]
print(next(r for r in test if r.startswith("hypothesis")))
')"
hyp_version="${hyp_req#hypothesis==}"
if [ "$("$VENV/bin/python" -c 'import hypothesis; print(hypothesis.__version__)' 2>/dev/null)" = "$hyp_version" ]; then
    say "hypothesis: $hyp_version present"
else
    say "hypothesis: installing $hyp_req"
    "$VENV/bin/pip" install -q --disable-pip-version-check "$hyp_req"
fi
