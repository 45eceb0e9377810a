"""The rows of a Newton iterate of large-deformation contact, in the current configuration.

:class:`CurrentRows` gives the rank's rows linearized at the iterate u (right-hand sides,
coefficients, normals: obstacles at their nodes' current positions, node-to-node pairs with
the deformed master surface's normals), their violation, and the terms the tangent gets from
the contact: the augmentation κ Σ b_r b_rᵀ on the active obstacle rows and the obstacles'
curvature term −λ ∂n/∂y (see :mod:`.newton` and docs/large_deformation.md).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..constraints.contact import obstacle_gaps
from ..constraints.rows import Kind
from ..mesh.topology import surface_points


def rows_with_rhs(rows, rhs: np.ndarray, comm: MPI.Comm, coef: np.ndarray | None = None,
                  normal: np.ndarray | None = None):
    """``rows`` with the right-hand sides ``rhs`` of the rank's own rows (collective).

    ``coef`` (per entry) and ``normal`` (per row) replace the coefficients and the normals
    (those of the current configuration) when given. The contact rows every rank keeps
    (``rows.contact``) take their right-hand sides and normals by one gather.
    """
    own = rows.own
    normal = own.normal if normal is None else normal
    index = rows.start + np.arange(own.size)
    mine = np.isin(index, rows.contact_index)
    parts = comm.allgather((index[mine], rhs[mine], normal[mine]))
    idx = np.concatenate([p[0] for p in parts])
    contact = rows.contact
    if idx.size:
        pos = rows.contact_rows(idx)
        crhs, cnormal = contact.rhs.copy(), contact.normal.copy()
        crhs[pos] = np.concatenate([p[1] for p in parts])
        cnormal[pos] = np.concatenate([p[2] for p in parts])
        contact = replace(contact, rhs=crhs, normal=cnormal)
    own = replace(own, rhs=np.asarray(rhs, dtype=float), normal=normal,
                  e_coef=own.e_coef if coef is None else coef)
    return replace(rows, own=own, contact=contact)


def pair_displacements(solver, comm: MPI.Comm, contact, u: PETSc.Vec, mesh) -> np.ndarray:
    """The displacements (points, gdim) of the node-to-node pairs' nodes, on every rank.

    Zero at every other point of ``mesh`` (the problem's); gathered from the ranks holding
    them (surfaces only).
    """
    data = solver.data
    pairs = (contact.kind == Kind.CONTACT) & (contact.partner >= 0)
    points = np.unique(np.r_[contact.node[pairs], contact.partner[pairs]])
    mine = np.isin(data.dof_node, points)
    parts = comm.allgather((data.dof_node[mine], data.dof_comp[mine], u.array_r[mine]))
    U = np.zeros((mesh.num_nodes, mesh.gdim))
    for nodes, comps, vals in parts:  # copies of a point agree to the gluing's round-off
        U[nodes, comps] = vals
    return U


class CurrentRows:
    """The rows of the iterate for one FetiSolver (collective methods).

    Args:
        solver: The FetiSolver (its rows' layout, its B, its subdomains).
        comm: The ranks.
        kappa: The stiffness scale max_i Σ_j |K_ij| of the augmentation.

    Attributes:
        geometry: The obstacle rows, their nodes' positions and the problem of the last
            :meth:`at` with ``keep`` (where the curvature term is taken).
        dropped: The largest component of a pair's deformed normal that its row has no
            entry for (projected back; must vanish at a solution).
    """

    def __init__(self, solver, comm: MPI.Comm, kappa: float) -> None:
        self.solver, self.comm, self.kappa = solver, comm, kappa
        self.geometry = None
        self.dropped = 0.0
        self.friction = None  # the tangential rows' hook (drivers/newton_friction.py)
        self.pair_u = None  # the pairs' nodes' displacements of the last at() (all ranks)

    def augmentation(self, lam: PETSc.Vec | None, curved: bool = True):
        """κ Σ b_r b_rᵀ over the rows active in the last QP (λ_r > 0), b_r in physical units.

        Convex on the critical cone of the contact, where the bare tangent
        of a compressed surface may not be; a constant on the step when the active set is
        right (B_r Δu is fixed there), so the Newton step and its fixed point are unchanged.
        """
        if lam is None:
            return None
        rows = self.solver.qp.rows
        own, data, kappa = rows.own, self.solver.data, self.kappa
        lam_phys = lam.array_r * own.scale
        # rows of one subdomain only (obstacles): K stays block diagonal
        # rows of one subdomain only (obstacles): a pair row couples two subdomains, and
        # K must stay block diagonal (its two sides apart would change the step)
        lo = np.full(own.size, np.iinfo(np.int64).max)
        hi = np.full(own.size, -1)
        np.minimum.at(lo, own.e_row, own.e_sub.astype(np.int64))
        np.maximum.at(hi, own.e_row, own.e_sub.astype(np.int64))
        active = own.inequality & (lam_phys > 0) & (lo == hi)
        entry = active[own.e_row]
        r, col = own.e_row[entry], rows.cols[entry] - data.primal_start
        coef = own.e_coef[entry] / own.scale[r]
        n = data.K.shape[0]
        Ba = sp.csr_matrix((coef, (r, col)), shape=(own.size, n))
        aug = kappa * (Ba.T @ Ba)
        return (aug + self.curvature(lam_phys, rows, n) if curved else aug).tocsr()

    def curvature(self, lam_phys: np.ndarray, rows, n: int) -> sp.csr_matrix:
        """−λ_r ∂n/∂y at the node of every active obstacle row (zero for a plane).

        The derivative of the contact force λ n(x + u), by central differences of the
        obstacle's normals.
        """
        geometry = self.geometry
        if geometry is None:
            return sp.csr_matrix((n, n))
        obst, y, problem = geometry
        own = rows.own
        act = lam_phys[obst] > 0
        ya, ra, lam = y[act], obst[act], lam_phys[obst][act]
        if not ra.size:
            return sp.csr_matrix((n, n))
        gdim = ya.shape[1]
        eps = 1e-6 * (1.0 + float(np.abs(ya).max()))
        dn = np.zeros((ra.size, gdim, gdim))
        spec = own.spec[ra]
        for j in range(gdim):
            step = np.zeros(gdim)
            step[j] = eps
            for sp_ in np.unique(spec):
                m = spec == sp_
                cond = problem.contact[int(sp_)]
                dn[m, :, j] = (obstacle_gaps(cond, ya[m] + step)[1]
                               - obstacle_gaps(cond, ya[m] - step)[1]) / (2 * eps)
        dn = 0.5 * (dn + dn.transpose(0, 2, 1))  # a Hessian of the distance: symmetric
        colmap = np.full((own.size, gdim), -1, dtype=np.int64)
        ent = np.flatnonzero(np.isin(own.e_row, ra))
        colmap[own.e_row[ent], own.e_comp[ent]] = rows.cols[ent] - self.solver.data.primal_start
        C = colmap[ra]
        ii = np.broadcast_to(C[:, :, None], dn.shape).ravel()
        jj = np.broadcast_to(C[:, None, :], dn.shape).ravel()
        return sp.csr_matrix(((-lam[:, None, None] * dn).ravel(), (ii, jj)), shape=(n, n))

    def Bu(self, u: PETSc.Vec) -> np.ndarray:
        """B u on this rank's rows (the solver's current B)."""
        B = self.solver.qp.system.B
        out = B.createVecLeft()
        B.mult(u, out)
        a = out.array_r.copy()
        out.destroy()
        return a

    def at(self, problem, rows0, c0: np.ndarray, u: PETSc.Vec, keep: bool = False):
        """The rank's rows linearized at u: right-hand sides, coefficients, normals.

        Rows linear in u (gluing, Dirichlet) take c − B u; an obstacle row the gap and the
        normal of the current position x + u of its node (for a plane the same as c − B u).
        """
        own = rows0.own
        rhs = c0 - self.Bu(u)
        coef, normal = own.e_coef.copy(), own.normal.copy()
        # node-to-node pairs (a mortar row has no partner: drivers/current_mortar.py)
        pairs = (rows0.contact.kind == Kind.CONTACT) & (rows0.contact.partner >= 0)
        if np.any(pairs):  # the same on every rank (the contact rows are replicated)
            self._pairs_at(problem, rows0, u, rhs, coef, normal)
        obst = np.flatnonzero(own.kind == Kind.OBSTACLE)
        if self.comm.allreduce(obst.size, op=MPI.SUM):
            self._obstacles_at(problem, rows0, u, obst, rhs, coef, normal, keep)
        if self.friction is not None:
            self.friction.at(u, rhs, coef, normal, self.pair_u)
        return rhs, coef, normal

    def _obstacles_at(self, problem, rows0, u: PETSc.Vec, obst: np.ndarray, rhs, coef, normal,
                      keep: bool) -> None:
        """Obstacle rows at u, in place: the gap and the normal of the nodes' positions."""
        own = rows0.own
        data, share = self.solver.data, self.solver.qp.share
        pos = np.full(own.size, -1)
        pos[obst] = np.arange(obst.size)
        ent = np.flatnonzero(pos[own.e_row] >= 0)
        local = rows0.cols[ent] - data.primal_start
        gdim = own.normal.shape[1]
        U = np.zeros((obst.size, gdim))
        U[pos[own.e_row[ent]], own.e_comp[ent]] = u.array_r[local]
        x = share.points.x[np.searchsorted(share.point_ids, own.node[obst])][:, :gdim] + U
        gap, n = np.zeros(obst.size), np.zeros((obst.size, gdim))
        for spec in np.unique(own.spec[obst]):
            m = own.spec[obst] == spec
            gap[m], n[m] = obstacle_gaps(problem.contact[int(spec)], x[m])
        rhs[obst] = gap * own.scale[obst]
        if keep:  # the positions the next tangent's curvature term is taken at
            self.geometry = (obst, x, problem)
        coef[ent] = -n[pos[own.e_row[ent]], own.e_comp[ent]] * own.scale[own.e_row[ent]]
        normal[obst] = n

    def _pairs_at(self, problem, rows0, u: PETSc.Vec, rhs, coef, normal) -> None:
        """Node-to-node rows at u, in place (collective).

        The normal of the deformed master surface at the master node, the gap of the current
        positions. The displacements of the pairs' nodes are gathered on every rank (surfaces only).
        """
        own, contact = rows0.own, rows0.contact
        mesh = problem.mesh
        pairs = (contact.kind == Kind.CONTACT) & (contact.partner >= 0)
        U = pair_displacements(self.solver, self.comm, contact, u, mesh)
        self.pair_u = U
        gdim = mesh.gdim
        y = mesh.x[:, :gdim] + U
        n_at = np.zeros((mesh.num_nodes, gdim))
        for spec in np.unique(contact.spec[pairs]):
            cond = problem.contact[int(spec)]
            facets = mesh.facets(cond.master)
            weights = np.full(facets.shape[1], 1.0 / facets.shape[1])
            nodes, nrm, _ = surface_points(y, mesh.cells, facets, facets, weights,
                                           mesh.cell_type)
            n_at[nodes] = nrm
        rows = np.flatnonzero((own.kind == Kind.CONTACT) & (own.partner >= 0))
        s_node, m_node = own.node[rows], own.partner[rows]
        n = n_at[m_node]
        pos = np.full(own.size, -1)
        pos[rows] = np.arange(rows.size)
        ent = np.flatnonzero(pos[own.e_row] >= 0)
        r = pos[own.e_row[ent]]
        # the set-up kept only the components its normals needed: a normal that turns out
        # of them is projected back (an iterate on the way; the solution must not need it)
        have = np.zeros((rows.size, gdim), dtype=bool)
        have[r, own.e_comp[ent]] = True
        dropped = float(np.abs(n[~have]).max(initial=0.0))
        self.dropped = self.comm.allreduce(dropped, op=MPI.MAX)
        n = np.where(have, n, 0.0)
        n /= np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]
        rhs[rows] = own.scale[rows] * np.einsum("ij,ij->i", y[s_node] - y[m_node], n)
        normal[rows] = n
        sign = np.where(own.e_node[ent] == s_node[r], -1.0, 1.0)
        coef[ent] = sign * n[r, own.e_comp[ent]] * own.scale[own.e_row[ent]]

    def c_at(self, problem, rows0, c0: np.ndarray, u: PETSc.Vec) -> np.ndarray:
        """c such that B u − c is the rows' value at the current u, for the solver's B.

        For an obstacle or a pair row: −gap. What the KKT check and the Solution's contact
        data read.
        """
        return self.Bu(u) + self.at(problem, rows0, c0, u)[0]

    def violation(self, rhs: np.ndarray, own) -> np.ndarray:
        """The violation of the rows (physical units) given their right-hand sides at u."""
        v = -rhs / own.scale
        v[own.kind == Kind.TANGENT] = 0.0  # a slip, not a violation
        ineq = own.inequality
        v[ineq] = np.maximum(v[ineq], 0.0)
        return v


__all__ = ["CurrentRows", "rows_with_rhs"]
