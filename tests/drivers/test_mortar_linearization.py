"""The derivatives of the deformed mortar rows (drivers/mortar_linearization.py) on a tiny problem.

A quarter disk (R = 1) moved 0.04 into a block, both neo-Hookean, mortar contact: the rows
of x + u, their gap derivative G = −∂g/∂u and the force derivative H = ∂(Σ λ_j b_j)/∂u at
positive multipliers, checked against what does not come from the difference quotients:

- a rigid rotation of the whole configuration leaves every gap as it is (G v = 0 for the
  rotation field v = ω × y), while the frozen rows B do not see that (B v ≠ 0 on the rows with
  a gap): G is not B;
- under that rotation the contact forces turn with the configuration: H v = ω × F;
- the derivatives against the rows of x + u ± h w (the solver's own row assembly and its
  global columns, the forces Bᵀλ assembled by PETSc) along a random direction w, and the
  tangent's part (:meth:`DeformedMortar.force_tangent`) plus the remainder equal to H w.
"""

from __future__ import annotations

import numpy as np
import pytest

import dolfinx_feti as df
from dolfinx_feti.drivers.current_mortar import DeformedMortar
from dolfinx_feti.io.meshes_occ import disk_on_block

pytestmark = pytest.mark.serial  # the dense derivatives sit on rank 0; one rank checks them


@pytest.fixture(scope="module")
def setup():
    mesh = df.build_mesh(disk_on_block, h_contact_disk=0.12, h_contact_block=0.2, h_far=0.6,
                         R=1.0, width=3.0, height=1.5, refine=0.6, gdim=2)
    problem = df.ContactProblem(
        mesh, df.NeoHookean(1.0, 0.3),
        dirichlet=[df.Dirichlet("load", -0.04, components=[1]),
                   df.Dirichlet("symmetry", 0.0, components=[0]), df.Dirichlet("bottom")],
        contact=[df.Mortar("disk_contact", "block_contact")], decomposition=df.ByTags())
    solver = df.FetiSolver(problem, method="fetidp", keep_meshes=True)
    data = solver.data
    disk = data.local_subs[np.array([b == "disk" for b in data.bodies], dtype=bool)]
    u = solver.qp.system.B.createVecRight()
    u.array[:] = np.where((data.dof_comp == 1) & np.isin(data.dof_sub, disk), -0.04, 0.0)
    mortar = DeformedMortar(solver, problem, solver.comm)
    rows, _, _ = mortar.relayout(problem, solver.qp.rows, solver.qp.rows.own.rhs, u)
    lam = solver.qp.system.B.createVecLeft()  # not used for H: the physical λ below
    yield solver, problem, mortar, rows, u
    lam.destroy()
    u.destroy()
    solver.destroy()


def derivatives(mortar, problem, rows, u, lam_phys):
    """The derivatives at u with the physical multipliers ``lam_phys`` of ``rows``' own rows."""
    lam = mortar.solver.qp.system.B.createVecLeft()
    lam.array[:] = lam_phys / rows.own.scale
    d = mortar.derivatives(problem, u, rows, lam)
    lam.destroy()
    return d


def positions(mortar, u) -> np.ndarray:
    """The current positions of the surfaces' points."""
    layer = mortar.solver.qp.surface.problem.mesh
    return layer.x[:, :2] + mortar._displacement(u)[:, :2]


