"""What the FEM side hands to the FETI layer: the assembled subdomains of a rank and their dof map.

The FETI layer (:mod:`dolfinx_feti.feti`) is algebra on these arrays; this module is the only
place that builds meshes and assembles.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

from ..errors import collective
from ..problem.contact_problem import ContactProblem
from ..setup.share import RankShare
from ..timing import Timer
from .rigid import rigid_modes
from .subdomain import Subdomain


@dataclass
class SubdomainData:
    """The assembled subdomains of one rank, in the canonical dof order.

    The global primal vector holds the subdomains one after another; subdomain ``s`` owns the
    global entries ``sub_offset[s]:sub_offset[s+1]``, node-major (``bs`` components per node).

    Attributes:
        comm: The communicator.
        bs: Components per node.
        gdim: Geometric dimension.
        local_subs: The subdomains of this rank (contiguous, increasing).
        sub_offset: Global primal offset of every subdomain (length ``num_subdomains + 1``).
        K: Block-diagonal stiffness matrix of the local subdomains (CSR).
        f: Local load vector.
        kernels: Per local subdomain, an orthonormal basis of ker K_s (rigid body modes).
        labels: Per local subdomain, a name for messages.
        bodies: Per local subdomain, the name of its body.
        dof_x: Coordinates of the node of every local dof (n_local × gdim).
        dof_comp: Component of every local dof.
        dof_node: Global dof point of every local dof.
        dof_sub: Subdomain of every local dof.
        assemblers: The meshes and spaces the blocks were assembled on (one
            :class:`~dolfinx_feti.fem.Subdomain` per run of subdomains, in block order), kept
            for :func:`assemble_loads`; None when not kept.
    """

    comm: MPI.Comm
    bs: int
    gdim: int
    local_subs: np.ndarray
    sub_offset: np.ndarray
    K: sp.csr_matrix
    f: np.ndarray
    kernels: list[np.ndarray]
    labels: list[str]
    bodies: list[str]
    dof_x: np.ndarray
    dof_comp: np.ndarray
    dof_node: np.ndarray
    dof_sub: np.ndarray
    assemblers: list | None = field(default=None, repr=False)

    @property
    def primal_start(self) -> int:
        """Global index of the first local primal entry."""
        return int(self.sub_offset[self.local_subs[0]]) if self.local_subs.size else 0

    @property
    def primal_size(self) -> tuple[int, int]:
        """(local, global) primal sizes."""
        return self.K.shape[0], int(self.sub_offset[-1])

    @property
    def offsets(self) -> np.ndarray:
        """Local offsets of the blocks (length ``len(local_subs) + 1``)."""
        return self.sub_offset[np.r_[self.local_subs, self.local_subs[-1] + 1]] - \
            self.primal_start if self.local_subs.size else np.zeros(1, dtype=np.int64)


def _cells_by_subdomain(cell_sub: np.ndarray, subs: np.ndarray) -> dict[int, np.ndarray]:
    """The cells of each given subdomain (one sort, not one scan per subdomain)."""
    order = np.argsort(cell_sub, kind="stable")
    start = np.searchsorted(cell_sub[order], subs)
    stop = np.searchsorted(cell_sub[order], subs, side="right")
    return {int(s): order[a:b] for s, a, b in zip(subs, start, stop, strict=True)}


#: About how many cells each DOLFINx mesh of a rank's subdomains holds. DOLFINx 0.5 builds a
#: mesh of 10⁵ cells in markedly less time per cell than one of 10⁶ (its sorts of the cells'
#: facets and vertices then stay in the cache), and each mesh costs one form and one assembly.
CELLS_PER_MESH = 1 << 17


def _runs_of_equal_bodies(mesh, subs, cells_of, limit: int = CELLS_PER_MESH
                          ) -> list[list[int]]:
    """Consecutive subdomains with the same set of bodies, each run to be assembled as one mesh.

    Grouping by bodies keeps ``sub.body`` meaningful in the user's forms callback. A run
    ends before a subdomain that would take it beyond ``limit`` cells (a subdomain larger
    than that is a run of its own).
    """
    runs, key, size = [], None, 0
    for s in subs:
        cells = cells_of[int(s)]
        k = tuple(np.unique(mesh.cell_body[cells]))
        if k != key or size + cells.size > limit:
            runs.append([])
            key, size = k, 0
        runs[-1].append(int(s))
        size += cells.size
    return runs


def block_diagonal(parts: list[sp.csr_matrix]) -> sp.csr_matrix:
    """``sp.block_diag(parts, format="csr")`` of CSR blocks, by concatenating their arrays."""
    if not parts:
        return sp.csr_matrix((0, 0))
    nnz = np.cumsum([0] + [p.nnz for p in parts])
    cols = np.cumsum([0] + [p.shape[1] for p in parts])
    indptr = np.concatenate([[0]] + [p.indptr[1:] + o for p, o in zip(parts, nnz, strict=False)])
    indices = np.concatenate([p.indices + c for p, c in zip(parts, cols, strict=False)])
    return sp.csr_matrix((np.concatenate([p.data for p in parts]), indices, indptr),
                         shape=(sum(p.shape[0] for p in parts), int(cols[-1])))


def _subdomains(share: RankShare):
    """The meshes of this rank's runs of subdomains (:func:`_runs_of_equal_bodies`), lazily."""
    mesh, dec = share.mesh, share.dec
    cells_of = _cells_by_subdomain(dec.cell_sub, dec.subs)
    for group in _runs_of_equal_bodies(mesh, dec.subs, cells_of, CELLS_PER_MESH):
        yield Subdomain(group, mesh, [cells_of[s] for s in group],
                        [dec.nodes(s) for s in group],
                        [share.facets.get(s, {}) for s in group], share.points,
                        check_group=share.check_group)


