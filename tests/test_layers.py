"""The layering of the package, as contracts (pyproject.toml, ``[tool.importlinter]``).

The QP solvers know nothing of FETI, meshes or DOLFINx; the FETI transforms are algebra;
the solver object sits over the set-up, which sits over the FETI layer, over the QP layer.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import dolfinx
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.serial
def test_import_contracts_hold():
    exe = Path(sys.executable).with_name("lint-imports")
    if not exe.exists():
        # the default environment (scripts/setup.sh) installs it with the linters; the
        # DOLFINx 0.11 one checks the same code without it
        assert not dolfinx.__version__.startswith("0.5"), "import-linter is not installed"
        pytest.skip("import-linter is installed in the default environment only")
    run = subprocess.run([str(exe), "--no-cache"], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "0 broken" in run.stdout


def _figures():
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import code_figures
    finally:
        sys.path.pop(0)
    return code_figures.figures(code_figures.sources(None))


@pytest.mark.serial
def test_no_import_cycle_and_no_private_import_across_modules():
    f = _figures()
    assert f["import_cycles"] == []
    assert f["private_imports"] == []


@pytest.mark.serial
def test_no_merge_conflict_markers():
    """A merge left no ``<<<<<<<`` / ``>>>>>>>`` lines in the code or the docs."""
    files = [p for pattern in ("dolfinx_feti/**/*.py", "tests/**/*.py", "bench/**/*.py",
                               "demos/*.py", "scripts/*", "docs/*.md", "README.md",
                               "pyproject.toml", "problems/*.toml")
             for p in ROOT.glob(pattern) if p.is_file()]
    bad = [f"{p.relative_to(ROOT)}:{i + 1}" for p in files
           for i, line in enumerate(p.read_text(errors="replace").splitlines())
           if line.startswith(("<<<<<<< ", ">>>>>>> "))]
    assert not bad, bad