def test_rotation_leaves_the_gaps(setup):
    solver, problem, mortar, rows, u = setup
    rng = np.random.default_rng(3)
    lam_phys = rng.uniform(0.5, 1.5, rows.own.size)
    d = derivatives(mortar, problem, rows, u, lam_phys)
    assert d.lam.min() > 0.4
    assert d.gap.min() < -1e-3 and d.gap.max() > 1e-3  # penetrating and open rows
    y = positions(mortar, u)
    v = np.zeros((y.shape[0], 2))
    v[:, 0], v[:, 1] = -y[:, 1], y[:, 0]  # ω × y, ω = 1
    dofs = np.zeros(y.shape[0] * 2, dtype=bool)
    dofs[mortar.surface_dofs(problem)] = True
    v.ravel()[~dofs] = 0.0  # points off the surfaces do not enter the rows
    Gv, Bv = d.G @ v.ravel(), d.B @ v.ravel()
    assert np.abs(Gv).max() < 1e-7, Gv
    assert np.abs(Bv).max() > 1e-2  # the frozen rows see a rotation
    # the forces F = Σ λ_j b_j turn with the configuration: H v = ω × F
    F = (d.lam @ d.B).reshape(-1, 2)
    turned = np.c_[-F[:, 1], F[:, 0]]
    assert np.abs(F).max() > 0.1
    assert np.abs((d.H @ v.ravel()).reshape(-1, 2) - turned).max() < 1e-7 * np.abs(F).max()


def test_derivatives_against_the_solvers_rows(setup):
    """G w and H w against central differences of the rows the solver assembles (rows_at:
    global columns, B assembled by PETSc), and force_tangent + remainder = H."""
    solver, problem, mortar, rows, u = setup
    rng = np.random.default_rng(5)
    lam_phys = rng.uniform(0.5, 1.5, rows.own.size)
    d = derivatives(mortar, problem, rows, u, lam_phys)
    w = solver.qp.system.B.createVecRight()
    w.array[:] = rng.standard_normal(w.array.size)
    data = solver.data
    h = 1e-6

    def at(s):
        v = u.copy()
        v.axpy(s, w)
        new, cols, c = mortar.rows_at(problem, v)
        gap = new.rhs / new.scale  # the rows' physical gaps
        key = new.node
        force = np.zeros(data.K.shape[0])
        mortar_rows = np.flatnonzero(rows.own.spec == 0)  # the Mortar condition's rows
        node = rows.own.node[mortar_rows]
        order = np.argsort(node)
        lam_new = lam_phys[mortar_rows][order][np.searchsorted(node[order], key)]
        np.add.at(force, cols - data.primal_start,
                  new.e_coef / new.scale[new.e_row] * lam_new[new.e_row])
        v.destroy()
        return key, gap, force

    key_p, gap_p, f_p = at(h)
    key_m, gap_m, f_m = at(-h)
    assert np.array_equal(key_p, key_m)
    W = mortar._displacement(w).ravel()
    # G w: the rows of d in the nodes' order
    pos = np.searchsorted(mortar._points, key_p)
    d_order = np.argsort(d.node)
    Gw = (d.G @ W)[d_order][np.searchsorted(d.node[d_order], pos)]
    assert np.abs(Gw + (gap_p - gap_m) / (2 * h)).max() < 1e-6
    # H w at the global columns (the first copy of every surface point)
    Hw = d.H @ W
    col = mortar._col.ravel()
    ref = (f_p - f_m) / (2 * h)
    got = np.zeros_like(ref)
    here = col >= 0
    np.add.at(got, col[here] - data.primal_start, Hw[here])
    assert np.abs(ref).max() > 1e-2
    assert np.abs(got - ref).max() < 1e-6 * np.abs(ref).max()
    # the tangent's symmetric part of one subdomain plus the remainder: H again
    S = mortar.force_tangent(d).toarray()
    full = np.zeros((data.K.shape[0], data.K.shape[0]))
    a, b = np.meshgrid(np.flatnonzero(here), np.flatnonzero(here), indexing="ij")
    np.add.at(full, (col[a] - data.primal_start, col[b] - data.primal_start),
              mortar.remainder[a, b])
    Wg = np.zeros(data.K.shape[0])
    Wg[col[here] - data.primal_start] = W[here]
    assert np.abs((S + full) @ Wg - got).max() < 1e-10 * np.abs(got).max()
    assert np.abs(S - S.T).max() == 0.0
    w.destroy()
