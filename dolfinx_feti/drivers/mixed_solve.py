"""Solving a problem whose bodies are of different cell types: one FETI system of all meshes.

A :class:`~dolfinx_feti.mesh.mixed.MixedMesh` is one mesh per cell type, and the problem on
it is one :class:`~dolfinx_feti.ContactProblem` per mesh plus the mortar conditions between
them (:mod:`dolfinx_feti.problem.mixed_problem`). Each mesh's problem goes through the usual
set-up (decomposition, dof points, rows, assembly: every subdomain lies in one body, so on a
mesh of one type); the systems are then joined into one Total FETI system:

- the primal vector of a rank is its subdomains of mesh 0, then of mesh 1, …; a column of
  mesh k's own layout moves to that place (:class:`Layout`);
- the dof points are numbered mesh after mesh (the meshes share no node);
- the rows are each mesh's own rows, then on rank 0 the rows of the conditions between
  meshes: the coupling of the two surfaces (:func:`.constraints.mortar_mixed
  .mortar_coupling_between`: a triangle against a quadrilateral by clipping), its rows
  addressed to the smallest subdomain holding each point (as in one mesh), their columns asked
  of the subdomains' owners.

From there the dual, the QP solvers and the map back are those of any problem. The result
(:class:`~dolfinx_feti.results.mixed_solution.MixedSolution`) holds the displacement per mesh
and the forces of the rows between meshes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

from .. import compat
from ..constraints.mortar_mixed import mortar_coupling_between
from ..constraints.mortar_rows import coupled_rows, snap_roundoff
from ..constraints.rows import Kind, Rows
from ..errors import InputError, NotConverged, collective
from ..fem.assembly import assemble_subdomains, block_diagonal
from ..feti.chain import chain_qp
from ..feti.system import BlockSystem, petsc_aij, row_blocks, row_types
from ..feti.transforms import EliminateDirichlet
from ..options import SolverOptions
from ..results.mixed_solution import Coupled, MixedSolution
from ..results.mortar_report import between_meshes_warnings
from ..results.report import Report
from ..setup.share_distributed import columns
from ..setup.stages import share_problem
from ..timing import Timer
from .kkt_stop import kkt_residuals
from .qp_solve import solve_qp


@dataclass
class Layout:
    """Where each mesh's primal entries sit in the joined primal vector.

    Rank r holds its entries of mesh 0, then of mesh 1, …; the ranks one after another.

    Attributes:
        n: (ranks, meshes) local primal sizes.
        start: (ranks, meshes) first global column of each rank in each mesh's own layout.
        rank_start: First joined column of each rank.
        within: (ranks, meshes) offset of each mesh's entries in a rank's block.
    """

    n: np.ndarray
    start: np.ndarray
    rank_start: np.ndarray
    within: np.ndarray

    @classmethod
    def of(cls, sizes: list[int], comm: MPI.Comm) -> Layout:
        """The layout from every rank's local primal size of each mesh (collective)."""
        n = np.array(comm.allgather(list(sizes)), dtype=np.int64).reshape(comm.size, -1)
        start = np.cumsum(n, axis=0) - n  # each mesh's own layout is rank after rank
        total = n.sum(axis=1)
        return cls(n, start, np.cumsum(total) - total, np.cumsum(n, axis=1) - n)

    def columns(self, k: int, cols: np.ndarray) -> np.ndarray:
        """The joined columns of mesh k's columns ``cols``."""
        cols = np.asarray(cols, dtype=np.int64)
        r = np.searchsorted(self.start[:, k], cols, side="right") - 1
        return cols - self.start[r, k] + self.rank_start[r] + self.within[r, k]


