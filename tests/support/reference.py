"""An independent monolithic reference for the contact benchmarks, and an independent KKT check.

Nothing here uses the FETI machinery of ``dolfinx_feti``: only the mesh arrays of
:class:`dolfinx_feti.MeshData` (node coordinates, cells, body and facet groups) are read.

* Each body is rebuilt as an undecomposed DOLFINx mesh on ``MPI.COMM_SELF`` from ``mesh.x`` and
  ``mesh.cells``; the stiffness matrix and the volume load are assembled from UFL forms written
  here; boundary tractions (constant vectors) are lumped by hand (exact for P1).
* Dofs are numbered ``bs * node + component`` by global mesh node, through
  ``geometry.input_global_indices`` and the cell dofmaps (and checked against the dof
  coordinates).
* Dirichlet conditions (homogeneous) are eliminated; contact pairs are matched here by the node
  coordinates along the surface (the coordinates given by ``match_axes``).
* The QP  min ½uᵀKu − fᵀu  s.t.  B u <= g  is solved by a primal–dual active set (semismooth
  Newton) method with sparse direct solves of the KKT system, and the result comes with a KKT
  certificate checked to ~1e-12.

Everything is serial and deterministic, so every MPI rank computes the same thing.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import ufl
from mpi4py import MPI

from dolfinx_feti import compat  # thin DOLFINx wrappers, version-independent (no FETI in it)

#: Tolerance of the reference's own KKT certificate (relative).
CERT_TOL = 1e-12

# ---------------------------------------------------------------------------------------------
# Forms written here (not the package's helpers)
# ---------------------------------------------------------------------------------------------


def membrane_source(x):
    """B1 load: −3 on (0,1)×[0.75,1), −1 on (1,2)×[0,0.25), 0 elsewhere."""
    f1 = ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0)
    f2 = ufl.conditional(ufl.lt(x[1], 0.25), -1.0, 0.0)
    return ufl.conditional(ufl.lt(x[0], 1.0), f1, f2)


def poisson_forms(source: Callable | None = None):
    """(u, v, x, body) -> (a, L) of −Δu = f, natural conditions elsewhere."""

    def forms(u, v, x, body):
        a = ufl.dot(ufl.grad(u), ufl.grad(v)) * ufl.dx
        L = None if source is None else source(x) * v * ufl.dx
        return a, L

    return forms


def elasticity_forms(E: float, nu: float):
    """(u, v, x, body) -> (a, None): isotropic linear elasticity, plane strain in 2D."""
    mu = E / (2.0 * (1.0 + nu))
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))

    def forms(u, v, x, body):
        d = u.ufl_shape[0]
        e_u, e_v = ufl.sym(ufl.grad(u)), ufl.sym(ufl.grad(v))
        s_u = 2.0 * mu * e_u + lam * ufl.tr(e_u) * ufl.Identity(d)
        return ufl.inner(s_u, e_v) * ufl.dx, None

    return forms


# ---------------------------------------------------------------------------------------------
# Assembly on the undecomposed bodies
# ---------------------------------------------------------------------------------------------


def _body_mesh(mesh, b: int):
    """(DOLFINx mesh of body b on COMM_SELF, the body's global node indices)."""
    cells_g = mesh.cells[mesh.cell_body == b]
    nodes = np.unique(cells_g)
    local = np.searchsorted(nodes, cells_g)
    msh = compat.create_mesh(MPI.COMM_SELF, local, mesh.x[nodes], mesh.cell_type)
    return msh, nodes


def _dof_nodes(V, nodes: np.ndarray, x_global: np.ndarray) -> np.ndarray:
    """Global node of each (block) dof of the P1 space V, checked against the dof coordinates."""
    msh = V.mesh
    geom = compat.cell_geometry_nodes(msh)
    dofs = compat.cell_dofs(V)
    input_index = compat.node_input_indices(msh)
    ndofs = V.dofmap.index_map.size_local + V.dofmap.index_map.num_ghosts
    node = np.full(ndofs, -1, dtype=np.int64)
    node[dofs.ravel()] = nodes[input_index[geom.ravel()]]
    assert np.all(node >= 0)
    # Independent check of the map: the dof coordinates are the node coordinates.
    xd = V.tabulate_dof_coordinates()[:, : x_global.shape[1]]
    assert np.abs(xd - x_global[node]).max() <= 1e-12 * max(1.0, np.abs(x_global).max())
    return node


def assemble(mesh, bs: int, forms) -> tuple[sp.csr_matrix, np.ndarray]:
    """Global K (bs·N square) and f, dof = bs·node + component, bodies assembled separately."""
    N = mesh.num_nodes
    n = bs * N
    rows, cols, vals = [], [], []
    f = np.zeros(n)
    for b, name in enumerate(mesh.body_names):
        msh, nodes = _body_mesh(mesh, b)
        V = compat.function_space(msh, bs)
        assert V.dofmap.index_map_bs == bs
        node = _dof_nodes(V, nodes, mesh.x)
        glob = (bs * node[:, None] + np.arange(bs)[None, :]).ravel()  # local dof bs*d+c → global
        u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
        a, L = forms(u, v, ufl.SpatialCoordinate(msh), name)
        A = compat.assemble_matrix(a)
        indptr, indices, data = A.getValuesCSR()
        Kb = sp.csr_matrix((data, indices, indptr), shape=A.getSize()).tocoo()
        A.destroy()
        rows.append(glob[Kb.row])
        cols.append(glob[Kb.col])
        vals.append(Kb.data)
        if L is not None:
            vec = compat.assemble_vector(L)
            np.add.at(f, glob, vec.array)
            vec.destroy()
    K = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n)).tocsr()
    K.sum_duplicates()
    return K, f


