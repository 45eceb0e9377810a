"""Fixtures shared by the whole suite: the repository root (paths never depend on the folder
pytest runs from).

The tests mirror the package (``tests/<area>/``, e.g. ``tests/feti/`` for ``dolfinx_feti/feti/``;
``tests/problems/`` and ``tests/robustness/`` for whole problems and hostile input); the
helpers they share are in ``tests/support/``. Every folder is put on ``sys.path`` here, so a
test imports a helper, or another test's builders, by its module name.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

# First: loads MPI before PETSc and DOLFINx, as DOLFINx 0.11's wheel needs (the test modules
# import dolfinx and petsc4py in alphabetical order).
from dolfinx_feti import compat  # noqa: F401  isort: skip

ROOT = Path(__file__).resolve().parents[1]
for _folder in sorted(p for p in (ROOT / "tests").iterdir() if p.is_dir() and
                      not p.name.startswith((".", "_"))):
    if str(_folder) not in sys.path:
        sys.path.insert(0, str(_folder))


@pytest.fixture(scope="session")
def root() -> Path:
    """The repository root (meshes/, problems/, demos/ are below it)."""
    return ROOT


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Parametrize a ``demo`` argument with every demos/demo_*.py (new demos join by name)."""
    if "demo" in metafunc.fixturenames:
        demos = sorted((ROOT / "demos").glob("demo_*.py"))
        metafunc.parametrize("demo", [p.name for p in demos], ids=[p.stem for p in demos])