def assemble_subdomains(problem: ContactProblem, share: RankShare, comm: MPI.Comm,
                        timer: Timer, assemblers: list | None = None, *,
                        keep: bool = True) -> SubdomainData:
    """Mesh and assemble the subdomains of this rank (collective on ``comm``).

    Consecutive subdomains of a rank with the same bodies are meshed together as a disjoint
    union, up to about :data:`CELLS_PER_MESH` cells, so one assembly gives their block of the
    block-diagonal K (see :class:`~dolfinx_feti.fem.Subdomain`); the grouping changes no bit
    of K or f. Only the rank's share (:mod:`dolfinx_feti.setup.share`) is read. ``assemblers``, the
    :attr:`SubdomainData.assemblers` of an earlier call on the same share, skips the meshing
    (new forms on the same subdomains); ``keep=False`` frees each mesh after its assembly
    (less memory during the factorization, a new meshing for :func:`assemble_loads`).
    """
    mesh, dec, bs = share.mesh, share.dec, problem.value_size
    local_subs = dec.subs
    sub_offset = np.concatenate([[0], np.cumsum(bs * dec.sub_size)]).astype(np.int64)
    with timer.phase("assembly"), collective(comm, "assembly"):
        K_parts, f_parts, kept = [], [], []
        for sub in _subdomains(share) if assemblers is None else assemblers:
            K, f = sub.assemble(problem.forms, bs)
            if keep:
                kept.append(sub)
            K_parts.append(K)
            f_parts.append(f)
        K = block_diagonal(K_parts)
        nodes = [dec.nodes(s) for s in local_subs]
        # The rigid motions are linear: their nodal interpolation at the dof points is exact.
        x = share.points.x
        kernels = [rigid_modes(x[n], bs) for n in nodes]
        local_node = np.repeat(np.concatenate(nodes), bs) if nodes else np.zeros(0, np.int64)
        dof_sub = np.repeat(local_subs, bs * np.array([n.size for n in nodes], dtype=np.int64))
    labels = [f"subdomain {s} of body {mesh.body_names[dec.sub_body[s]]!r}" for s in local_subs]
    return SubdomainData(
        comm=comm, bs=bs, gdim=mesh.gdim, local_subs=local_subs, sub_offset=sub_offset, K=K,
        f=np.concatenate(f_parts) if f_parts else np.zeros(0), kernels=kernels, labels=labels,
        bodies=[mesh.body_names[dec.sub_body[s]] for s in local_subs],
        dof_x=x[local_node], dof_comp=np.tile(np.arange(bs), local_node.size // bs),
        dof_node=np.repeat(share.pair_points, bs), dof_sub=dof_sub,
        assemblers=kept if keep else None)


def assemble_loads(forms, data: SubdomainData, share: RankShare, timer: Timer) -> np.ndarray:
    """The load vector of ``forms`` on the subdomains of ``data`` (collective).

    Only the linear forms are assembled, on the meshes and spaces of the first assembly when
    it kept them (else meshed again): a new load case (tractions, body forces) of the same
    stiffness costs one vector assembly.
    """
    with timer.phase("assembly"), collective(data.comm, "assembly"):
        subs = _subdomains(share) if data.assemblers is None else data.assemblers
        parts = [sub.assemble_load(forms, data.bs) for sub in subs]
    return np.concatenate(parts) if parts else np.zeros(0)
