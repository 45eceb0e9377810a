"""The solution of a contact problem: displacement, multipliers, contact pressure, report."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..constraints.contact import surface
from ..constraints.friction import FRICTIONLESS, SLIP, STICK
from ..constraints.mortar_rows import self_contact_areas
from ..constraints.rows import Kind
from ..drivers.kkt_stop import kkt_residuals
from ..feti.system import BlockSystem
from ..problem.conditions import RigidObstacle
from ..problem.contact_problem import ContactProblem
from ..setup.share import RankShare
from .report import Report


@dataclass
class ContactData:
    """Contact results per contact node (one entry per inequality row), on every rank.

    Attributes:
        spec: Index of the contact condition in ``problem.contact``.
        node: Slave node (global index); ``x`` its coordinates.
        partner: Master node of a node-to-node pair, -1 for an obstacle.
        normal: Contact normal (master's / obstacle's outward normal).
        force: Nodal contact force (the physical multiplier, >= 0).
        pressure: Force divided by the node's lumped area on its surface (for self-contact:
            on the zones of its surface that the search paired).
        gap: Gap after deformation (>= 0 up to the tolerance; < 0 is penetration).

    With friction on some contact condition (None otherwise; zeros, NaN and ``FRICTIONLESS``
    at the nodes of frictionless conditions):

    Attributes:
        tangential_force: (n, gdim) friction force on the slave node, −Σ_k λ_T,k t_k.
        tangential_traction: The tangential force divided by the node's lumped area.
        slip: (n, gdim) relative tangential displacement Σ_k ((u_slave − u_master)·t_k) t_k
            (u_master = 0 for an obstacle). Where a node slips, the slip is opposite to the
            tangential force; where it sticks, it is zero.
        slip_bound: The nodal slip bound g (a force: Tresca bound × area, or 𝓕 × normal force
            of the previous Coulomb step); |tangential_force| <= slip_bound.
        state: ``STICK`` (1: |λ_T| < g, zero slip), ``SLIP`` (2: |λ_T| = g) or
            ``FRICTIONLESS`` (0).
    """

    FRICTIONLESS: ClassVar[int] = FRICTIONLESS
    STICK: ClassVar[int] = STICK
    SLIP: ClassVar[int] = SLIP

    spec: np.ndarray
    node: np.ndarray
    x: np.ndarray
    partner: np.ndarray
    normal: np.ndarray
    force: np.ndarray
    pressure: np.ndarray
    gap: np.ndarray
    tangential_force: np.ndarray | None = None
    tangential_traction: np.ndarray | None = None
    slip: np.ndarray | None = None
    slip_bound: np.ndarray | None = None
    state: np.ndarray | None = None

    def of(self, spec: int) -> ContactData:
        """The entries of one contact condition."""
        m = self.spec == spec
        return ContactData(**{k: None if v is None else v[m] for k, v in self.__dict__.items()})


class Solution:
    """What :func:`dolfinx_feti.solve` returns.

    Attributes:
        report: The :class:`~dolfinx_feti.results.report.Report`.
        contact: :class:`ContactData` for all contact nodes.
        lam: The multipliers λ (a distributed PETSc Vec, rows in the order of ``rows``).
        u_vec: The primal solution, subdomain by subdomain (a distributed PETSc Vec).
        feti: The Total FETI system of the problem (all rows, whatever the method).
        dual: The dual operators the method solved with (``F``, ``d``, ``Gt_local``, ``e``),
            when the solution comes from :func:`dolfinx_feti.solve`.
        alpha: Rigid-body amplitudes (the same on every rank).
    """

    def __init__(self, problem: ContactProblem, feti: BlockSystem, share: RankShare,
                 u: PETSc.Vec, lam: PETSc.Vec, alpha: np.ndarray, report: Report,
                 comm: MPI.Comm, friction=None, surface=None) -> None:
        """Collect results (collective).

        ``feti`` is the Total FETI system of the problem (all rows, whatever the method),
        ``share`` what this rank holds of the problem (:mod:`.share`), ``friction`` the
        solve's FrictionSolve or None, ``surface`` the cells along the contact surfaces of a
        distributed mesh (:class:`.share_distributed.Surface`, rank 0) or None.
        """
        self.problem, self.feti, self.share = problem, feti, share
        self.surface = surface
        self.dec, self.rows = share.dec, share.rows
        self.friction = friction
        self.dual = None
        self.u_vec, self.lam, self.alpha, self.report, self.comm = u, lam, alpha, report, comm
        self._Bu = feti.B.createVecLeft()
        feti.B.mult(u, self._Bu)
        self._nodal = None
        self._cell_sub = None
        self._function = None
        self._directory = None
        self.contact = self._contact_data()

    # --- residuals -------------------------------------------------------------------------
    def check_kkt(self, ineq: np.ndarray) -> None:
        """Fill ``report.kkt`` and ``report.max_penetration`` from u and λ (collective).

        The residuals of :func:`.kkt_stop.kkt_residuals` (the ones the stopping test bounds).
        """
        own = self.rows.own
        self.report.kkt, self.report.max_penetration = kkt_residuals(
            self.feti, own.scale, own.kind, ineq, self.u_vec, self.lam, self._Bu, self.friction)

    # --- contact ---------------------------------------------------------------------------
    def _contact_data(self) -> ContactData:
        own, feti, mesh = self.rows.own, self.feti, self.problem.mesh
        ineq = own.inequality
        lam = self.comm.allgather(self.lam.array_r[ineq] * own.scale[ineq])
        gap = self.comm.allgather(((feti.c.array_r - self._Bu.array_r) / own.scale)[ineq])
        lam, gap = np.concatenate(lam), np.concatenate(gap)
        rows = self.rows.contact  # every inequality row, in the global order
        sel = rows.inequality
        spec, node = rows.spec[sel], rows.node[sel]
        area = xs = None
        if self.comm.rank == 0:  # from the whole mesh, or the cells along its surfaces
            problem, at = self.problem, node
            if self.surface is not None:  # a distributed mesh: rank 0 has the surfaces
                problem, at = self.surface.problem, self.surface.local(node)
            area = np.ones(node.size)
            for i, c in enumerate(problem.contact):
                if c.self_contact:  # its zones
                    nodes, a = self_contact_areas(problem.mesh, c, problem.dof_points)
                else:
                    nodes, _, a = surface(problem.mesh, c.group, problem.dof_points)
                m = spec == i
                area[m] = a[np.searchsorted(nodes, at[m])]
            xs = problem.dof_points.x[at]
        area, xs = self.comm.bcast((area, xs), root=0)
        extra = {}
        if self.friction is not None:
            scale = own.scale
            extra = self.friction.contact_fields(self.lam.array_r * scale,
                                                 (self._Bu.array_r - feti.c.array_r) / scale,
                                                 mesh.gdim)
            extra["tangential_traction"] = extra["tangential_force"] / area[:, None]
        return ContactData(spec=spec, node=node, x=xs,
                           partner=rows.partner[sel],
                           normal=rows.normal[sel], force=lam, pressure=lam / area, gap=gap,
                           **extra)

    def smoothed_pressure(self) -> np.ndarray:
        """A smoothed contact pressure at the contact nodes (aligned with ``contact``).

        The force over the area of each node's patch (the points sharing a facet with it):
        Σ f_k / Σ ∫ N_k (:mod:`dolfinx_feti.results.contact_fields`); ``contact.pressure`` is the
        node's own force over its own lumped area. Collective; the same array on every rank.
        """
        from ..mesh.topology import facets_in_cell_order
        from .contact_fields import smoothed_pressure
        c = self.contact
        out = None
        if self.comm.rank == 0:
            problem, at = self.problem, c.node
            if self.surface is not None:  # a distributed mesh: rank 0 has the surfaces
                problem, at = self.surface.problem, self.surface.local(c.node)
            out = np.zeros(c.node.size)
            points, mesh = problem.dof_points, problem.mesh
            for i, cond in enumerate(problem.contact):
                m = c.spec == i
                if not m.any():
                    continue
                facets = facets_in_cell_order(mesh.cells, mesh.facets(cond.group),
                                              mesh.cell_type)  # tensor order for quads
                out[m] = smoothed_pressure(points.x, points.facet_points(mesh, facets),
                                           mesh.cell_type, problem.degree,
                                           points.num_points, at[m], c.force[m])
        return self.comm.bcast(out, root=0)

    @property
    def total_contact_force(self) -> np.ndarray:
        """Sum of the nodal contact force vectors Σ λ n (a scalar sum for scalar problems).

        With friction the tangential forces are included.
        """
        if self.problem.value_size == 1:
            return np.array([self.contact.force.sum()])
        total = (self.contact.force[:, None] * self.contact.normal).sum(axis=0)
        if self.contact.tangential_force is not None:
            total = total + self.contact.tangential_force.sum(axis=0)
        return total

    # --- displacement ----------------------------------------------------------------------
    def nodal_values(self) -> np.ndarray:
        """The solution at every mesh node, shape (N, value_size), on every rank.

        Where subdomains share a node their values agree to the solver tolerance; the mean is
        returned.
        """
        if self._nodal is None:
            self._nodal = self.comm.bcast(self.nodal_values_on_root(), root=0)
        return self._nodal

    def nodal_values_on_root(self) -> np.ndarray | None:
        """:meth:`nodal_values` on rank 0 only (None elsewhere; collective).

        Each rank sends its subdomains' values: no other rank holds an array of the whole
        mesh.
        """
        if self._nodal is not None:
            return self._nodal if self.comm.rank == 0 else None
        share, bs = self.share, self.problem.value_size
        parts = self.comm.gather((share.pair_points, self.u_vec.array_r.reshape(-1, bs)), root=0)
        if self.comm.rank != 0:
            return None
        acc = np.zeros((share.num_points, bs))
        cnt = np.zeros(share.num_points)
        for n, v in parts:
            np.add.at(acc, n, v)
            np.add.at(cnt, n, 1.0)
        return acc / np.maximum(cnt, 1)[:, None]

    def surface_values(self) -> np.ndarray | None:
        """The solution at the points of :attr:`surface` on rank 0 (None elsewhere; collective).

        For the checks after a solve on a distributed mesh: the values come from the ranks
        that hold those points, through a directory.
        """
        from .output import node_values
        wanted = self.surface.point_ids if self.surface is not None else \
            np.zeros(0, dtype=np.int64)
        share, bs = self.share, self.problem.value_size
        out = node_values(share.pair_points, self.u_vec.array_r.reshape(-1, bs), wanted,
                          share.num_points, self.comm)
        return out if self.comm.rank == 0 else None

    def cell_subdomains(self) -> np.ndarray:
        """The subdomain of every cell of the mesh, on every rank (collective, then cached)."""
        if self._cell_sub is None:
            share = self.share
            cells = np.concatenate(self.comm.allgather(share.cell_ids))
            subs = np.concatenate(self.comm.allgather(share.dec.cell_sub))
            self._cell_sub = np.empty(share.num_cells, dtype=subs.dtype)
            self._cell_sub[cells] = subs
        return self._cell_sub

    @property
    def energy(self) -> float:
        """The energy ½ uᵀ K u − fᵀ u of the (decomposed) solution."""
        return self.feti.energy(self.u_vec)

    @property
    def u(self):
        """The solution as a DOLFINx Function on the whole mesh.

        A Lagrange Function of the problem's degree: on the user's own mesh when the problem
        came from :func:`~dolfinx_feti.from_dolfinx` (``u.function_space.mesh is mesh``), else
        on a mesh built from the MeshData and distributed over ``comm``.
        """
        if self._function is None:
            self._function = self._local_pairs_function(
                self.u_vec.array_r.reshape(-1, self.problem.value_size),
                "displacement" if self.problem.value_size > 1 else "u")
        return self._function

    def _local_pairs_function(self, values: np.ndarray, name: str, degree: int | None = None):
        """A Function from this rank's subdomain values (in the pairs' order), exchanged."""
        from .output import distributed_function
        msh = None if self._function is None else self._function.function_space.mesh
        return distributed_function(self.problem.mesh, self.share.pair_points, values, self.comm,
                                    name, self._points(), degree, msh=msh)

    def _points(self):
        """The dof points of the output: the problem's, or on a distributed mesh a directory."""
        if self.problem.mesh.part is None:
            return self.problem.dof_points
        if self._directory is None:
            from ..mesh.point_directory import PointDirectory
            self._directory = PointDirectory(self.problem.mesh.cell_type, self.problem.degree,
                                             self.problem.mesh.num_nodes, self.comm, self.share)
        return self._directory

    def pressure_function(self, degree: int | None = None, smoothed: bool = False):
        """The contact pressure as a scalar Lagrange Function on the whole mesh.

        Of the problem's degree unless ``degree`` is given (1: the values at the vertices);
        zero off the contact surfaces. ``smoothed``: the values of :meth:`smoothed_pressure`
        instead of ``contact.pressure`` (collective either way).
        """
        if smoothed:
            return self.contact_function(self.smoothed_pressure(), "contact_pressure_smoothed",
                                         degree)
        return self.contact_function(self.contact.pressure, "contact_pressure", degree)

    def contact_function(self, values: np.ndarray, name: str, degree: int | None = None):
        """A Lagrange Function on the whole mesh of values per contact node; zero elsewhere.

        Args:
            values: Per node of :attr:`contact` (its order), shape (n,) or (n, k).
            name: The Function's name.
            degree: Its degree (default: the problem's; 1: the values at the vertices).
        """
        from .output import distributed_function
        c = self.contact  # gathered on every rank (contact surfaces are small): no exchange
        v = np.asarray(values, dtype=float)
        v = v[:, None] if v.ndim == 1 else v
        return distributed_function(self.problem.mesh, c.node, v, self.comm, name,
                                    self._points(), degree, local=True,
                                    msh=self.u.function_space.mesh)

    def write_xdmf(self, path: str | Path) -> None:
        """Write the solution to XDMF (for ParaView), atomically.

        Fields: the displacement (``u`` for a scalar problem), ``contact_pressure`` (zero off
        contact), ``subdomain`` (DG0) and, for :class:`~dolfinx_feti.Elasticity`,
        ``von_mises`` (DG0; see :mod:`dolfinx_feti.results.postprocess`). XDMF holds fields of the
        mesh's geometry degree: for a degree-2 problem on a straight-sided mesh the
        displacement and the pressure are written by their values at the vertices
        (``solution.u`` keeps the whole field).
        """
        from .output import write_xdmf
        from .postprocess import output_functions
        degree = self.problem.mesh.geometry_degree
        u = self.u if self.problem.degree == degree else self._local_pairs_function(
            self.u_vec.array_r.reshape(-1, self.problem.value_size), self.u.name, degree)
        write_xdmf(path, u, [u, self.pressure_function(degree=degree), *output_functions(self)])

    def multipliers(self, kind: Kind | None = None) -> np.ndarray:
        """Physical multipliers (nodal forces) of all rows, or of one kind, on every rank."""
        own = self.rows.own
        lam = self.lam.array_r * own.scale
        if kind is not None:
            lam = lam[own.kind == kind]
        return np.concatenate(self.comm.allgather(lam))


__all__ = ["ContactData", "RigidObstacle", "Solution"]