def traction_load(mesh, group: str, t: Sequence[float]) -> np.ndarray:
    """Nodal loads of a constant traction t on a facet group, lumped exactly (P1): measure/d."""
    bs = len(t)
    F = mesh.facet_groups[group]
    X = mesh.x[F]  # (F, d, gdim)
    if F.shape[1] == 2:
        meas = np.linalg.norm(X[:, 1] - X[:, 0], axis=1)
    else:
        meas = 0.5 * np.linalg.norm(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]), axis=1)
    load = np.zeros((mesh.num_nodes, bs))
    for k in range(F.shape[1]):
        np.add.at(load, F[:, k], np.outer(meas / F.shape[1], t))
    return load.ravel()


# ---------------------------------------------------------------------------------------------
# Constraints built here
# ---------------------------------------------------------------------------------------------


@dataclass
class Pairs:
    """Node-to-node contact rows B u <= g, one per slave node.

    Vector problems: (u_master − u_slave)·n <= g = (x_slave − x_master)·n, n the master's
    outward normal. Scalar problems: u_slave − u_master <= 0.
    """

    slave: np.ndarray
    master: np.ndarray
    normal: np.ndarray | None
    B: sp.csr_matrix
    g: np.ndarray


def match_pairs(mesh, slave: str, master: str, axes: Sequence[int], bs: int,
                normal: Sequence[float] | None) -> Pairs:
    """Pair every slave node with the master node that has the same coordinates ``axes``."""
    s = np.unique(mesh.facet_groups[slave])
    m = np.unique(mesh.facet_groups[master])
    assert s.size == m.size, f"{slave}: {s.size} nodes, {master}: {m.size} nodes"
    scale = np.abs(mesh.x).max()
    key_s = np.round(mesh.x[s][:, list(axes)] / scale, 9)
    key_m = np.round(mesh.x[m][:, list(axes)] / scale, 9)
    os_ = np.lexsort(key_s.T[::-1])
    om = np.lexsort(key_m.T[::-1])
    assert np.array_equal(key_s[os_], key_m[om]), "contact surfaces do not match"
    s, m = s[os_], m[om]
    npair = s.size
    N = mesh.num_nodes
    if bs == 1:
        assert normal is None
        B = sp.csr_matrix((np.r_[np.ones(npair), -np.ones(npair)],
                           (np.r_[np.arange(npair), np.arange(npair)], np.r_[s, m])),
                          shape=(npair, N))
        g = np.zeros(npair)
        n = None
    else:
        n = np.asarray(normal, dtype=float)
        assert n.size == bs and abs(np.linalg.norm(n) - 1.0) < 1e-14
        r = np.repeat(np.arange(npair), bs)
        c = np.arange(bs)
        B = sp.csr_matrix((np.r_[np.tile(n, npair), -np.tile(n, npair)],
                           (np.r_[r, r], np.r_[(bs * m[:, None] + c).ravel(),
                                               (bs * s[:, None] + c).ravel()])),
                          shape=(npair, bs * N))
        g = (mesh.x[s] - mesh.x[m]) @ n
    B.eliminate_zeros()
    return Pairs(slave=s, master=m, normal=n, B=B, g=g)


def dirichlet_dofs(mesh, bs: int, conditions: Sequence[tuple[str, Sequence[int] | None]]
                   ) -> np.ndarray:
    """Mask of the dofs fixed (to zero) by [(group, components or None for all)]."""
    fixed = np.zeros((mesh.num_nodes, bs), dtype=bool)
    for group, comps in conditions:
        nodes = np.unique(mesh.facet_groups[group])
        for c in range(bs) if comps is None else comps:
            fixed[nodes, c] = True
    return fixed.ravel()


