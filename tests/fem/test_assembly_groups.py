"""A rank's subdomains meshed by DOLFINx in groups of a bounded number of cells: the grouping
changes neither the assembled K and f nor the solve, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
import reference as ref
import scipy.sparse as sp
from test_b1_membranes import grid

import dolfinx_feti as df
import dolfinx_feti.solver as solver
from dolfinx_feti.fem import assembly


def test_block_diagonal_is_scipys():
    parts = [sp.random(n, n, density=0.4, format="csr", random_state=i)
             for i, n in enumerate([5, 1, 7, 3])]
    for p in parts:
        p.sort_indices()
    got, want = assembly.block_diagonal(parts), sp.block_diag(parts, format="csr")
    assert got.shape == want.shape
    for name in ("indptr", "indices", "data"):
        assert np.array_equal(getattr(got, name), getattr(want, name))
    assert assembly.block_diagonal([]).shape == (0, 0)


def test_runs_end_at_the_cell_limit():
    class Mesh:  # only the cells' bodies are read
        cell_body = np.array([0, 0, 0, 0, 1, 1, 1])

    m = Mesh()
    cells_of = {0: np.array([0]), 1: np.array([1, 2]), 2: np.array([3]), 3: np.array([4, 5]),
                4: np.array([6])}
    subs = np.arange(5)
    assert assembly._runs_of_equal_bodies(m, subs, cells_of, 10) == [[0, 1, 2], [3, 4]]
    assert assembly._runs_of_equal_bodies(m, subs, cells_of, 3) == [[0, 1], [2], [3, 4]]
    assert assembly._runs_of_equal_bodies(m, subs, cells_of, 1) == [[0], [1], [2], [3], [4]]


@pytest.mark.serial
def test_grouping_changes_no_bit(root, monkeypatch):
    mesh = df.read_gmsh(root / "meshes/membranes_16.msh")
    problem = df.ContactProblem(
        mesh, df.Poisson(source=ref.membrane_source), dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")], decomposition=grid(0.25))
    runs = []
    for limit in (10**9, 40):  # one mesh per body; a mesh per subdomain (32 cells each)
        got = {}

        def spy(*args, _orig=assembly.assemble_subdomains, _got=got, **kwargs):
            data = _orig(*args, **kwargs)
            _got["K"], _got["f"] = data.K.copy(), data.f.copy()
            return data

        monkeypatch.setattr(assembly, "CELLS_PER_MESH", limit)
        monkeypatch.setattr(solver, "assemble_subdomains", spy)
        sol = df.solve(problem, rtol=1e-10)
        runs.append((got, sol.report.hessian_mults, sol.nodal_values()))
    (a, mults_a, u_a), (b, mults_b, u_b) = runs
    assert (a["K"] != b["K"]).nnz == 0 and np.array_equal(a["K"].indices, b["K"].indices)
    assert np.array_equal(a["f"], b["f"])
    assert mults_a == mults_b
    assert np.array_equal(u_a, u_b)