def solve_mixed(problem, *, comm: MPI.Comm = MPI.COMM_WORLD,
                options: SolverOptions | Sequence[str] | None = None, **kwargs
                ) -> MixedSolution:
    """Solve a problem on bodies of different cell types (module docstring; collective).

    Total FETI (or FETI-1) on the joined system; the options are those of
    :func:`dolfinx_feti.solve` (``method`` "tfeti", "feti1" or "auto", which is Total FETI
    here).
    """
    with collective(comm, "options"):
        opts = SolverOptions.create(argv=options, **kwargs) if not isinstance(
            options, SolverOptions) else options.replace(**kwargs)
        if getattr(problem.forms, "solve_by", None) is not None:
            raise InputError(f"forms solved by {problem.forms.solve_by!r} (large deformation) "
                             "on bodies of several cell types are not implemented")
        if opts.method not in ("tfeti", "feti1", "auto"):
            raise InputError(f"method={opts.method!r}: a problem on bodies of several cell "
                             "types is solved by Total FETI or FETI-1 (method 'tfeti', "
                             "'feti1' or 'auto')")
    timer = Timer()
    split, bs = problem.mixed, problem.value_size
    shares, datas, shared_all = [], [], []
    for p in split.problems:
        shared = share_problem(p, comm, "tfeti", timer)
        shared_all.append(shared)
        shares.append(shared.share)
        datas.append(assemble_subdomains(p, shared.share, comm, timer, keep=False))
    layout = Layout.of([d.K.shape[0] for d in datas], comm)
    point_start = np.cumsum([0] + [s.num_points for s in shares])
    own, cols = [], []
    for k, share in enumerate(shares):
        rows = share.rows.own
        own.append(replace(rows, node=np.where(rows.node >= 0, rows.node + point_start[k], -1)))
        cols.append(layout.columns(k, share.rows.cols))
    with timer.phase("constraints"):
        cross, coupled = _across_rows(problem, shares, layout, point_start, bs, comm)
    own.append(cross.rows)
    cols.append(cross.cols)
    own_rows = Rows.concatenate(own)
    total = _joined_system(datas, own_rows, np.concatenate(cols), layout, comm)
    # FETI-1: the Dirichlet rows eliminated from the joined system (FETI-DP would need the
    # corners of the joined subdomains: not yet); "auto" is Total FETI here
    method = "feti1" if opts.method == "feti1" else "tfeti"
    steps = [EliminateDirichlet(total, own_rows.kind == Kind.DIRICHLET)] \
        if method == "feti1" else []
    qp = chain_qp(total, steps, method=method, factor=opts.factor, norm_rtol=opts.norm_rtol,
                  timer=timer, dual_operator=opts.dual_operator)
    qp.copy_weight = np.concatenate([1.0 / np.repeat(s.dec.multiplicity, bs) for s in shares])
    report = Report()
    report.warnings.extend(qp.warnings)
    report.warnings.extend(w for s in shared_all for info in s.mortar for w in info.warnings)
    try:
        out = solve_qp(qp, opts, report=report, timer=timer)
        e = qp.feti.e  # the summary's ||G λ − e|| relative to ||e||, as a single mesh's
        e_norm = float(np.linalg.norm(e))
        report.G_lambda = float(np.linalg.norm(out.G_lambda - e) / (e_norm if e_norm > 0 else 1.0))
    finally:  # the chain's operators and factors (the solution keeps plain arrays)
        qp.destroy()
    res = out.result
    report.converged = bool(res.converged) and bool(np.isfinite(res.gP_norm))
    report.reason = res.reason
    report.gP_rel = float(res.gP_norm / res.b_norm) if res.b_norm > 0 else float(res.gP_norm)
    report.iterations, report.outer_iterations = res.iterations, res.outer_iterations
    report.method = {"tfeti": "TFETI", "feti1": "FETI-1"}[method]
    report.sizes = {"primal": int(layout.n.sum()), "dual": int(total.dual_size[1]),
                    "subdomains": int(sum(s.dec.num_subdomains for s in shares)),
                    "ranks": comm.size}
    report.kkt, report.max_penetration = kkt_residuals(
        total, own_rows.scale, own_rows.kind, own_rows.inequality, out.u, out.lam)
    report.timings = timer.reduced(comm)
    lam = out.lam.array_r[own_rows.size - cross.rows.size:] if comm.rank == 0 else None
    sol = MixedSolution(problem, shares, datas, layout, out.u.array_r.copy(), coupled,
                        comm.bcast(lam, root=0), report, comm)
    nodal = [sol.nodal_values(k) for k in range(len(shares))]  # collective
    warn, report.extra["mortar"] = between_meshes_warnings(problem.mesh.parts, nodal,
                                                           split.across, coupled)
    report.warnings.extend(warn)
    for v in (out.x, out.u, out.lam):
        v.destroy()
    total.destroy()
    compat.garbage_cleanup(comm)
    if opts.error_if_not_converged and not report.converged:
        raise NotConverged(f"the solver did not converge: {report.reason}; see "
                           "error.solution.report", sol)
    return sol


