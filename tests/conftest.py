"""Fixtures shared by the whole suite: the repository root (paths never depend on the folder
pytest runs from)."""

from __future__ import annotations

from pathlib import Path

import pytest

# First: loads MPI before PETSc and DOLFINx, as DOLFINx 0.11's wheel needs (the test modules
# import dolfinx and petsc4py in alphabetical order).
from dolfinx_feti import compat  # noqa: F401  isort: skip

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def root() -> Path:
    """The repository root (meshes/, problems/, demos/ are below it)."""
    return ROOT


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Parametrize a ``demo`` argument with every demos/demo_*.py (new demos join by name)."""
    if "demo" in metafunc.fixturenames:
        demos = sorted((ROOT / "demos").glob("demo_*.py"))
        metafunc.parametrize("demo", [p.name for p in demos], ids=[p.stem for p in demos])
