"""Mortar contact rows of a Newton iterate: the search and the integrals on the deformed surfaces.

At the iterate u_k the contact search and the segment-to-segment integrals D, M of every
:class:`~dolfinx_feti.Mortar` condition are redone on the current surfaces x + u_k (the
builders of the set-up, :func:`.constraints.mortar_rows.mortar_contact_rows`, on the cells
along the surfaces, rank 0), and the rows of the increment's QP are

    B_j(u_k) Δu <= g̃_j(u_k),   g̃_j = s_j n_j·((x_j + u_j) − Σ_k w_jk (x_k + u_k))

with w_jk = M_jk / D_j, the averaged slave normal n_j and the scale s_j all of the
configuration x + u_k, and B_j(u_k) their gradient with D, M and n frozen (the standard
linearization of the weighted gap; the derivatives of D, M and n are not in the tangent). The
residual's contact forces are B(u)ᵀλ with the D, M, n of the iterate. Newton stops only when
:meth:`DeformedMortar.kkt_at`, the search and the integrals redone at the last iterate u
itself, finds the weighted non-penetration g̃(u) >= 0, λ >= 0, λ_j g̃_j(u) = 0 and the
equilibrium r(u) = B(u)ᵀλ of that configuration within the Newton tolerance: not a
linearized version of them (the rows of the iterate before give those only to first order in
the last increment, since their D, M, n are frozen).

The set of coupled slave nodes, so the number of rows and the master nodes of a row, may
change from one iterate to the next: :meth:`DeformedMortar.relayout` gives the rank's rows in
a new layout (the other rows kept, each mortar row on the rank of its smallest subdomain, the
order of the set-up: stable by smallest subdomain), which
:meth:`~dolfinx_feti.FetiSolver.update_stiffness` takes with the tangent (it rebuilds B from
the rows anyway).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..constraints.mortar_rows import mortar_contact_rows
from ..constraints.rows import Kind, Rows
from ..errors import InputError, collective
from ..parallel.exchange import exclusive_scan
from ..problem.contact_problem import ContactProblem, Mortar
from ..setup.share import RankRows, row_subset
from .mortar_friction import MortarSlip
from .mortar_linearization import RowDerivatives, RowsAt


def check_mortar(c: Mortar, problem: ContactProblem) -> None:
    """Mortar contact under Newton: degree 1, a vector problem, two surfaces."""
    if problem.value_size == 1 or problem.degree != 1:
        raise InputError("large-deformation contact: mortar contact of degree-1 meshes and a "
                         "vector problem only")
    if c.slave == c.master:
        raise InputError("large-deformation contact: mortar self-contact is not supported by "
                         "the Newton driver")
    if problem.mesh.part is not None:
        raise InputError("large-deformation contact: mortar contact on a distributed mesh "
                         "(distribute=True) is not supported by the Newton driver; read the "
                         "mesh whole")


def _permuted_cols(rows: Rows, cols: np.ndarray, order: np.ndarray) -> np.ndarray:
    """The entries' columns in the order :meth:`Rows.permuted` gives the entries."""
    new_of_old = np.full(rows.size, -1, dtype=np.int64)
    new_of_old[order] = np.arange(order.size)
    e_new = new_of_old[rows.e_row]
    kept = np.flatnonzero(e_new >= 0)
    return cols[kept[np.argsort(e_new[kept], kind="stable")]]