@dataclass
class _Cross:
    """The rows between meshes (rank 0; empty elsewhere) and their joined columns."""

    rows: Rows
    cols: np.ndarray


def _surface_points(problem, shares, comm: MPI.Comm) -> list[tuple[np.ndarray, ...]]:
    """Per mesh, on rank 0: the smallest subdomain and the Dirichlet mask of each point.

    Filled at the points on the surfaces of the conditions between meshes (arrays over the
    mesh's points; None on the other ranks).
    """
    split, out = problem.mixed, []
    for k, share in enumerate(shares):
        groups = [c.spec.slave for c in split.across if c.slave == k] + \
            [c.spec.master for c in split.across if c.master == k]
        mesh = problem.mesh.parts[k]
        nodes = np.unique(np.concatenate([mesh.facets(g).ravel() for g in groups])) \
            if groups else np.zeros(0, dtype=np.int64)
        d = share.directory
        here = np.flatnonzero(np.isin(share.point_ids, nodes))
        piece = (share.point_ids[here], d.subs[d.ptr[here]], d.fixed[here])
        pieces = comm.gather(piece, root=0)
        if comm.rank != 0:
            out.append(None)
            continue
        first = np.full(share.num_points, -1, dtype=np.int64)
        fixed = np.zeros((share.num_points, d.fixed.shape[1]), dtype=bool)
        for pid, sub, fx in pieces:
            first[pid], fixed[pid] = sub, fx
        out.append((first, fixed))
    return out


def _across_rows(problem, shares, layout: Layout, point_start: np.ndarray, bs: int,
                 comm: MPI.Comm) -> tuple[_Cross, list[Coupled]]:
    """The rows of the conditions between meshes and their joined columns (collective)."""
    split = problem.mixed
    points = _surface_points(problem, shares, comm)
    gdim = problem.mesh.gdim
    blocks: list[Rows] = []
    coupled: list[Coupled] = []
    with collective(comm, "constraints"):
        if comm.rank == 0:
            first = np.concatenate([p[0] for p in points])
            fixed = np.concatenate([p[1] for p in points])
            for a in split.across:
                rows, info = _condition_rows(problem.mesh, a, first, fixed, point_start, bs)
                blocks.append(rows)
                coupled.append(info)
    coupled = comm.bcast(coupled, root=0)
    rows = Rows.concatenate(blocks) if blocks else Rows.empty(gdim)
    part = np.searchsorted(point_start, rows.e_node, side="right") - 1
    cols = np.zeros(rows.e_node.size, dtype=np.int64)
    for k, share in enumerate(shares):  # collective: the owners of the subdomains answer
        on = np.flatnonzero(part == k)
        mine = Rows(e_row=rows.e_row[on], e_sub=rows.e_sub[on],
                    e_node=rows.e_node[on] - point_start[k], e_comp=rows.e_comp[on],
                    e_coef=rows.e_coef[on], rhs=rows.rhs, kind=rows.kind, scale=rows.scale,
                    node=rows.node, partner=rows.partner, normal=rows.normal, spec=rows.spec)
        dec = share.dec
        pair_sub = np.repeat(dec.subs, np.diff(dec.pair_ptr)).astype(np.int64)
        c = columns(mine, pair_sub, dec.pair_node, share.point_ids, share.num_points,
                    dec.sub_size, dec.sub_rank, bs, comm)
        cols[on] = layout.columns(k, c)
    return _Cross(rows, cols), coupled


