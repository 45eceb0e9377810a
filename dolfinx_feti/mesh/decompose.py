"""Decomposition of the bodies into subdomains, and the subdomain ↔ node ↔ primal dof maps.

A decomposition is computed from global arrays on every rank and is therefore the same on
every rank and for every number of ranks; only the assignment of subdomains to ranks depends on
the communicator size.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from scipy.sparse.csgraph import connected_components

from ..errors import InputError, collective
from ..validation import Choice, Flag, Function, Integer, checked, per_body
from .auto_parts import BALANCE, Auto, auto_parts
from .connected_parts import merge_fragments
from .data import MeshData
from .dofpoints import DofPoints
from .topology import cell_volumes, facet_neighbours

#: The largest number of parts of one body that Parts accepts (it is also at most its cells).
MAX_PARTS = 2**31 - 1


@dataclass(frozen=True)
class ByTags:
    """One subdomain per body (per connected piece of a physical volume/surface group)."""


@dataclass(frozen=True)
@checked(n=per_body(Integer(ge=1, le=MAX_PARTS)), method=Choice("rcb", "ptscotch"),
         balance=Choice("cells", "volume"), merge=Flag())
class Parts:
    """Split every body into parts of (nearly) equal size.

    Args:
        n: Parts per body: one number for all bodies or a mapping body name → number.
        method: ``"rcb"``: recursive coordinate bisection of the cell midpoints (compact,
            box-like parts; the default); ``"ptscotch"``: PETSc's graph partitioner (PT-Scotch)
            on the cells' facet adjacency (fewer interface nodes on unstructured meshes),
            computed on rank 0. PT-Scotch's result can differ with the number of ranks, so
            with "ptscotch" only the solution, not the decomposition, is rank-independent.
        balance: What ``"rcb"`` makes equal: ``"cells"`` (the cell counts; the default) or
            ``"volume"`` (the parts' volumes). On a mesh graded toward a contact, equal cell
            counts give many small subdomains (and pieces that fall apart) where the contact
            is; equal volumes give compact subdomains with the fine cells inside them, and far
            fewer F-multiplications (docs/benchmarks.md § 5).
        merge: Whether the pieces a cut leaves apart (a part in pieces that share no facet)
            are merged into their neighbouring parts, so that every body gives about ``n``
            connected subdomains (the default; :mod:`.connected_parts`), or kept as
            subdomains of their own (``False``: one subdomain per piece).
    """

    n: int | Mapping[str, int]
    method: str = "rcb"
    balance: str = "cells"
    merge: bool = True


@dataclass(frozen=True)
@checked(fn=Function("a function fn(midpoints (C, gdim)) -> (C,) integer labels"))
class ByFunction:
    """Subdomains labelled by a function of the cell midpoints (e.g. a regular H×H grid).

    Cells with equal labels form a subdomain; a label whose cells are not connected through
    facets, or that spans two bodies not glued together, gives one subdomain per piece. The
    function is called on rank 0, which holds the mesh during the set-up — or, for a mesh read
    with ``distribute=True``, on every rank with the midpoints of its cells (a label must then
    depend on each midpoint alone).

    Args:
        fn: ``fn(midpoints: (C, gdim) array) -> (C,) integer labels``.
    """

    fn: Callable[[np.ndarray], np.ndarray]


@dataclass
class Decomposition:
    """Subdomains, their owners, and the (subdomain, node) pairs that number the primal dofs.

    A "node" here is a dof point (:mod:`.dofpoints`): a vertex for degree 1; a vertex, edge,
    face or cell interior point for degree 2. The primal unknowns are ordered subdomain by
    subdomain, and inside a subdomain by global node index then component:
    dof(s, node, c) = bs * pair_index(s, node) + c. This order does not depend on DOLFINx's dof
    numbering nor on the number of ranks.

    Attributes:
        cell_sub: Subdomain of each cell.
        sub_body: Body index of each subdomain (of its first cell).
        sub_rank: Rank owning each subdomain (subdomains of a rank are contiguous).
        pair_sub, pair_node: The (subdomain, node) pairs sorted by subdomain then node.
        sub_ptr: Pairs of subdomain s are ``sub_ptr[s]:sub_ptr[s+1]``.
        num_nodes: Number of dof points of the whole mesh.
    """

    cell_sub: np.ndarray
    sub_body: np.ndarray
    sub_rank: np.ndarray
    pair_sub: np.ndarray
    pair_node: np.ndarray
    sub_ptr: np.ndarray
    num_nodes: int

    @property
    def num_subdomains(self) -> int:
        """Number of subdomains."""
        return self.sub_body.size

    def local_subdomains(self, rank: int) -> np.ndarray:
        """Subdomains owned by ``rank``."""
        return np.flatnonzero(self.sub_rank == rank)

    def rank_pairs(self, rank: int) -> slice:
        """The (subdomain, node) pairs of the subdomains of ``rank`` (they are contiguous)."""
        subs = self.local_subdomains(rank)
        if subs.size == 0:
            return slice(0, 0)
        return slice(int(self.sub_ptr[subs[0]]), int(self.sub_ptr[subs[-1] + 1]))

    def nodes(self, s: int) -> np.ndarray:
        """Sorted global nodes of subdomain ``s``."""
        return self.pair_node[self.sub_ptr[s]:self.sub_ptr[s + 1]]

    def pair_index(self, sub: np.ndarray, node: np.ndarray) -> np.ndarray:
        """Index of each (subdomain, node) pair; raises if a node is not in the subdomain."""
        keys = self.pair_sub.astype(np.int64) * self.num_nodes + self.pair_node
        want = np.asarray(sub, dtype=np.int64) * self.num_nodes + np.asarray(node, dtype=np.int64)
        pos = np.searchsorted(keys, want)
        if np.any(pos >= keys.size) or np.any(keys[np.minimum(pos, keys.size - 1)] != want):
            raise ValueError("node not in subdomain")
        return pos

    def node_subdomains(self) -> tuple[np.ndarray, np.ndarray]:
        """CSR-like map node → subdomains containing it: ``(ptr, subs)``, subs sorted per node."""
        order = np.lexsort((self.pair_sub, self.pair_node))
        ptr = np.zeros(self.num_nodes + 1, dtype=np.int64)
        np.add.at(ptr, self.pair_node + 1, 1)
        return np.cumsum(ptr), self.pair_sub[order]


def decompose(mesh: MeshData, how, comm: MPI.Comm | int,
              points: DofPoints | None = None) -> Decomposition:
    """Split ``mesh`` into subdomains and assign them to the ranks of ``comm``.

    Args:
        mesh: The mesh.
        how: :class:`ByTags`, :class:`Parts`, :class:`ByFunction` or
            :class:`~.auto_parts.Auto` (Parts by the mesh's size and the ranks).
        comm: The communicator, or just its size (for planning without MPI).
        points: The dof points that number the primal dofs (default: the vertices, degree 1).
    """
    comm_size = comm if isinstance(comm, int) else comm.size
    if isinstance(how, Auto):
        how = Parts(auto_parts(how, np.bincount(mesh.cell_body,
                                                minlength=len(mesh.body_names)),
                               mesh.body_names, mesh.cell_type, comm_size), balance=BALANCE)
    midpoints = midpoints_of(mesh.x, mesh.cells) if not isinstance(how, ByTags) else None
    if isinstance(how, ByTags):
        label = mesh.cell_body.astype(np.int64)
    elif isinstance(how, Parts):
        label = np.empty(mesh.cells.shape[0], dtype=np.int64)
        for b, name in enumerate(mesh.body_names):
            n = how.n.get(name, 1) if isinstance(how.n, Mapping) else how.n
            cells = np.flatnonzero(mesh.cell_body == b)
            if n > cells.size:
                raise InputError(f"Parts: {n} parts for body {name!r}, which has only "
                                 f"{cells.size} cells")
            if how.balance == "volume" and how.method != "rcb":
                raise InputError("Parts: balance='volume' needs method='rcb'")
            if how.method == "rcb":
                weights = None if how.balance == "cells" else \
                    np.abs(cell_volumes(mesh.x, mesh.cells[cells], mesh.cell_type))
                part = rcb(midpoints[cells], int(n), weights)
            elif how.method == "ptscotch" and isinstance(comm, int):
                part = graph_partition(mesh.cells[cells], int(n), mesh.cell_type)
            elif how.method == "ptscotch":  # on rank 0: PT-Scotch may differ between processes
                part = None
                with collective(comm, "decomposition"):
                    if comm.rank == 0:
                        part = graph_partition(mesh.cells[cells], int(n), mesh.cell_type)
                part = comm.bcast(part, root=0)
            else:
                raise InputError(f"Parts: unknown method {how.method!r}; use 'rcb' or 'ptscotch'")
            label[cells] = b * (1 << 32) + part
        if isinstance(how.n, Mapping):
            unknown = set(how.n) - set(mesh.body_names)
            if unknown:
                raise InputError(f"Parts: unknown bodies {sorted(unknown)}; the bodies are "
                                 f"{list(mesh.body_names)}")
    elif isinstance(how, ByFunction):
        try:
            label = np.asarray(how.fn(midpoints))
        except Exception as e:  # the user's labeller: say which function failed
            raise InputError(f"ByFunction.fn(midpoints) raised {type(e).__name__}: {e}") from e
        if label.shape != (mesh.cells.shape[0],) or not np.issubdtype(label.dtype, np.integer):
            raise InputError("ByFunction: the function must return one integer label per cell "
                             f"(shape ({mesh.cells.shape[0]},)), got {label.dtype} {label.shape}")
    else:
        raise InputError(f"unknown decomposition {how!r}: use Auto(), ByTags(), Parts(n) or "
                         "ByFunction(fn)")
    cell_sub = _split_components(mesh.cells, label, mesh.cell_type)
    if isinstance(how, Parts) and how.merge:
        cell_sub = merge_fragments(mesh.cells, cell_sub, label, mesh.cell_body, mesh.cell_type)
    cell_points = mesh.cells if points is None else points.cell_points
    num_points = mesh.num_nodes if points is None else points.num_points
    return _build(mesh, cell_sub, comm_size, cell_points, num_points)


def _split_components(cells: np.ndarray, label: np.ndarray,
                      cell_type: str | None = None) -> np.ndarray:
    """Subdomain id per cell: connected (through facets) pieces of equal label.

    Pieces are numbered in the order of their first cell, so the numbering is deterministic.
    """
    pairs = facet_neighbours(cells, cell_type)
    same = label[pairs[:, 0]] == label[pairs[:, 1]]
    pairs = pairs[same]
    n = cells.shape[0]
    graph = sp.coo_matrix((np.ones(pairs.shape[0]), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, comp = connected_components(graph, directed=False)
    first = first_of_each(comp, int(comp.max()) + 1)
    order = np.argsort(first, kind="stable")
    renumber = np.empty_like(order)
    renumber[order] = np.arange(order.size)
    return renumber[comp].astype(np.int32)


def pair_keys(cell_sub: np.ndarray, cell_points: np.ndarray, n: int) -> np.ndarray:
    """The distinct (subdomain, point) pairs of the cells, as sorted keys ``sub * n + point``.

    ``np.unique`` of the keys, column by column: each column gives sorted runs, which a
    stable sort merges faster than a sort of the whole.
    """
    keys = np.sort((cell_sub.astype(np.int64) * n + cell_points.T).ravel(), kind="stable")
    return keys[np.r_[True, keys[1:] != keys[:-1]]] if keys.size else keys


def _build(mesh: MeshData, cell_sub: np.ndarray, comm_size: int, cell_points: np.ndarray,
           N: int) -> Decomposition:
    nsub = int(cell_sub.max()) + 1
    keys = pair_keys(cell_sub, cell_points, N)
    pair_sub = (keys // N).astype(np.int32)
    pair_node = keys % N
    sub_ptr = np.searchsorted(pair_sub, np.arange(nsub + 1)).astype(np.int64)
    sub_body = mesh.cell_body[first_of_each(cell_sub, nsub)]
    return Decomposition(cell_sub=cell_sub, sub_body=sub_body,
                         sub_rank=assign_ranks(np.diff(sub_ptr), comm_size),
                         pair_sub=pair_sub, pair_node=pair_node, sub_ptr=sub_ptr, num_nodes=N)


def midpoints_of(x: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """The mean of each cell's vertices, bit for bit ``x[cells].mean(axis=1)``.

    Without the (cells × vertices × gdim) temporary of the fancy index.
    """
    total = x[cells[:, 0]]
    for j in range(1, cells.shape[1]):  # over the 3 to 8 vertices of a cell
        total += x[cells[:, j]]
    return total / cells.shape[1]


def first_of_each(labels: np.ndarray, k: int) -> np.ndarray:
    """The first index of each value 0 … k − 1 in ``labels`` (each must occur).

    A counting sort (SciPy's COO → CSR keeps the order within a row), not ``np.minimum.at``
    (slow in NumPy < 1.25) or a comparison sort.
    """
    n = labels.size
    by_label = sp.csr_matrix((np.ones(n, dtype=np.int8), (labels, np.arange(n))), shape=(k, n))
    return by_label.indices[by_label.indptr[:-1]].astype(np.int64)


def assign_ranks(weights: np.ndarray, comm_size: int) -> np.ndarray:
    """Contiguous blocks of subdomains with balanced total weight (node count).

    No rank is left without a subdomain when there are at least as many subdomains as ranks.
    """
    nsub = weights.size
    if nsub <= comm_size:  # one subdomain each on the first ranks
        return np.arange(nsub, dtype=np.int32)
    cum = np.cumsum(weights)
    starts = [0]
    for r in range(1, comm_size):
        s = int(np.searchsorted(cum, cum[-1] * r / comm_size))
        if nsub >= comm_size:
            s = min(max(s, starts[-1] + 1), nsub - (comm_size - r))
        starts.append(min(s, nsub))
    rank = np.zeros(nsub, dtype=np.int32)
    for r, s in enumerate(starts[1:], start=1):
        rank[s:] = r
    return rank


def graph_partition(cells: np.ndarray, n: int, cell_type: str | None = None) -> np.ndarray:
    """Partition cells into ``n`` parts with PETSc's PT-Scotch on their facet adjacency graph.

    Runs on ``COMM_SELF`` on every rank with the same input, hence the same result everywhere.
    """
    from petsc4py import PETSc

    if n == 1:
        return np.zeros(cells.shape[0], dtype=np.int64)
    pairs = facet_neighbours(cells, cell_type)
    m = cells.shape[0]
    g = sp.coo_matrix((np.ones(2 * pairs.shape[0]), (np.r_[pairs[:, 0], pairs[:, 1]],
                                                      np.r_[pairs[:, 1], pairs[:, 0]])),
                      shape=(m, m)).tocsr()
    g.sort_indices()
    adj = PETSc.Mat().createAIJ((m, m), csr=(g.indptr.astype(PETSc.IntType),
                                             g.indices.astype(PETSc.IntType), g.data),
                                comm=PETSc.COMM_SELF)
    adj.assemble()
    part = PETSc.MatPartitioning().create(PETSc.COMM_SELF)
    prefix = "dolfinx_feti_partition_"
    part.setOptionsPrefix(prefix)
    part.setAdjacency(adj)
    part.setType("ptscotch")
    opts = PETSc.Options()
    opts.setValue(f"{prefix}mat_partitioning_nparts", n)  # petsc4py 3.18 has no setNParts
    try:
        part.setFromOptions()
        iset = PETSc.IS().create(PETSc.COMM_SELF)
        part.apply(iset)
        labels = iset.getIndices().astype(np.int64)
    finally:
        opts.delValue(f"{prefix}mat_partitioning_nparts")
        part.destroy()
        adj.destroy()
    return labels


def rcb(points: np.ndarray, n: int, weights: np.ndarray | None = None) -> np.ndarray:
    """Recursive coordinate bisection of points into ``n`` parts of (nearly) equal size.

    Every work item is sorted (stably) along the longest side of its bounding box, so points at
    equal coordinates keep the order of the level above: the order is that of the key
    (coordinate of this level, of the level above, …, point index), which a distributed
    selection can reproduce (:mod:`.distributed_decompose`).

    With non-negative ``weights``, the parts are of (nearly) equal total weight and every part
    keeps at least one point (when there are at least ``n`` points). The weights are turned
    into integers once (:func:`fixed_point_weights`) so that the cut depends on exact sums,
    not on the order of a floating-point summation.
    """
    labels = np.zeros(points.shape[0], dtype=np.int64)
    q = None if weights is None else \
        fixed_point_weights(weights, float(np.max(weights, initial=0.0)), points.shape[0])
    work = [(np.arange(points.shape[0]), n, 0)]
    while work:
        idx, k, first = work.pop()
        if k == 1 or idx.size == 0:
            labels[idx] = first
            continue
        p = points[idx]
        axis = int(np.argmax(p.max(axis=0) - p.min(axis=0)))
        order = idx[np.argsort(p[:, axis], kind="stable")]
        k1 = k // 2
        if q is None:
            cut = int(round(idx.size * k1 / k))
        else:
            cw = np.cumsum(q[order])
            cut = int(np.searchsorted(cw, weight_target(int(cw[-1]), k1, k))) + 1
            cut = min(max(cut, k1), idx.size - (k - k1))
        work.append((order[:cut], k1, first))
        work.append((order[cut:], k - k1, first + k1))
    return labels


def fixed_point_weights(weights: np.ndarray, wmax: float, m: int) -> np.ndarray:
    """Non-negative weights as int64 fixed-point numbers whose sum cannot overflow.

    ``wmax`` is the largest weight and ``m`` their number, over all ranks (scalars, or arrays
    of one value per weight for several point sets at once). The scale is the power of two
    that maps ``wmax`` below ``2**(62 - bits(m))``: each weight keeps about 42 bits relative to
    the largest for a million points, and every sum of them is exact.
    """
    bits = 62 - np.frexp(np.asarray(m, dtype=np.float64))[1]  # 62 - m.bit_length()
    exponent = np.frexp(np.asarray(wmax, dtype=np.float64))[1]
    return np.rint(np.ldexp(np.asarray(weights, dtype=np.float64), bits - exponent)
                   ).astype(np.int64)


def weight_target(total, k1, k):
    """The least integer at least ``total * k1 / k`` (exact, for int64 scalars or arrays).

    The cut of a weighted bisection is at the first point whose prefix sum reaches it.
    """
    return total // k * k1 - (-(total % k) * k1 // k)