class DeformedMortar:
    """The mortar contact rows of the iterates of one Newton set-up (collective methods).

    Args:
        solver: The FetiSolver (its surfaces on rank 0, its subdomains).
        problem: The problem (its :class:`~dolfinx_feti.Mortar` conditions).
        comm: The ranks.

    Attributes:
        specs: The indices of the mortar conditions in ``problem.contact``.
        infos: What the last search found, per condition (every rank).
    """

    def __init__(self, solver, problem: ContactProblem, comm: MPI.Comm) -> None:
        self.solver, self.comm = solver, comm
        self.specs = np.array([i for i, c in enumerate(problem.contact) if c.mortar],
                              dtype=np.int32)
        self.infos: list = []
        self.consistent = True  # the rows' derivatives in the Newton step (mortar_step.py)
        self.derivs: RowsAt | None = None  # rank 0: the rows of the last iterate
        self.derived = False  # every rank: whether derivs are of the current iterate
        self.dofs: np.ndarray | None = None  # rank 0: the surfaces' dofs (derivs' domain)
        surface = solver.qp.surface
        points = comm.bcast(surface.point_ids if comm.rank == 0 else None, root=0)
        self._points = points  # the global dof points of the cells along the surfaces
        data = solver.data
        self._bs, self._gdim = data.bs, data.gdim
        # every copy of a surface point, its subdomain and its global column
        at = np.flatnonzero(np.isin(data.dof_node, points))
        parts = comm.allgather((data.dof_node[at], data.dof_sub[at], data.dof_comp[at],
                                data.primal_start + at))
        node, sub, comp, col = (np.concatenate([p[i] for p in parts]) for i in range(4))
        pos = np.searchsorted(points, node)
        # the copy in the smallest subdomain of each point: where the set-up's rows sit
        first = np.full(points.size, np.iinfo(np.int64).max)
        np.minimum.at(first, pos, sub.astype(np.int64))
        mine = sub == first[pos]
        self._first = first
        self._col = np.full((points.size, self._bs), -1, dtype=np.int64)
        self._col[pos[mine], comp[mine]] = col[mine]
        lo, hi = data.primal_start, data.primal_start + data.K.shape[0]
        self._here = np.flatnonzero((self._col >= lo) & (self._col < hi))  # flat (point, comp)
        # friction: the slip of each step, from the surfaces' displacement at its start (rank 0
        # holds the surfaces; drivers/mortar_friction.py)
        slip = MortarSlip(problem, self.specs, getattr(surface, "fixed", None))
        self.friction = bool(slip.with_friction)  # the problem is the same on every rank
        self.slip = slip if comm.rank == 0 and self.friction else None

    def _displacement(self, u: PETSc.Vec) -> np.ndarray | None:
        """The displacement of the surfaces' points (rank 0; None elsewhere), from u."""
        data = self.solver.data
        cols = self._col.ravel()[self._here]
        parts = self.comm.gather((self._here, u.array_r[cols - data.primal_start]), root=0)
        if self.comm.rank != 0:
            return None
        U = np.zeros(self._col.size)
        for where, vals in parts:
            U[where] = vals
        return U.reshape(self._col.shape)

    def rows_at(self, problem: ContactProblem, u: PETSc.Vec):
        """The mortar rows of the configuration x + u (collective; every rank).

        Returns:
            ``(rows, cols, c)``: the rows in global dof points (the whole problem's), the
            global column of every entry, and per row −B_j x (so that c − B_j u' is the gap
            of any u' linearized with this iterate's D, M and n: the right-hand side of the
            increment from u' and the violation of a trial point).
        """
        U = self._displacement(u)
        out = None
        with collective(self.comm, "constraints"):
            if self.comm.rank == 0:
                out = self._build(problem, U)
        rows, cols, c, self.infos = self.comm.bcast(out, root=0)
        return rows, cols, c

    def _layer_rows(self, problem: ContactProblem, U: np.ndarray) -> tuple[Rows, list]:
        """Rank 0: the rows on the deformed cells along the surfaces (the layer's points)."""
        layer = self.solver.qp.surface.problem.mesh
        x = layer.x.copy()
        x[:, : self._gdim] += U[:, : self._gdim]
        deformed = replace(layer, x=x)
        ptr = np.arange(self._points.size + 1)
        blocks, infos = [], []
        for i in self.specs:
            rows, info = mortar_contact_rows(deformed, problem.contact[int(i)], int(i), ptr,
                                             self._first, self._bs)
            blocks.append(rows if self.slip is None else self.slip.rows_of(rows, int(i)))
            infos.append(info)
        return (Rows.concatenate(blocks) if blocks else Rows.empty(self._gdim)), infos

    def _build(self, problem: ContactProblem, U: np.ndarray):
        """Rank 0: the rows on the deformed cells along the surfaces."""
        rows, infos = self._layer_rows(problem, U)
        if not np.all(np.isfinite(rows.rhs)) or not np.all(np.isfinite(rows.e_coef)):
            raise InputError("large-deformation contact: non-finite mortar rows at the "
                             "iterate (a surface turned inside out)")
        if self.slip is not None:  # the tangential rows act on the slip of the step
            rows = replace(rows, rhs=self.slip.rhs(rows, U))
        Bu = np.zeros(rows.size)
        np.add.at(Bu, rows.e_row, rows.e_coef * U[rows.e_node, rows.e_comp])
        cols = self._col[rows.e_node, rows.e_comp]
        gmap = self._points
        rows = replace(rows, e_node=gmap[rows.e_node], node=gmap[rows.node])
        return rows, cols, rows.rhs + Bu, infos

    def begin(self, u: PETSc.Vec) -> None:
        """A load step starts from the converged ``u``: the slip is measured from it.

        Collective; nothing without friction (drivers/mortar_friction.py).
        """
        if not self.friction:
            return
        U = self._displacement(u)
        if self.comm.rank == 0:
            self.slip.begin(U)

    def friction_rows(self, rows: RankRows):
        """The friction data of ``rows`` (a layout of the mortar rows; collective)."""
        from ..setup.share_distributed import surface_friction

        fdata = None
        with collective(self.comm, "friction"):
            if self.comm.rank == 0:
                fdata = surface_friction(self.solver.qp.surface, rows)
        return self.comm.bcast(fdata, root=0)

    def surface_dofs(self, problem: ContactProblem) -> np.ndarray:
        """Rank 0: the flat (point, component) dofs of the mortar surfaces' nodes."""
        layer = self.solver.qp.surface.problem.mesh
        names = [n for i in self.specs for n in (problem.contact[int(i)].slave,
                                                 problem.contact[int(i)].master)]
        nodes = np.unique(np.concatenate([layer.facets(n).ravel() for n in names]))
        return (nodes[:, None] * self._bs + np.arange(self._gdim)).ravel()

    def rows_at_iterate(self, problem: ContactProblem, u: PETSc.Vec, old: RankRows,
                        lam: PETSc.Vec | None) -> RowsAt | None:
        """The rows of x + u with their derivatives' products (:mod:`.mortar_linearization`).

        Collective.

        Args:
            problem: The problem of the step.
            u: The iterate.
            old: The rows of the last QP (their layout), whose multipliers are ``lam``.
            lam: The last QP's multipliers: the forces (physical, by slave node) of H.

        Returns:
            On rank 0 the rows, the surfaces' points as nodes; None elsewhere.
        """
        U = self._displacement(u)
        own = old.own
        mortar = (own.kind == Kind.CONTACT) & np.isin(own.spec, self.specs)
        phys = np.zeros(int(mortar.sum())) if lam is None else \
            lam.array_r[mortar] * own.scale[mortar]
        parts = self.comm.gather((own.spec[mortar], own.node[mortar], phys), root=0)
        out = None
        with collective(self.comm, "constraints"):
            if self.comm.rank == 0:
                spec, node, val = (np.concatenate([p[i] for p in parts]) for i in range(3))
                # the rows' nodes are global dof points: the layer's points are self._points
                local = np.searchsorted(self._points, node)

                def build(V: np.ndarray) -> Rows:
                    return self._layer_rows(problem, V)[0]

                base = build(U)
                key = spec.astype(np.int64) * self._points.size + local
                want = base.spec.astype(np.int64) * self._points.size + base.node
                srt = np.argsort(key)
                pos = np.minimum(np.searchsorted(key[srt], want), max(key.size - 1, 0))
                hit = (key[srt][pos] == want) if key.size else np.zeros(want.size, bool)
                lam_base = np.where(hit, val[srt][pos] if key.size else 0.0, 0.0)
                out = RowsAt(build, U, lam_base, base=base)
        return out

    def derivatives(self, problem: ContactProblem, u: PETSc.Vec, old: RankRows,
                    lam: PETSc.Vec | None) -> RowDerivatives | None:
        """G and H of the rows of x + u as matrices on the surfaces' dofs (collective).

        Arguments as :meth:`rows_at_iterate`; on rank 0 the derivatives, None elsewhere.
        """
        at = self.rows_at_iterate(problem, u, old, lam)
        return None if at is None else at.dense(self.surface_dofs(problem))

    def linearization(self, problem: ContactProblem, u: PETSc.Vec, old: RankRows,
                      lam: PETSc.Vec | None) -> None:
        """The rows of u and their derivatives' products for :func:`.mortar_step.exact_step`.

        Keeps :attr:`derivs` (rank 0) and :attr:`dofs`, the surfaces' dofs (collective).
        None of it enters the factored tangent: H is unsymmetric and couples the two bodies
        (FETI's K is symmetric and block diagonal), and its symmetric part made the tangent
        of the blocks compressed 40 % indefinite; all of it goes to the inner QPs'
        right-hand sides.
        """
        self.derivs, self.derived = None, False
        if not self.consistent:
            return
        self.derivs = self.rows_at_iterate(problem, u, old, lam)
        if self.comm.rank == 0:
            self.dofs = self.surface_dofs(problem)
        self.derived = True

    def relayout(self, problem: ContactProblem, rows: RankRows, c0: np.ndarray,
                 u: PETSc.Vec) -> tuple[RankRows, RankRows, np.ndarray]:
        """The rank's rows with the mortar rows of x + u (collective).

        Args:
            problem: The problem of the step.
            rows: The rank's rows linearized at u (the right-hand sides of the increment), in
                the solver's current layout.
            c0: The problem's right-hand sides of the same rows (``c0 − B u`` is the value of
                a row at u).
            u: The iterate.

        Returns:
            ``(rows, rows0, c0)`` in the new layout: the rows of the increment (the mortar
            rows' right-hand sides the weighted gaps of x + u), the same with the right-hand
            sides ``c0``, and ``c0`` (the mortar rows' −B_j x).
        """
        comm = self.comm
        new, new_cols, new_c = self.rows_at(problem, u)
        own = rows.own
        keep = np.flatnonzero(~self._mortar(own))
        sub_rank = self.solver.qp.share.dec.sub_rank
        here = np.flatnonzero(np.asarray(sub_rank)[new.min_subdomain()] == comm.rank)
        e_here = np.isin(new.e_row, here)
        kept = Rows.concatenate([row_subset(own, keep), row_subset(new, here)])
        cols = np.concatenate([rows.cols[np.isin(own.e_row, keep)], new_cols[e_here]])
        rhs_new = np.r_[own.rhs[keep], new.rhs[here]]
        c_new = np.r_[c0[keep], new_c[here]]
        order = np.argsort(kept.min_subdomain(), kind="stable")
        cols = _permuted_cols(kept, cols, order)
        kept = kept.permuted(order)
        rhs_new, c_new = rhs_new[order], c_new[order]
        own_new = replace(kept, rhs=rhs_new)
        start = exclusive_scan(comm, own_new.size)
        size = comm.allreduce(own_new.size)
        contact, index = self._contact(own_new, start)
        out = RankRows(own=own_new, cols=cols, start=start, size=size, contact=contact,
                       contact_index=index)
        out0 = replace(out, own=replace(own_new, rhs=c_new))
        return out, out0, c_new

    def _mortar(self, own: Rows) -> np.ndarray:
        """Mask of the mortar contact rows of ``own`` and their tangential rows."""
        return ((own.kind == Kind.CONTACT) | (own.kind == Kind.TANGENT)) & \
            np.isin(own.spec, self.specs)

    def _contact(self, own: Rows, start: int) -> tuple[Rows, np.ndarray]:
        """The contact and friction rows of every rank in global order, and their indices."""
        mine = np.flatnonzero(own.inequality | own.tangential)
        parts = self.comm.allgather((row_subset(own, mine), mine + start))
        return (Rows.concatenate([p[0] for p in parts]),
                np.concatenate([p[1] for p in parts]).astype(np.int64))

    def kkt_at(self, problem: ContactProblem, u: PETSc.Vec, lam: PETSc.Vec, c_now: np.ndarray,
               r: np.ndarray, r_scale: float, friction=None) -> dict[str, float] | None:
        """The KKT residuals of (u, λ) with the mortar rows of x + u itself (collective).

        The last QP's rows (D, M, n of the iterate before) give u's gaps and forces only to
        first order in the increment; here the search and the integrals are redone at u: the
        weighted gaps g̃(u), and the forces B(u)ᵀλ (each row's physical force kept) in the
        equilibrium r(u) − B(u)ᵀλ. None when the rows of u are not those of the QP (another
        set of coupled slave nodes): not converged.

        Args:
            problem: The problem of the step.
            u: The iterate.
            lam: The multipliers of the last QP (its rows).
            c_now: The last QP's rows' c at u (:meth:`.CurrentRows.c_at`).
            r: r(u) on this rank.
            r_scale: The equilibrium's reference.
            friction: The last QP's friction solve (its bounds), or None: the friction
                conditions with the slips of the rows of u (drivers/mortar_friction.py).
        """
        from .kkt_stop import kkt_residuals

        comm, rows = self.comm, self.solver.qp.rows
        own = rows.own
        new, _, _ = self.relayout(problem, rows, own.rhs, u)
        mortar = self._mortar(own)  # with friction its tangential rows too: the same c and λ
        same = new.own.size == own.size and np.array_equal(new.own.node, own.node) and \
            np.array_equal(new.own.spec, own.spec) and np.array_equal(new.own.kind, own.kind)
        if not comm.allreduce(bool(same), op=MPI.LAND):
            return None
        B = self.solver.qp.system.B
        w = B.createVecRight()
        B.multTranspose(lam, w)
        lam_phys = lam.array_r * own.scale  # the rows' nodal forces, kept
        old_e = mortar[own.e_row]
        new_e = mortar[new.own.e_row]
        lam_new = lam_phys / new.own.scale
        add = PETSc.InsertMode.ADD_VALUES  # the forces of the rows of u replace the QP's
        w.setValues(rows.cols[old_e].astype(PETSc.IntType),
                    -own.e_coef[old_e] * lam.array_r[own.e_row[old_e]], addv=add)
        w.setValues(new.cols[new_e].astype(PETSc.IntType),
                    new.own.e_coef[new_e] * lam_new[new.own.e_row[new_e]], addv=add)
        w.assemble()
        Bu = B.createVecLeft()
        B.mult(u, Bu)
        c = B.createVecLeft()
        c.array[:] = c_now
        # B u − c is each mortar row's −g̃(u), in the units of the QP's row (its scale)
        c.array[mortar] = Bu.array_r[mortar] + new.own.rhs[mortar] / new.own.scale[mortar] * \
            own.scale[mortar]
        kkt, _ = kkt_residuals(_AtIterate(B, c, w, r, r_scale, comm), own.scale, own.kind,
                               own.inequality, u, lam, Bu=Bu, friction=friction)
        for v in (w, Bu, c):
            v.destroy()
        return kkt

    def quiet(self) -> None:
        """No mortar check on the increments' QP solves.

        Their u is an increment on the reference surfaces; :meth:`report` checks the total
        displacement instead.
        """
        self.solver.qp.mortar = []

    def report(self, sol) -> None:
        """The mortar summaries and checks of ``sol`` (the total displacement; collective).

        What a linear solve reports (``report.extra["mortar"]``, warnings on penetrating
        nodes and active rim rows), with the search of the last iterate; a converged
        solution's ``report.kkt`` are those of :meth:`kkt_at` (the rows of u itself).
        """
        from ..results.mortar_report import mortar_warnings

        comm, c = self.comm, sol.contact
        nodal = sol.nodal_values_on_root()
        found = None
        with collective(comm, "constraints"):
            if comm.rank == 0:
                infos = [replace(i, rim_nodes=self._points[i.rim_nodes]) for i in self.infos]
                found = mortar_warnings(sol.problem.mesh, infos, nodal, c.spec, c.node, c.force)
        warn, sol.report.extra["mortar"] = comm.bcast(found, root=0)
        sol.report.warnings.extend(warn)
        history = sol.report.extra.get("newton")
        if sol.report.converged and history:  # the KKT residuals with the rows of u itself
            sol.report.kkt = dict(history[-1]["kkt"])

    def warm_start(self, old: RankRows, lam: PETSc.Vec, new: RankRows) -> np.ndarray:
        """The last multipliers in the new layout (collective).

        A kept row takes its own, a mortar row that of its slave node's row before (0 for a
        node that had none).
        """
        comm = self.comm
        own_o, own_n = old.own, new.own
        mortar_o, mortar_n = self._mortar(own_o), self._mortar(own_n)
        out = np.zeros(own_n.size)
        out[~mortar_n] = lam.array_r[~mortar_o]  # kept rows: same rank, same order
        # a slave node's normal and tangential rows apart: the key of a row is its
        # (condition, slave node, place among the node's rows: the normal one first)
        parts = comm.allgather((own_o.spec[mortar_o], _row_key(own_o, mortar_o),
                                lam.array_r[mortar_o]))
        spec = np.concatenate([p[0] for p in parts]).astype(np.int64)
        node = np.concatenate([p[1] for p in parts]).astype(np.int64)
        val = np.concatenate([p[2] for p in parts])
        sel = np.flatnonzero(mortar_n)
        node_n = _row_key(own_n, mortar_n)
        span = max(int(node.max(initial=0)), int(node_n.max(initial=0))) + 1
        key = spec * span + node
        want = own_n.spec[sel].astype(np.int64) * span + node_n
        order = np.argsort(key)
        pos = np.searchsorted(key[order], want)
        ok = (pos < key.size) & (key[order][np.minimum(pos, max(key.size - 1, 0))] == want) \
            if key.size else np.zeros(sel.size, dtype=bool)
        out[sel[ok]] = val[order][pos[ok]]
        return out


