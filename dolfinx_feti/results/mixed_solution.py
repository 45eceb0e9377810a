"""The solution of a problem on bodies of different cell types: one field per mesh.

:func:`~dolfinx_feti.drivers.mixed_solve.solve_mixed` solves one FETI system of all meshes;
this holds its result split back: the displacement on each mesh (values at its dof points,
a DOLFINx Function per mesh, XDMF per mesh) and the forces of the rows between meshes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI


@dataclass
class Coupled:
    """The rows of one condition between two meshes.

    Attributes:
        index: The condition's index in the problem's contact list (or ties).
        tie: Whether it is a tie (equality rows per component) or contact (one row per node).
        slave_part: The mesh of its slave surface.
        slave_nodes: The coupled slave nodes (points of that mesh).
        D: Their areas ∫ N_j over the slave surface.
        scale: Per row, the factor s_j of the row (the nodal force is s_j λ).
        row_node: Per row, its slave node (index into ``slave_nodes``).
        row_comp: Per row, the component of a tie row (−1 for contact).
        normal: Per slave node, the unit normal of its contact row, pointing from the master
            toward the slave (zeros for a tie).
        uncoupled: Slave nodes without a row.
        pairs: Facet pairs with an overlap.
        search_distance: The search distance used.
    """

    index: int
    tie: bool
    slave_part: int
    slave_nodes: np.ndarray
    D: np.ndarray
    scale: np.ndarray
    row_node: np.ndarray
    row_comp: np.ndarray
    normal: np.ndarray
    uncoupled: int
    pairs: int
    search_distance: float

    @property
    def rows(self) -> int:
        """Number of rows."""
        return self.scale.size


def xdmf_paths(path: str | Path, cell_types) -> list[Path]:
    """The XDMF file of each mesh: ``<stem>_<cell type>.xdmf`` beside ``path``."""
    path = Path(path)
    return [path.with_name(f"{path.stem}_{t}{path.suffix or '.xdmf'}") for t in cell_types]


class MixedSolution:
    """What solving a problem on bodies of different cell types returns.

    Attributes:
        problem: The problem.
        report: The solver's report (convergence, iterations, sizes, timings).
        coupled: Per condition between meshes, its rows (:class:`Coupled`).
    """

    def __init__(self, problem, shares, datas, layout, u: np.ndarray, coupled: list[Coupled],
                 lam: np.ndarray, report, comm: MPI.Comm) -> None:
        """Split the joined solution back per mesh (collective)."""
        self.problem, self.report, self.coupled, self.comm = problem, report, coupled, comm
        self._shares, self._lam = shares, lam
        bs = problem.value_size
        within = layout.within[comm.rank]
        self._pairs = []  # per mesh: (global point of each local pair, its values)
        for k, (share, data) in enumerate(zip(shares, datas, strict=True)):
            local = u[within[k]:within[k] + data.K.shape[0]].reshape(-1, bs)
            self._pairs.append((share.pair_points, local))
        self._nodal: dict[int, np.ndarray] = {}
        self._functions: dict[int, object] = {}

    @property
    def meshes(self) -> tuple:
        """The meshes, one per cell type (``problem.mesh.parts``)."""
        return self.problem.mesh.parts

    def nodal_values(self, k: int) -> np.ndarray:
        """The displacement at every dof point of mesh k, (points, value size), every rank.

        Where subdomains share a point their values agree to the solver tolerance; the mean
        is returned.
        """
        if k not in self._nodal:
            n, bs = self._shares[k].num_points, self.problem.value_size
            points, values = self._pairs[k]
            acc = np.zeros((n, bs))
            count = np.zeros(n)
            np.add.at(acc, points, values)
            np.add.at(count, points, 1.0)
            acc, count = self.comm.allreduce(acc), self.comm.allreduce(count)
            self._nodal[k] = acc / np.maximum(count, 1.0)[:, None]
        return self._nodal[k]

    def displacement(self, body: str) -> tuple[np.ndarray, np.ndarray]:
        """(node coordinates, displacement) of the mesh that holds ``body``, every rank."""
        k = self.problem.mesh.part_of_body(body)
        return self.meshes[k].x, self.nodal_values(k)

    def function(self, k: int):
        """The displacement on mesh k as a DOLFINx Function (a mesh built from the part)."""
        if k not in self._functions:
            from .output import distributed_function

            points, values = self._pairs[k]
            name = "displacement" if self.problem.value_size > 1 else "u"
            self._functions[k] = distributed_function(self.meshes[k], points, values,
                                                      self.comm, name)
        return self._functions[k]

    @property
    def u(self) -> list:
        """The displacement as one DOLFINx Function per mesh."""
        return [self.function(k) for k in range(len(self.meshes))]

    def write_xdmf(self, path: str | Path) -> list[Path]:
        """Write one XDMF file per mesh: ``<stem>_<cell type>.xdmf`` beside ``path``.

        Returns:
            The files written.
        """
        from .output import write_xdmf

        out = xdmf_paths(path, [m.cell_type for m in self.meshes])
        for k, p in enumerate(out):
            u = self.function(k)
            write_xdmf(p, u, [u])
        return out

    def results(self) -> dict:
        """A few numbers that characterize the solution (the command's report, collective).

        ``max_abs_u`` over all meshes; per mesh its cell type, bodies, nodes and largest
        displacement; per condition between meshes its rows and total force (contact: the
        sum of the normal forces; tie: the force vector).
        """
        meshes = []
        for k, mesh in enumerate(self.meshes):
            u = self.nodal_values(k)
            meshes.append({"cell_type": mesh.cell_type, "bodies": list(mesh.body_names),
                           "nodes": int(mesh.num_nodes),
                           "max_abs_u": float(np.abs(u).max()) if u.size else 0.0})
        between = []
        for i, c in enumerate(self.coupled):
            f = self.forces(i)["force"]
            between.append({"condition": c.index, "tie": c.tie, "rows": int(c.rows),
                            "total_force": f.sum(axis=0).tolist()})
        return {"max_abs_u": max(m["max_abs_u"] for m in meshes), "meshes": meshes,
                "between_meshes": between}

    def save_nodal_values(self, path: str | Path) -> None:
        """Write every mesh's nodes and solution to ``.npz`` (call on one rank).

        :meth:`nodal_values` is collective: call it for every mesh on every rank first. The
        arrays of mesh k are named with its cell type t: ``x_t``, ``u_t``, ``cells_t``,
        ``cell_body_t`` (indices into ``body_names_t``) and ``body_names_t``.
        """
        from .postprocess import atomic_file

        arrays = {}
        for k, mesh in enumerate(self.meshes):
            t = mesh.cell_type
            arrays.update({f"x_{t}": mesh.x, f"u_{t}": self.nodal_values(k),
                           f"cells_{t}": mesh.cells, f"cell_body_{t}": mesh.cell_body,
                           f"body_names_{t}": np.array(mesh.body_names)})
        with atomic_file(path) as tmp, open(tmp, "wb") as f:
            np.savez(f, **arrays)

    def forces(self, i: int) -> dict[str, np.ndarray]:
        """The nodal forces of the rows of the i-th condition between meshes.

        Returns:
            ``node`` (slave points of its mesh), ``x`` their coordinates, ``force`` (contact:
            the normal force, ≥ 0, pushing the slave along ``normal``; tie: the force vector
            per node), ``pressure`` (force per unit area of the slave surface, ``force / D``)
            and ``normal``.
        """
        c = self.coupled[i]
        start = int(sum(x.rows for x in self.coupled[:i]))
        f = c.scale * self._lam[start:start + c.rows]
        mesh = self.meshes[c.slave_part]
        if c.tie:
            force = np.zeros((c.slave_nodes.size, self.problem.value_size))
            force[c.row_node, c.row_comp] = f
            pressure = force / c.D[:, None]
        else:
            force = np.zeros(c.slave_nodes.size)
            force[c.row_node] = f
            pressure = force / c.D
        return {"node": c.slave_nodes, "x": mesh.x[c.slave_nodes], "force": force,
                "pressure": pressure, "normal": c.normal}


__all__ = ["Coupled", "MixedSolution", "xdmf_paths"]
