"""The parts of a set-up's rows that a new load case changes: Dirichlet values, obstacle gaps.

Gluing, tie and two-body contact rows depend on the reference geometry only. A Dirichlet row
u = u_D takes the new value u_D at its node; an obstacle row −n·u <= φ/|∇φ| the new gap and,
for a curved obstacle that moved, a new normal (then B changes). Both are computed by every
rank for the rows it owns, from its share's dof points and boundary facets — the same code for
every way of holding the mesh:

- a Dirichlet row's value is that of the last condition whose group holds its node (the rule
  of the set-up); the rank that owns the row may not hold the facets of every group at the
  node, so each rank evaluates its conditions on its own facets' points and the values meet
  at the node's home rank (:func:`.distributed_rows.settle_conditions`);
- an obstacle row's node is a point of the owner's subdomain; the rows of the whole problem
  that every rank keeps (``RankRows.contact``) get the new gaps and normals by one gather;
- a friction (tangential) row's right-hand side is 0 for a load case from the unloaded state,
  or, on a load path, the relative tangential displacement B_t u of the previous step (the row
  then measures the slip increment of the step), given by the caller for the rows it owns.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from mpi4py import MPI

from ..errors import InputError, collective
from ..problem.contact_problem import ContactProblem
from .contact import obstacle_gaps
from .dirichlet import condition_values
from .distributed_rows import settle_conditions
from .rows import Kind

#: Normals that differ by less than this (unit vectors) are the same: B is kept.
NORMAL_TOL = 1e-12


class LoadRows:
    """Recomputes the load-dependent right-hand sides of one rank's rows.

    Args:
        share: This rank's share (:class:`~dolfinx_feti.setup.share.RankShare`).
        bs: Components per node.
    """

    def __init__(self, share, bs: int) -> None:
        self.share, self.bs = share, bs
        own = share.rows.own
        self._dirichlet = np.flatnonzero(own.kind == Kind.DIRICHLET)
        self._obstacle = np.flatnonzero(own.kind == Kind.OBSTACLE)
        self.tangential = np.flatnonzero(own.kind == Kind.TANGENT)
        comp = np.zeros(own.size, dtype=np.int64)
        comp[own.e_row] = own.e_comp  # a Dirichlet row has one entry
        self._comp = comp[self._dirichlet]
        self._dir_nodes, self._dir_pos = np.unique(own.node[self._dirichlet],
                                                   return_inverse=True)

    def rows(self, problem: ContactProblem, comm: MPI.Comm,
             tangential: np.ndarray | None = None, tangents_follow: bool = False):
        """This rank's rows with the right-hand sides of ``problem`` (collective).

        Args:
            problem: The new load case.
            comm: The ranks of the set-up.
            tangential: The right-hand sides of this rank's tangential rows (in the order of
                :attr:`tangential`); None for 0 (no slip before the load case).
            tangents_follow: The caller turns the friction rows with the obstacle's new
                normals itself (Newton: drivers/newton_friction.py), so a moved curved
                obstacle with friction is not refused.

        Returns:
            The new :class:`~dolfinx_feti.setup.share.RankRows`, and whether B changed (an
            obstacle's normals moved).

        Raises:
            InputError: On every rank, for bad Dirichlet values or obstacle distances, or a
                moving curved obstacle with friction.
        """
        rows = self.share.rows
        own = rows.own
        rhs = own.rhs.copy()
        with collective(comm, "constraints"):
            records = self._dirichlet_records(problem)
        values = settle_conditions(comm, *records, self.bs, self.share.num_points,
                                   self._dir_nodes)
        new = values[self._dir_pos, self._comp]
        with collective(comm, "constraints"):
            if np.any(np.isnan(new)):
                raise InputError("update: a Dirichlet row's node is fixed by no condition of the "
                                 "new problem")
            rhs[self._dirichlet] = new
            gap, normal = self._obstacles(problem)
        rhs[self._obstacle] = gap
        rhs[self.tangential] = 0.0 if tangential is None else tangential
        moved = comm.allreduce(bool(np.any(
            np.abs(normal - own.normal[self._obstacle]) > NORMAL_TOL)), op=MPI.LOR)
        coef = own.e_coef
        own_normal = own.normal
        several = np.bincount(own.e_row[np.isin(own.e_row, self._obstacle)],
                              minlength=own.size)[self._obstacle] > own.normal.shape[1]
        if moved and comm.allreduce(bool(np.any(several)), op=MPI.LOR):
            raise InputError("update: an obstacle moved so that its normals changed, on "
                             "rows of several nodes (degree-2 tetrahedra); create a new "
                             "FetiSolver")
        if moved:
            own_normal = own.normal.copy()
            own_normal[self._obstacle] = normal
            coef = own.e_coef.copy()
            entry = np.isin(own.e_row, self._obstacle)
            coef[entry] = -own_normal[own.e_row[entry], own.e_comp[entry]]
        contact = self._contact(rows, gap, normal, comm, moved, tangents_follow)
        return replace(rows, own=replace(own, rhs=rhs, e_coef=coef, normal=own_normal),
                       contact=contact), moved

    def _dirichlet_records(self, problem: ContactProblem):
        """(point, condition) and values (NaN where free) of the conditions on my facets."""
        share, bs = self.share, self.bs
        pts_of, cond_of, vals_of = [], [], []
        for i, bc in enumerate(problem.dirichlet):
            facets = [f[bc.group] for f in share.facets.values() if bc.group in f]
            if not facets:
                continue
            on = np.unique(np.concatenate([share.points.facet_points(share.mesh, f).ravel()
                                           for f in facets]))
            comps, v = condition_values(bc, share.points.x[on], bs)
            full = np.full((on.size, bs), np.nan)
            full[:, comps] = v
            pts_of.append(share.point_ids[on])
            cond_of.append(np.full(on.size, i))
            vals_of.append(full)
        if not pts_of:
            return np.zeros((0, 2), dtype=np.int64), np.zeros((0, bs))
        return (np.c_[np.concatenate(pts_of), np.concatenate(cond_of)],
                np.concatenate(vals_of))

    def _obstacles(self, problem: ContactProblem) -> tuple[np.ndarray, np.ndarray]:
        """New gaps and normals of my obstacle rows."""
        own, share = self.share.rows.own, self.share
        rows = self._obstacle
        gap = np.zeros(rows.size)
        normal = np.zeros((rows.size, own.normal.shape[1]))
        x = share.points.x[np.searchsorted(share.point_ids, own.node[rows])]
        for spec in np.unique(own.spec[rows]):
            m = own.spec[rows] == spec
            gap[m], normal[m] = obstacle_gaps(problem.contact[int(spec)], x[m])
        return gap, normal

    def _contact(self, rows, gap: np.ndarray, normal: np.ndarray, comm: MPI.Comm, moved: bool,
                 tangents_follow: bool = False):
        """The contact rows every rank keeps, with the new obstacle gaps and normals."""
        index = rows.start + self._obstacle
        parts = comm.allgather((index, gap, normal))
        index = np.concatenate([p[0] for p in parts])
        contact = rows.contact
        if index.size == 0:
            return contact
        pos = rows.contact_rows(index)
        rhs = contact.rhs.copy()
        rhs[pos] = np.concatenate([p[1] for p in parts])
        if not moved:
            return replace(contact, rhs=rhs)
        if not tangents_follow and np.any(np.isin(contact.spec[contact.kind == Kind.TANGENT],
                                                  contact.spec[pos])):
            raise InputError("update: a rigid obstacle with friction moved so that its normals "
                             "changed; friction rows on a moving curved obstacle are not "
                             "supported by update (create a new FetiSolver)")
        n = contact.normal.copy()
        n[pos] = np.concatenate([p[2] for p in parts])
        return replace(contact, rhs=rhs, normal=n)


__all__ = ["NORMAL_TOL", "LoadRows"]
