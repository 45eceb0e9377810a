"""What the distributed set-up hands a rank for its rows (constraints.distributed_rows), cut
from a serial problem and decomposition: for the tests and the benchmark."""

from __future__ import annotations

import numpy as np

from dolfinx_feti.constraints.distributed_rows import ConditionPoints
from dolfinx_feti.mesh.topology import locate_facets


class RankInputs:
    """The inputs of rank ``rank`` when subdomain s is owned by ``sub_rank[s]``.

    Attributes:
        cells: The rank's cells (those of its subdomains).
        points: The sorted global dof points of those cells.
        ptr, subs: Each point's subdomains (all of them, sorted; CSR).
        conditions: Per Dirichlet condition, the points on the group's facets that are facets
            of the rank's cells, with their coordinates.
    """

    def __init__(self, problem, dec, sub_rank: np.ndarray, rank: int):
        mesh, pts = problem.mesh, problem.dof_points
        self.cells = np.flatnonzero(sub_rank[dec.cell_sub] == rank)
        self.points = np.unique(pts.cell_points[self.cells])
        node_ptr, node_subs = dec.node_subdomains()
        count = np.diff(node_ptr)[self.points]
        self.ptr = np.r_[0, np.cumsum(count)].astype(np.int64)
        start = np.repeat(node_ptr[self.points] - self.ptr[:-1], count)
        self.subs = node_subs[start + np.arange(self.ptr[-1])]
        mine = np.zeros(mesh.cells.shape[0], dtype=bool)
        mine[self.cells] = True
        self.conditions = []
        for bc in problem.dirichlet:
            facets = mesh.facets(bc.group)
            cell, _ = locate_facets(mesh.cells, facets, mesh.cell_type)
            on = pts.facet_points(mesh, facets)[mine[cell]].ravel()
            self.conditions.append(ConditionPoints(bc, on, pts.x[on]))