# ---------------------------------------------------------------------------------------------
# The monolithic problem and its PDAS solve
# ---------------------------------------------------------------------------------------------


@dataclass
class ReferenceSolution:
    u: np.ndarray  # (N, bs) nodal values
    lam: np.ndarray  # contact force per pair (order of problem.pairs.slave)
    energy: float
    iterations: int
    certificate: dict


class MonolithicProblem:
    """K, f, Dirichlet dofs and contact pairs of one benchmark, built independently.

    Args:
        mesh: The :class:`dolfinx_feti.MeshData` (only its arrays are used).
        bs: Components per node.
        forms: ``forms(u, v, x, body) -> (a, L or None)`` in UFL with ``ufl.dx``.
        tractions: Facet group → constant traction vector (lumped exactly).
        dirichlet: [(group, components or None)] fixed to zero.
        contact: (slave group, master group), or the rows themselves as :class:`Pairs`.
        match_axes: The coordinates that pair slave and master nodes.
        normal: The master's outward normal (vector problems).
        extra_fixed: Further single dofs fixed to zero (e.g. to remove free rigid motions).
    """

    def __init__(self, mesh, bs: int, forms, *, tractions: dict | None = None,
                 dirichlet: Sequence[tuple[str, Sequence[int] | None]] = (),
                 contact: tuple[str, str] | Pairs | None = None, match_axes: Sequence[int] = (0,),
                 normal: Sequence[float] | None = None, extra_fixed: Sequence[int] = ()) -> None:
        self.mesh, self.bs = mesh, bs
        self.K, self.f = assemble(mesh, bs, forms)
        for group, t in (tractions or {}).items():
            self.f = self.f + traction_load(mesh, group, t)
        self.fixed = dirichlet_dofs(mesh, bs, dirichlet)
        self.fixed[np.asarray(extra_fixed, dtype=np.int64)] = True  # single dofs bs·node + c
        self.free = np.flatnonzero(~self.fixed)
        self.pairs = contact if isinstance(contact, Pairs) else \
            match_pairs(mesh, contact[0], contact[1], match_axes, bs, normal)

    # -- the QP -----------------------------------------------------------------------------
    def solve(self, max_it: int = 100) -> ReferenceSolution:
        """Primal–dual active set method; exact to round-off, with a KKT certificate."""
        free = self.free
        Kf = self.K[free][:, free].tocsc()
        ff = self.f[free]
        Bf = self.pairs.B[:, free].tocsr()
        g = self.pairs.g
        m = g.size
        c = float(np.mean(self.K.diagonal()))  # complementarity constant, units of K
        active = np.ones(m, dtype=bool)  # start with every pair closed: controls the kernels
        iterations = 0
        while True:
            iterations += 1
            if iterations > max_it:
                raise RuntimeError(f"PDAS did not converge in {max_it} iterations")
            BA = Bf[active]
            KKT = sp.bmat([[Kf, BA.T], [BA, None]], format="csc")
            rhs = np.r_[ff, g[active]]
            lu = spla.splu(KKT)
            z = lu.solve(rhs)
            for _ in range(3):  # iterative refinement
                z += lu.solve(rhs - KKT @ z)
            u_f = z[: free.size]
            lam = np.zeros(m)
            lam[active] = z[free.size:]
            r = Bf @ u_f - g
            new = lam + c * r > 0.0
            if np.array_equal(new, active):
                break
            active = new
        u = np.zeros(self.K.shape[0])
        u[free] = u_f
        cert = self.kkt(u, lam)
        for k, v in cert.items():
            assert v <= CERT_TOL, f"reference KKT certificate: {k} = {v:.2e}"
        energy = 0.5 * float(u @ (self.K @ u)) - float(self.f @ u)
        return ReferenceSolution(u=u.reshape(-1, self.bs), lam=lam, energy=energy,
                                 iterations=iterations, certificate=cert)

    # -- residuals ---------------------------------------------------------------------------
    def kkt(self, u: np.ndarray, lam: np.ndarray) -> dict[str, float]:
        """Relative KKT residuals of (u, λ), with u a flat dof vector and λ per pair.

        stationarity: ||(K u − f + Bᵀλ)_free|| / max(||f||, ||Bᵀλ||) (2-norms);
        backward: the same residual as a normwise backward error, / (||K||₁ ||u|| + ||f||);
        dirichlet: max |u_fixed| / max |u|; primal: max (B u − g)⁺ / max |u|;
        dual: max (−λ)⁺ / max λ; complementarity: max |λ (B u − g)| / (max λ · max |u|).
        """
        B, g = self.pairs.B, self.pairs.g
        Btl = B.T @ lam
        res = (self.K @ u - self.f + Btl)[self.free]
        umax = max(np.abs(u).max(), 1e-300)
        lmax = max(np.abs(lam).max(), 1e-300)
        r = B @ u - g
        rn = np.linalg.norm(res)
        knorm = spla.norm(self.K, 1)
        return {
            "stationarity": float(rn / max(np.linalg.norm(self.f), np.linalg.norm(Btl))),
            "backward": float(rn / (knorm * np.linalg.norm(u) + np.linalg.norm(self.f))),
            "dirichlet": float(np.abs(u[self.fixed]).max(initial=0.0) / umax),
            "primal_feasibility": float(max(r.max(), 0.0) / umax),
            "dual_feasibility": float(max(-lam.min(), 0.0) / lmax),
            "complementarity": float(np.abs(lam * r).max() / (lmax * umax)),
        }

    # -- checking somebody else's answer ------------------------------------------------------
    def multipliers_from(self, nodes: np.ndarray, forces: np.ndarray) -> np.ndarray:
        """Forces given per slave node (any order) → per pair of this problem."""
        nodes = np.asarray(nodes)
        assert np.array_equal(np.sort(nodes), np.sort(self.pairs.slave)), \
            "the solution's contact nodes are not the slave nodes of the reference"
        by_node = dict(zip(nodes.tolist(), np.asarray(forces, dtype=float).tolist(), strict=True))
        return np.array([by_node[s] for s in self.pairs.slave.tolist()])

    def check(self, nodal: np.ndarray, nodes: np.ndarray, forces: np.ndarray) -> dict[str, float]:
        """Independent KKT residuals of a solution given as nodal values and slave-node forces."""
        nodal = np.asarray(nodal, dtype=float)
        assert nodal.shape == (self.mesh.num_nodes, self.bs)
        return self.kkt(nodal.ravel(), self.multipliers_from(nodes, forces))

    def energy(self, nodal: np.ndarray) -> float:
        """½uᵀKu − fᵀu of nodal values, with this module's K and f."""
        u = np.asarray(nodal, dtype=float).ravel()
        return 0.5 * float(u @ (self.K @ u)) - float(self.f @ u)