def _condition_rows(mesh, a, first: np.ndarray, fixed: np.ndarray, point_start: np.ndarray,
                    bs: int) -> tuple[Rows, Coupled]:
    """Rank 0: the rows of one condition between two meshes, in joined points."""
    ms, mm = mesh.parts[a.slave], mesh.parts[a.master]
    name = f"{type(a.spec).__name__}({a.spec.slave!r}, {a.spec.master!r})"
    c = mortar_coupling_between(ms, ms.facets(a.spec.slave), mm, mm.facets(a.spec.master),
                                a.spec.search_distance)
    if not np.any(c.coupled):
        raise InputError(f"{name}: no slave node has a master facet within the search "
                         f"distance {c.search_distance:.3g}")
    keep = np.flatnonzero(c.coupled)
    W = c.weights()
    gap = snap_roundoff(np.einsum("ij,ij->i", c.normals[keep], W @ mm.x - ms.x[c.slave_nodes[
        keep]]), np.vstack([ms.x, mm.x]))
    # the coupling in joined points: slave points of its mesh, master columns of the other
    M = c.M.tocsr()
    joined = replace(c, slave_nodes=c.slave_nodes + point_start[a.slave],
                     M=type(M)((M.data, M.indices + point_start[a.master], M.indptr),
                               shape=(M.shape[0], int(point_start[-1]))))
    slave = joined.slave_nodes[keep]
    if a.tie:
        blocks, comps = [], []
        for comp in range(bs):
            dirs = np.zeros((keep.size, bs))
            dirs[:, comp] = 1.0
            e_row, e_sub, e_node, e_comp, e_coef, s, _ = coupled_rows(joined, first, bs, dirs)
            free = ~fixed[slave, comp]
            new = np.cumsum(free) - 1
            ke = free[e_row]
            nr = int(free.sum())
            blocks.append(Rows(e_row=new[e_row[ke]], e_sub=e_sub[ke], e_node=e_node[ke],
                               e_comp=e_comp[ke], e_coef=e_coef[ke], rhs=np.zeros(nr),
                               kind=np.full(nr, Kind.GLUE, dtype=np.int8), scale=s[free],
                               node=slave[free], partner=np.full(nr, -1),
                               normal=np.zeros((nr, mesh.gdim)),
                               spec=np.full(nr, -1, dtype=np.int32)))
            comps.append(np.full(nr, comp))
        rows = Rows.concatenate(blocks)
        comp_of_row = np.concatenate(comps)
    else:
        dirs = c.normals[keep] if bs > 1 else np.ones((keep.size, 1))
        if bs == 1:
            gap = np.zeros(keep.size)
        e_row, e_sub, e_node, e_comp, e_coef, s, _ = coupled_rows(joined, first, bs, dirs)
        nr = keep.size
        rows = Rows(e_row=e_row, e_sub=e_sub, e_node=e_node, e_comp=e_comp, e_coef=e_coef,
                    rhs=s * gap, kind=np.full(nr, Kind.CONTACT, dtype=np.int8), scale=s,
                    node=slave, partner=np.full(nr, -1), normal=-c.normals[keep],
                    spec=np.full(nr, a.index, dtype=np.int32))
        comp_of_row = np.full(nr, -1)
    info = Coupled(index=a.index, tie=a.tie, slave_part=a.slave,
                   slave_nodes=c.slave_nodes[keep], D=c.D[keep], scale=rows.scale,
                   row_node=np.searchsorted(slave, rows.node), row_comp=comp_of_row,
                   normal=np.zeros((keep.size, mesh.gdim)) if a.tie else -c.normals[keep],
                   uncoupled=int(c.slave_nodes.size - keep.size), pairs=c.pairs,
                   search_distance=c.search_distance)
    return rows, info


def _joined_system(datas, own: Rows, cols: np.ndarray, layout: Layout, comm: MPI.Comm
                   ) -> BlockSystem:
    """The Total FETI system of all meshes: K block diagonal, the rows' columns joined."""
    n_loc = int(layout.n[comm.rank].sum())
    n_glob = int(layout.n.sum())
    rows_glob = comm.allreduce(own.size)
    Bloc = sp.csr_matrix((own.e_coef, (own.e_row, cols)), shape=(own.size, n_glob))
    B = petsc_aij(Bloc, (own.size, rows_glob), (n_loc, n_glob), comm)
    sizes = [d.K.shape[0] for d in datas]
    offsets = np.concatenate([[0]] + [d.offsets[1:] + o for d, o in
                                      zip(datas, np.cumsum([0] + sizes[:-1]), strict=True)])
    return BlockSystem(comm, block_diagonal([d.K for d in datas]),
                       np.concatenate([d.f for d in datas]), B, own.rhs, row_types(own),
                       offsets, [k for d in datas for k in d.kernels],
                       [f"mesh {i}: {lab}" for i, d in enumerate(datas) for lab in d.labels],
                       [b for d in datas for b in d.bodies], row_blocks(own))


__all__ = ["Layout", "solve_mixed"]