__all__ = ["DeformedMortar", "check_mortar"]


def _row_key(own: Rows, mask: np.ndarray) -> np.ndarray:
    """Per row of ``mask``: 3 × its node + its place among the node's rows.

    The place: 0 the normal row, 1 and 2 the tangents (a node's rows are consecutive, the
    normal one first).
    """
    idx = np.arange(own.size)
    last = np.maximum.accumulate(np.where(own.inequality, idx, -1))
    place = np.where(own.kind == Kind.TANGENT, idx - np.maximum(last, 0), 0)
    return 3 * own.node[mask].astype(np.int64) + place[mask]


class _AtIterate:
    """The system kkt_residuals reads at an iterate u, with the mortar rows of x + u.

    The last QP's B; ``c`` giving the mortar rows' weighted gaps of x + u; the equilibrium
    r(u) − B(u)ᵀλ with the mortar rows' forces of the D, M, n of x + u (``Bt_lam``).
    """

    def __init__(self, B: PETSc.Mat, c: PETSc.Vec, Bt_lam: PETSc.Vec, r: np.ndarray,
                 r_scale: float, comm: MPI.Comm) -> None:
        self.B, self.c, self.comm = B, c, comm
        self._w, self._r, self._scale = Bt_lam, r, r_scale

    def residuals(self, u: PETSc.Vec, lam: PETSc.Vec) -> dict[str, float]:
        """The equilibrium, relative to max(‖r at the step's start‖, ‖B(u)ᵀλ‖)."""
        d = float(np.sum((self._r - self._w.array_r) ** 2))
        res = np.sqrt(self.comm.allreduce(d, op=MPI.SUM))
        return {"equilibrium": res / max(self._scale, self._w.norm(), 1e-300)}
