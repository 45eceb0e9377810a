"""A mesh held whole (on every rank, or on rank 0) as the input of the one set-up pipeline.

The set-up (:mod:`.share_distributed`) starts from blocks of cells, one per rank. A mesh every
rank holds (``read_gmsh``'s default) is cut into the same blocks a distributed read would hand
out, each rank cutting its own; a mesh only rank 0 holds (``replicate=False``) has its blocks
handed out by rank 0 (:func:`~.mesh.distributed.block_of`). From there the decomposition, the
dof points, the rows, FETI-DP's corners and the shares are the distributed ones.

What a whole mesh has that blocks of a distributed one do not yet, carried here:

- PT-Scotch partitions the whole mesh on one rank, and a :class:`~.mesh.decompose.ByFunction`
  labeller of a whole mesh sees all its midpoints at once: rank 0 runs them (as the serial
  decomposition did) and the labels travel with the blocks;
- a curved (second-order) mesh: the dof points of edges and faces are the mesh's geometry
  nodes, which only the whole mesh holds (:class:`WholePoints`).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from ..errors import collective
from ..mesh.data import answered_by_root
from ..mesh.decompose import ByFunction, Parts, decompose, midpoints_of
from ..mesh.distributed import block_of
from ..mesh.distributed_decompose import BlockLabels, labels_of
from ..problem.contact_problem import ContactProblem
from ..timing import Timer


@dataclass
class WholePoints:
    """The dof points of a curved mesh held whole: coordinates of global points.

    Attributes:
        mesh: The whole mesh (its arrays on rank 0 at least).
        x: The coordinates of all dof points (rank 0's; every rank's if ``replicated``).
        replicated: Whether every rank holds them.
        comm: The ranks.
    """

    mesh: object
    x: np.ndarray
    replicated: bool
    comm: MPI.Comm

    def of(self, points: np.ndarray) -> np.ndarray:
        """The coordinates of the given global points (collective)."""
        if self.replicated:
            return self.x[points]
        return answered_by_root(self.comm, np.asarray(points, dtype=np.int64),
                                lambda p: self.x[p])


def as_blocks(problem: ContactProblem, comm: MPI.Comm, timer: Timer
              ) -> tuple[ContactProblem, WholePoints | None]:
    """``problem`` on this rank's block of its whole mesh (collective).

    Returns:
        The problem on the block (the same conditions, forms and decomposition; a
        PT-Scotch or ByFunction decomposition as rank 0's labels,
        :class:`~.mesh.distributed_decompose.BlockLabels`), and for a curved mesh its
        :class:`WholePoints` (None otherwise).
    """
    mesh, how = problem.mesh, problem.decomposition
    arrays = midpoints = None
    labelled = isinstance(how, ByFunction) or isinstance(how, Parts) and how.method == "ptscotch"
    if labelled:
        with timer.phase("decomposition"), collective(comm, "decomposition"):
            if comm.rank == 0:  # PT-Scotch may differ between processes: one runs it
                if isinstance(how, ByFunction):
                    midpoints = midpoints_of(mesh.x, mesh.cells)
                    arrays = {"label": labels_of(how, midpoints)}
                else:
                    arrays = {"label": decompose(mesh, how, 1).cell_sub}
        if mesh.root_only is None:  # every rank cuts its own block
            arrays = comm.bcast(arrays, root=0)
    with timer.phase("distribution"):
        block, given = block_of(mesh, comm, arrays, midpoints)
    view = copy.copy(problem)  # no new checks: they ran on the whole mesh
    object.__setattr__(view, "mesh", block)
    if labelled:
        object.__setattr__(view, "decomposition", BlockLabels(given["label"]))
    whole = None
    if mesh.high_order is not None:
        whole = WholePoints(mesh, problem.dof_points.x if mesh.holds_arrays else None,
                            mesh.root_only is None, comm)
    return view, whole


__all__ = ["WholePoints", "as_blocks"]
