"""An independent reference for contact with Tresca (given) and Coulomb friction.

The undecomposed problem is assembled here (through ``reference.assemble``: one DOLFINx mesh
per body, nothing of the FETI machinery), Dirichlet values are eliminated, the contact rows are
built here from the node coordinates (with a tangent basis of our own: 2D t = (−n_y, n_x), the
opposite of the package's; 3D a rotated basis), and the dual problem

    min ½ λᵀ S λ − λᵀ d,   S = B K⁻¹ Bᵀ (dense),   λ_N >= 0,   |λ_T,i| <= g_i (box / disc)

is solved by a semismooth Newton method (``cone_qp``); u follows from K u = f − Bᵀλ. Coulomb
friction is the fixed point g = 𝓕 λ_N over such solves, iterated to round-off. All serial and
deterministic: every MPI rank computes the same thing.
"""

from __future__ import annotations

from dataclasses import dataclass

import cone_qp
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from reference import assemble, traction_load


@dataclass
class FrictionSolution:
    u: np.ndarray  # (N, bs) nodal values
    slave: np.ndarray  # contact nodes
    normal_force: np.ndarray  # per contact node, >= 0
    tangential_force: np.ndarray  # (k, d) force on the slave node, −Σ λ_T t
    slip: np.ndarray  # (k, d) Σ ((u_s − u_m)·t) t
    bound: np.ndarray  # nodal slip bound g_i (a force)
    lam: np.ndarray  # the dual solution [λ_N; λ_T]
    natural_residual: float
    energy: float

    def by_node(self, nodes: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Values given per node in another order → in the order of ``slave``."""
        where = {int(n): i for i, n in enumerate(nodes)}
        return np.asarray(values)[[where[int(s)] for s in self.slave]]


class FrictionReference:
    """The monolithic problem with one flat contact surface.

    Args:
        mesh: :class:`dolfinx_feti.MeshData` (only its arrays are used).
        forms: ``forms(u, v, x, body)`` of ``reference`` (e.g. ``elasticity_forms``).
        dirichlet: [(group, value vector)]: every component prescribed.
        slave: The slave group (the body whose nodes are constrained).
        normal: The contact normal n: the master's (or obstacle's) outward normal.
        master: The master group (node-to-node: paired by the coordinates ``match_axes``), or
            None for a rigid plane ``(x − point)·n <= 0`` (the obstacle).
        point: A point of the plane (obstacle only).
        match_axes: Coordinates that pair slave and master nodes.
        tractions: Group → constant traction vector.
        weights: Instead of pairing: a sparse (slave nodes × all nodes) matrix of master
            weights (mortar), the master point of slave node j being Σ_k w_jk x_k; the rows
            are (u_m − u_s)·n <= gap and (u_s − u_m)·t with u_m = Σ_k w_jk u_k.
    """

    def __init__(self, mesh, forms, *, dirichlet, slave: str, normal, master: str | None = None,
                 point=None, match_axes=(0,), tractions=None, weights=None) -> None:
        bs = mesh.gdim
        self.mesh, self.bs = mesh, bs
        self.K, self.f = assemble(mesh, bs, forms)
        for group, t in (tractions or {}).items():
            self.f = self.f + traction_load(mesh, group, t)
        fixed = np.zeros((mesh.num_nodes, bs), dtype=bool)
        values = np.zeros((mesh.num_nodes, bs))
        for group, value in dirichlet:
            nodes = np.unique(mesh.facet_groups[group])
            fixed[nodes] = True
            values[nodes] = np.asarray(value, dtype=float)
        self.fixed, self.uD = fixed.ravel(), values.ravel()
        n = np.asarray(normal, dtype=float)
        assert abs(np.linalg.norm(n) - 1) < 1e-14
        s = np.unique(mesh.facet_groups[slave])
        if weights is not None:
            W = sp.csr_matrix(weights)
            s = s[np.asarray(W.sum(axis=1)).ravel() > 0]
            W = W[np.asarray(W.sum(axis=1)).ravel() > 0]
            m = None
            gap = (mesh.x[s] - W @ mesh.x) @ n
        elif master is not None:
            m = np.unique(mesh.facet_groups[master])
            key = np.round(mesh.x[:, list(match_axes)] / np.abs(mesh.x).max(), 9)
            index = {tuple(k): i for i, k in zip(m, key[m], strict=True)}
            m = np.array([index[tuple(k)] for k in key[s]])
            gap = (mesh.x[s] - mesh.x[m]) @ n
        else:
            m = None
            gap = (mesh.x[s] - np.asarray(point, dtype=float)) @ n
        if bs == 2:
            T = np.array([[-n[1], n[0]]])
        else:
            a = np.array([0.3, 0.5, 0.8])
            t1 = a - (a @ n) * n
            t1 /= np.linalg.norm(t1)
            T = np.array([t1, np.cross(t1, n)])
        self.slave, self.master, self.n, self.T, self.gap = s, m, n, T, gap
        self.area = traction_load(mesh, slave, [1.0])[s]  # lumped length / area
        k, N = s.size, mesh.num_nodes
        rows, cols, vals = [], [], []

        def add(row, nodes, vec, sign):
            for c in range(bs):
                if vec[c] != 0.0:
                    rows.append(row)
                    cols.append(bs * nodes + c)
                    vals.append(np.full(nodes.size, sign * vec[c]))

        r = np.arange(k)

        def add_weighted(row, vec, sign):  # sign · Σ_k w_jk vec·u_k
            Wc = W.tocoo()
            for c in range(bs):
                if vec[c] != 0.0:
                    rows.append(row[Wc.row])
                    cols.append(bs * Wc.col + c)
                    vals.append(sign * vec[c] * Wc.data)

        add(r, s, n, -1.0)  # (u_m − u_s)·n <= gap
        if m is not None:
            add(r, m, n, 1.0)
        if weights is not None:
            add_weighted(r, n, 1.0)
        for j, t in enumerate(T):  # (u_s − u_m)·t
            rj = k + j * k + r
            add(rj, s, t, 1.0)
            if m is not None:
                add(rj, m, t, -1.0)
            if weights is not None:
                add_weighted(rj, t, -1.0)
        nt = T.shape[0]
        self.B = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                       np.concatenate(cols))),
                               shape=((1 + nt) * k, bs * N))
        self.c = np.concatenate([gap, np.zeros(nt * k)])
        free = np.flatnonzero(~self.fixed)
        D = np.flatnonzero(self.fixed)
        self.free = free
        Kff = self.K[free][:, free].tocsc()
        self.lu = spla.splu(Kff)
        self.rhs0 = self.f[free] - self.K[free][:, D] @ self.uD[D]
        BF = self.B[:, free].toarray()
        KiBt = self.lu.solve(np.ascontiguousarray(BF.T))
        self.S = BF @ KiBt
        self.S = 0.5 * (self.S + self.S.T)
        self.d = BF @ self.lu.solve(self.rhs0) + self.B[:, D] @ self.uD[D] - self.c
        self.k, self.nt = k, nt

    def cone(self, g: np.ndarray) -> cone_qp.ConeSet:
        """The set of the dual for nodal slip bounds g (inf: bonded, 0: frictionless)."""
        k, nt = self.k, self.nt
        lb = np.concatenate([np.zeros(k), np.full(nt * k, -np.inf)])
        ub = np.full((1 + nt) * k, np.inf)
        if nt == 1:
            lb[k:], ub[k:] = -g, g
            return cone_qp.ConeSet(lb, ub)
        pairs = np.stack([k + np.arange(k), 2 * k + np.arange(k)], axis=1)
        return cone_qp.ConeSet(lb, ub, pairs, np.zeros((k, 2)), g)

    def solve_bound(self, g: np.ndarray, lam0=None, slip0=None) -> FrictionSolution:
        """Tresca with nodal bounds g (forces).

        ``slip0``: the tangential rows' right-hand sides (a load path's previous step,
        :meth:`tangential_displacement`; the rows then measure the slip increment); None: 0.
        """
        cs = self.cone(np.asarray(g, dtype=float))
        d = self.d if slip0 is None else self.d - np.concatenate([np.zeros(self.k), slip0])
        lam = cone_qp.solve(self.S, d, cs)
        return self._solution(lam, cs, g, d)

    def tangential_displacement(self, u: np.ndarray) -> np.ndarray:
        """The tangential rows' B_t u of nodal values u (the next step's ``slip0``)."""
        return (self.B @ np.asarray(u).ravel())[self.k:]

    def solve_tresca(self, traction_bound: float) -> FrictionSolution:
        """Tresca with a constant traction bound (× the lumped areas)."""
        return self.solve_bound(traction_bound * self.area)

    def solve_coulomb(self, coefficient: float, max_steps: int = 200,
                      slip0=None) -> FrictionSolution:
        """The Coulomb fixed point g = 𝓕 λ_N from g = ∞, to round-off."""
        g = np.full(self.k, np.inf)
        for _ in range(max_steps):
            sol = self.solve_bound(g, slip0=slip0)
            g_new = coefficient * sol.normal_force
            if np.all(np.isfinite(g)) and np.abs(g_new - g).max() <= 1e-13 * g_new.max():
                return sol
            g = g_new
        raise RuntimeError("the reference Coulomb fixed point did not converge")

    def _solution(self, lam, cs, g, d) -> FrictionSolution:
        k, nt, bs = self.k, self.nt, self.bs
        u = self.uD.copy()
        u[self.free] = self.lu.solve(self.rhs0 - self.B[:, self.free].T @ lam)
        lt = lam[k:].reshape(nt, k).T  # (k, nt)
        slip_c = (self.B @ u)[k:].reshape(nt, k).T
        energy = 0.5 * u @ (self.K @ u) - self.f @ u
        return FrictionSolution(
            u=u.reshape(-1, bs), slave=self.slave, normal_force=lam[:k],
            tangential_force=-(lt @ self.T), slip=slip_c @ self.T,
            bound=np.broadcast_to(np.asarray(g, dtype=float), (k,)).copy(), lam=lam,
            natural_residual=cone_qp.natural_residual(self.S, d, cs, lam), energy=energy)
