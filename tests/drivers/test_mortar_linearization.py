"""The derivatives of the deformed mortar rows (drivers/mortar_linearization.py) on a tiny problem.

A quarter disk (R = 1) moved 0.04 into a block, both neo-Hookean, mortar contact: the rows
of x + u, their gap derivative G = −∂g/∂u and the force derivative H = ∂(Σ λ_j b_j)/∂u at
positive multipliers, checked against what does not come from the difference quotients:

- a rigid rotation of the whole configuration leaves every gap as it is (G v = 0 for the
  rotation field v = ω × y), while the frozen rows B do not see that (B v ≠ 0 on the rows with
  a gap): G is not B;
- under that rotation the contact forces turn with the configuration: H v = ω × F;
- the derivatives against the rows of x + u ± h w (the solver's own row assembly and its
  global columns) along a random direction w, and the directional products
  (:meth:`RowsAt.derivative`, what Newton uses) equal to the matrices times w;
- on the flat blocks pressed 20 %, whose interface's ends stay together (where the rows are
  not differentiable), a homogeneous motion (a translation, a stretch) moves no contact force
  (H v = 0) and no gap beyond the frozen rows ((G − B) v = 0) along the direction, while the
  dof-by-dof matrices take the kink's mean.
"""

from __future__ import annotations

import numpy as np
import pytest
from hand_meshes import blocks
from test_newton import neo_hookean_exact
from test_newton_mortar import TWO_BLOCKS, stack

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


def _physical(mortar, rows, lam_phys):
    """A Vec of the QP multipliers of ``rows``' own rows of the physical ``lam_phys``."""
    lam = mortar.solver.qp.system.B.createVecLeft()
    lam.array[:] = lam_phys / rows.own.scale
    return lam


def derivatives(mortar, problem, rows, u, lam_phys):
    """The derivatives at u with the physical multipliers ``lam_phys`` of ``rows``' own rows."""
    lam = _physical(mortar, rows, lam_phys)
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
    global columns), and the directional products equal to the matrices times w."""
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
    # the directional products Newton takes: the matrices times w
    at = mortar.rows_at_iterate(problem, u, rows, _physical(mortar, rows, lam_phys))
    Gv, Hv = at.derivative(W)
    assert np.abs(Gv - d.G @ W).max() < 1e-6 * np.abs(d.G @ W).max()
    assert np.abs(Hv - d.H @ W).max() < 1e-6 * np.abs(d.H @ W).max()
    assert np.abs(at.frozen(W) - d.B @ W).max() < 1e-12 * np.abs(d.B @ W).max()
    w.destroy()


def test_homogeneous_motion_on_the_flat_blocks():
    """The flat blocks pressed 20 % (the exact homogeneous state): along a translation or a
    stretch the directional products give H v = 0 and (G − B) v = 0 to round-off; the
    dof-by-dof H does not (its columns at the interface's ends average the two sides)."""
    mesh = blocks(TWO_BLOCKS)
    problem = stack(mesh, 0.2, df.Mortar("upper_bottom", "lower_top"))
    solver = df.FetiSolver(problem, method="fetidp", keep_meshes=True)
    data = solver.data
    a, p22 = neo_hookean_exact(0.2)
    u = solver.qp.system.B.createVecRight()
    u.array[:] = np.where(data.dof_comp == 0, (a - 1) * data.dof_x[:, 0], -0.2 * data.dof_x[:, 1])
    mortar = DeformedMortar(solver, problem, solver.comm)
    rows, _, _ = mortar.relayout(problem, solver.qp.rows, solver.qp.rows.own.rhs, u)
    lam = _physical(mortar, rows, np.full(rows.own.size, -p22 * 0.4))
    at = mortar.rows_at_iterate(problem, u, rows, lam)
    d = at.dense(mortar.surface_dofs(problem))
    y = positions(mortar, u)
    assert np.abs(at.gap).max() < 1e-12 and at.lam.min() > 0.1
    kink = 0.0
    for v in (np.c_[np.ones(len(y)), np.zeros(len(y))], np.c_[y[:, 0], np.zeros(len(y))],
              np.c_[np.zeros(len(y)), y[:, 1]]):
        Gv, Hv = at.derivative(v.ravel())
        assert np.abs(Hv).max() < 1e-9 * at.lam.max()
        assert np.abs(Gv - at.frozen(v.ravel())).max() < 1e-9
        kink = max(kink, np.abs(d.H @ v.ravel()).max())
    assert kink > 1e-7 * at.lam.max()  # the matrices' mean of the kink's two sides
    lam.destroy()
    u.destroy()
    solver.destroy()
