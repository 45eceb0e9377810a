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
def test_no_isinstance_dispatch_on_condition_classes():
    """A condition says what it is and does (its methods, ``role``, ``mortar``, the registries
    ``ROW_BUILDERS`` and ``FILE_TABLES``): no module asks for its class."""
    assert _figures()["isinstance_dispatch"] == 0


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


@pytest.mark.serial
def test_every_import_of_the_package_resolves():
    """Relative and absolute imports of the package's own modules name modules that exist —
    also the ones inside functions, which only fail when the function runs."""
    import ast

    package = ROOT / "dolfinx_feti"
    modules = {".".join(p.relative_to(ROOT).with_suffix("").parts[:-1]
                        if p.name == "__init__.py" else p.relative_to(ROOT).with_suffix("").parts)
               for p in package.rglob("*.py")}
    bad = []
    for path in package.rglob("*.py"):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        here = parts[:-1]  # the package the module is in (itself for an __init__)
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.ImportFrom):
                continue
            if node.level:
                base = here[:len(here) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.startswith("dolfinx_feti") and target not in modules:
                bad.append(f"{path.relative_to(ROOT)}:{node.lineno} {target}")
    assert not bad, bad
