"""Friction under Newton: tangential rows in the current configuration on the incremental slip.

A contact node with friction has, next to its normal row, gdim − 1 tangential rows: t·u on a
rigid obstacle, s·t·(u_slave − u_master) on a node-to-node pair (s = 1/√2,
constraints/friction.py). Under large deformation (:mod:`.newton`) each Newton iterate u_k
takes

- the tangents of the current normal n(x + u_k) (2D: t = (n_y, −n_x); 3D: the basis of
  :func:`~dolfinx_feti.constraints.friction.tangent_basis`); for a plane they never change;
- the right-hand side of the **slip increment of the load step**: the row of the increment
  Δu is t·Δu = t·(u_0 + Δd) − t·u_k, u_0 the node's displacement at the end of the last
  converged step and Δd how far the obstacle carried the material point of its surface at
  the node's position x + u_0 since then (:func:`.obstacle_motion.obstacle_motion`: the
  rigid motion of a :class:`~dolfinx_feti.RigidMotion` — a spinning or rolling disc — or the
  translation of a moved :class:`~dolfinx_feti.Plane`'s ``point``, a moved
  :class:`~dolfinx_feti.Sphere`'s ``center``). So B_t u − c_t = t·(u − u_0 − Δd) is the slip
  relative to the obstacle in the step, a node that sticks keeps its position on the
  obstacle, and the
  friction law (Tresca's bound, or Coulomb's fixed point over Tresca solves that every
  :meth:`FetiSolver.solve` runs) is that of the small-deformation load paths, per step.

Mortar pairs are not handled here: their rows are re-searched at every iterate, with the
slip of the step measured on the surfaces' displacement since its start
(:mod:`.mortar_friction`).

A node-to-node pair takes the tangents of its row's current normal (the deformed master
surface's at the master node, drivers/current_rows.py) and the slip increment of the slave
node relative to its master node, which the master body carries (the master point of a pair
is a node): s·t·Δu_rel = s·t·(v_0 − v_k), v = u_slave − u_master, v_0 at the end of the last
converged step. So B_t u − c_t = s·t·(v − v_0), the relative slip in the step, as on a
small-deformation load path (``FetiSolver.update(slip_from=...)``).

The multipliers of the increment QP are the total forces, so at Δu = 0 its friction
conditions are those of the nonlinear step. Not in the tangent: the derivative of the tangents
(λ_T ∂t/∂y, zero for a plane): on a curved obstacle with friction Newton converges
linearly, not quadratically, near the solution.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..constraints.friction import tangent_basis
from ..constraints.rows import Kind
from ..problem.contact_problem import ContactProblem
from .current_rows import pair_displacements
from .obstacle_motion import obstacle_motion


class IncrementalSlip:
    """The tangential rows of a Newton iterate (module docstring), for one FetiSolver.

    Args:
        solver: The FetiSolver (its rows' layout and subdomains).
        comm: The ranks.

    Attributes:
        t: Local indices of the rank's tangential rows on rigid obstacles.
        n_of: The local normal (obstacle) row of each.
        k_of: Which tangent of its node each one is (0, or 0 and 1 in 3D).
        pairs: The rank's tangential rows of node-to-node pairs (:class:`_PairSlip`).
    """

    def __init__(self, solver, comm: MPI.Comm) -> None:
        self.solver, self.comm = solver, comm
        own = solver.qp.rows.own
        tang = own.kind == Kind.TANGENT
        # the rows of one node are consecutive, its normal row first
        last_ineq = np.maximum.accumulate(np.where(own.inequality, np.arange(own.size), -1))
        normal_kind = own.kind[np.maximum(last_ineq, 0)]
        pair = tang & (normal_kind == Kind.CONTACT) & (own.partner >= 0)
        mortar = tang & (normal_kind == Kind.CONTACT) & (own.partner < 0)
        # mortar pairs measure their slip themselves (drivers/mortar_friction.py); with
        # them no other friction (drivers/newton.check_newton_problem)
        self.pairs = _PairSlip(own, np.flatnonzero(pair), last_ineq)
        self.t = np.flatnonzero(tang & ~pair & ~mortar)
        self.n_of = last_ineq[self.t]
        self.k_of = self.t - self.n_of - 1
        self.gdim = own.normal.shape[1]
        # the entries of each row's node, all components (the normal row keeps every one)
        pos = np.full(own.size, -1)
        pos[self.n_of] = self.n_of
        ent = np.flatnonzero(pos[own.e_row] >= 0)
        cols = np.full((own.size, self.gdim), -1, dtype=np.int64)
        cols[own.e_row[ent], own.e_comp[ent]] = solver.qp.rows.cols[ent] - solver.data.primal_start
        self._cols = cols[self.n_of]  # (t rows, gdim) local columns of the node
        is_t = np.zeros(own.size, dtype=bool)
        is_t[self.t] = True
        tent = np.flatnonzero(is_t[own.e_row])
        self._t_ent = tent
        self._t_row = np.searchsorted(self.t, own.e_row[tent])
        if np.any(self._cols < 0) or not np.array_equal(self.t[self._t_row], own.e_row[tent]):
            raise AssertionError("a tangential row's node has no entry for every component")
        self._u0 = np.zeros((self.t.size, self.gdim))
        self._d = np.zeros((self.t.size, self.gdim))
        share = solver.qp.share  # the reference position of each row's node
        self._x = share.points.x[np.searchsorted(share.point_ids, own.node[self.t])][:, :self.gdim]
        self._done: ContactProblem | None = None  # the problem of the last converged step
        self._any_pair = comm.allreduce(self.pairs.rows.size, op=MPI.SUM) > 0

    def begin(self, u: PETSc.Vec, problem: ContactProblem) -> None:
        """Start a load step from the converged state ``u`` towards ``problem`` (collective)."""
        if self._any_pair:
            self.pairs.begin(pair_displacements(self.solver, self.comm,
                                                self.solver.qp.rows.contact, u, problem.mesh))
        self._u0 = u.array_r[self._cols]
        own = self.solver.qp.rows.own
        # from the unloaded state: no slip history, no motion
        if self._done is None or not self.t.size:
            self._d = np.zeros_like(self._u0)
            return
        self._d = obstacle_motion(self._done, problem, own.spec[self.t], self._x + self._u0,
                                  translate=True)

    def converged(self, problem: ContactProblem) -> None:
        """The step to ``problem`` converged: the next one starts from it."""
        self._done = problem

    def at(self, u: PETSc.Vec, rhs: np.ndarray, coef: np.ndarray, normal: np.ndarray,
           pair_u: np.ndarray | None = None) -> None:
        """The tangential rows at u, in place (after the normal rows took the current normals).

        Right-hand sides of the increment t·(u_0 + Δd − u) (pairs: s·t·(v_0 − v)),
        coefficients scale·t, normals t. ``pair_u``: the pairs' nodes' displacements at u
        (:func:`.current_rows.pair_displacements`).
        """
        own = self.solver.qp.rows.own
        if self.pairs.rows.size:
            self.pairs.at(own, pair_u, rhs, coef, normal)
        if not self.t.size:
            return
        T = tangent_basis(normal[self.n_of])  # (rows, gdim − 1, gdim)
        t = T[np.arange(self.t.size), self.k_of]
        s = own.scale[self.t]
        U = u.array_r[self._cols]
        rhs[self.t] = s * np.einsum("ij,ij->i", t, self._u0 + self._d - U)
        normal[self.t] = t
        ent = self._t_ent
        coef[ent] = s[self._t_row] * t[self._t_row, own.e_comp[ent]]


class _PairSlip:
    """The tangential rows of node-to-node pairs at an iterate (module docstring).

    Args:
        own: The rank's rows.
        rows: The local indices of its pairs' tangential rows.
        last_ineq: Per row, the local index of the last inequality row up to it (its node's
            normal row for a tangential one).
    """

    def __init__(self, own, rows: np.ndarray, last_ineq: np.ndarray) -> None:
        self.rows = rows
        self.n_of = last_ineq[rows]
        self.k_of = rows - self.n_of - 1
        self.slave, self.master = own.node[rows], own.partner[rows]
        at = np.full(own.size, -1)
        at[rows] = np.arange(rows.size)
        ent = np.flatnonzero(at[own.e_row] >= 0)
        self._ent, self._row = ent, at[own.e_row[ent]]
        # + on the slave node's entries, − on the master's (constraints/friction.py)
        self._sign = np.where(own.e_node[ent] == self.slave[self._row], 1.0, -1.0)
        self._v0 = np.zeros((rows.size, own.normal.shape[1]))

    def begin(self, U: np.ndarray) -> None:
        """The relative displacements v_0 at the start of the step (U: the nodes')."""
        self._v0 = U[self.slave] - U[self.master]

    def at(self, own, U: np.ndarray, rhs, coef, normal) -> None:
        """The rows at the displacements U of the pairs' nodes, in place."""
        T = tangent_basis(normal[self.n_of])
        t = T[np.arange(self.rows.size), self.k_of]
        s = own.scale[self.rows]
        v = U[self.slave] - U[self.master]
        rhs[self.rows] = s * np.einsum("ij,ij->i", t, self._v0 - v)
        normal[self.rows] = t
        r = self._row
        coef[self._ent] = self._sign * s[r] * t[r, own.e_comp[self._ent]]


__all__ = ["IncrementalSlip"]