def forces_by_node(contact) -> tuple[np.ndarray, np.ndarray]:
    """(slave nodes sorted, their forces) of a solution's ContactData (its row order depends on
    the decomposition)."""
    order = np.argsort(contact.node)
    return contact.node[order], contact.force[order]


def rel_max_diff(a: np.ndarray, b: np.ndarray) -> float:
    """max |a − b| / max |b|."""
    return float(np.abs(np.asarray(a) - np.asarray(b)).max() / np.abs(np.asarray(b)).max())


def assert_kkt_agree(mine: dict[str, float], theirs: dict[str, float], tol: float,
                     stationarity_tol: float = 1e-6) -> None:
    """Both the independent residuals and the solver's own report are below ``tol``.

    The independent stationarity residual is evaluated at the nodal values, where the copies of
    an interface node are averaged: their mismatch (the solver's "equality" residual, ~rtol)
    is amplified by ||K|| ||u|| / ||f||, so it gets its own (looser) tolerance; as a backward
    error it must be below ``tol`` like the rest.
    """
    for k, v in mine.items():
        limit = stationarity_tol if k == "stationarity" else tol
        assert v <= limit, f"independent KKT check: {k} = {v:.2e} > {limit:.0e}"
    for k in ("dual_feasibility", "primal_feasibility", "equality", "complementarity",
              "equilibrium"):
        assert theirs[k] <= tol, f"solver report: kkt[{k!r}] = {theirs[k]:.2e} > {tol:.0e}"
    # The residuals defined alike agree in magnitude (the solver's normalizations of λ differ:
    # its max |λ| runs over all rows, gluing and Dirichlet included).
    for k_mine, k_theirs, factor in (("primal_feasibility", "primal_feasibility", 10.0),
                                     ("complementarity", "complementarity", 100.0)):
        a, b = mine[k_mine], theirs[k_theirs]
        assert max(a, b) <= 1e-13 or (min(a, b) > 0 and max(a, b) <= factor * min(a, b)), \
            f"{k_mine}: independent {a:.2e} vs reported {b:.2e}"
    assert mine["dirichlet"] <= 10.0 * theirs["equality"] + 1e-13, \
        f"Dirichlet residual {mine['dirichlet']:.2e} vs reported equality {theirs['equality']:.2e}"
