"""FETI preconditioners of the dual operator F = B K⁺ Bᵀ: lumped (B K Bᵀ) and Dirichlet (B S Bᵀ).

The rows of B are orthonormal on the gluing (k − 1 Helmert rows at a node of k subdomains),
which is the multiplicity scaling for these rows: with equal subdomains, B S Bᵀ inverts F on an
interface exactly. S_i is the Schur complement of K_i on the dofs that B touches (the
interface, Dirichlet and contact dofs of the subdomain), applied with a sparse Cholesky
factorization of the interior block.

Stiffness scaling (``scaling="stiffness"``, Rixen & Farhat, IJNME 44 (1999) 489–516): with
Δ = diag(K)⁻¹ (each dof weighted by the inverse of its own stiffness) the preconditioner is
Z B Δ K Bᵀ Δ Z (lumped) or Z B Δ S Δ Bᵀ Z (Dirichlet), Z ≈ (B Δ Bᵀ)⁻¹. Across a coefficient
jump the stiff side then carries the interface, which multiplicity scaling cannot see.

B Δ Bᵀ couples two rows only where they touch a common dof: the gluing rows of one node (one
block of k − 1 rows per component at a node of k subdomains), the normal and tangential rows of
one contact node, and a contact row with the gluing or Dirichlet rows at its two nodes. So it
is block diagonal with small blocks, and Z inverts it block by block exactly (dense inverses of
a few rows): no factorization of a global dual matrix, the same blocks on any number of ranks
(see :class:`_DualScaling`).

Both are applied as ``mult(x, y)`` objects on dual vectors; the QP solvers project and mask
them as the constraints require. They are built from the operands a primal system gives
(``preconditioner_operands()``, a :class:`~dolfinx_feti.feti.system.PreconditionerOperands`):
its block-diagonal K, the rows B of the dual, the dofs to leave out (FETI-DP's corners, which
are primal unknowns: the Dirichlet preconditioner then takes the Schur complement with them
held, B_r S_rr B_rᵀ) and the node-and-kind block label of each row (for the stiffness scaling).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc
from scipy.sparse.csgraph import connected_components

from ..errors import SolveError
from .kplus import SparseCholesky
from .system import PreconditionerOperands

SCALINGS = ("multiplicity", "stiffness")


#: Couplings of B Δ Bᵀ between node blocks merge them into one exactly inverted block while the
#: result has at most this many rows; larger groups (a contact surface held together by mortar
#: rows) keep their node blocks and drop the couplings between them. Dropping them costs
#: accuracy at a given rtol and iterations (docs/robustness.md finding 14: a 579-row mortar
#: group split gave 20–200 × rtol errors, whole 1–6 × rtol; a 1 619-row group whole was faster
#: overall despite its 0.7 s dense inverse); 2 048 rows is a 32 MB dense inverse per rank.
MERGE_MAX = 2048


class _DualScaling:
    """Z = (B Δ Bᵀ)⁻¹, Δ = diag(K)⁻¹, by exact inverses of its diagonal blocks.

    The blocks are the connected groups of rows of B Δ Bᵀ: the rows of one node and one kind
    (gluing, Dirichlet, contact), joined where a contact row couples them (with the gluing rows
    at its two nodes, or the Dirichlet rows at its node). For node-to-node and obstacle contact
    every group is small and Z is the exact inverse. Node blocks live on the rank that owns
    their rows; the few joined groups (contact nodes on subdomain interfaces) are gathered —
    they are contact-surface data — and inverted on every rank. Z is a distributed sparse
    matrix with the pattern of B Δ Bᵀ.
    """

    def __init__(self, K: sp.csr_matrix, B: PETSc.Mat, row_blocks: np.ndarray | None) -> None:
        """Z for the rows of ``B``, grouped by ``row_blocks`` (a label per local row)."""
        comm = B.getComm().tompi4py()
        if comm.allreduce(row_blocks is None, op=MPI.LOR):
            raise SolveError("stiffness scaling: the primal system gives no row blocks")
        diag = K.diagonal()
        if not comm.allreduce(bool(np.all(diag > 0)), op=MPI.LAND):
            raise SolveError("stiffness scaling: a subdomain matrix has a non-positive "
                             "diagonal entry")
        self.delta = 1.0 / diag
        Bd = B.duplicate(copy=True)
        dvec = B.createVecRight()
        dvec.array[:] = self.delta
        Bd.diagonalScale(R=dvec)  # B Δ
        C = Bd.matTransposeMult(B)  # B Δ Bᵀ: local rows, neighbours' dofs included
        Bd.destroy()
        dvec.destroy()
        lo, hi = C.getOwnershipRange()
        sizes = C.getSizes()
        indptr, cols, vals = C.getValuesCSR()
        C.destroy()
        n = hi - lo
        key = np.asarray(row_blocks, dtype=np.int64)
        # A node block is labelled by its smallest (global) row: rank-independent.
        _, inv = np.unique(key, return_inverse=True)
        first = np.full(inv.max() + 1 if n else 0, np.iinfo(np.int64).max)
        np.minimum.at(first, inv, lo + np.arange(n))
        label = first[inv]
        bsize = np.bincount(inv)[inv]
        erow = lo + np.repeat(np.arange(n), np.diff(indptr))
        cols = cols.astype(np.int64)
        mine = (cols >= lo) & (cols < hi)
        lab_col = np.full(cols.size, -1, dtype=np.int64)
        lab_col[mine] = label[cols[mine] - lo]
        lab_row = label[erow - lo]
        cross = lab_col != lab_row
        rec = np.stack([erow[cross], lab_row[cross], bsize[erow[cross] - lo], cols[cross]], 1)
        allrec = np.concatenate(comm.allgather(rec)) if comm.size > 1 else rec
        g_label, g_head = _merge_groups(allrec)  # merged node blocks -> their group
        rec_row, at = np.unique(allrec[:, 0], return_index=True)
        rec_label = allrec[at, 1]
        in_group = _lookup(g_label, g_head, label) >= 0
        # The merged groups' entries (row, col, value, group), gathered from every rank.
        gsel = in_group[erow - lo]
        gr, gc, gv = erow[gsel], cols[gsel], vals[gsel]
        mine_c = (gc >= lo) & (gc < hi)
        lab_c = np.where(mine_c, label[np.clip(gc - lo, 0, max(n - 1, 0))],
                         _lookup(rec_row, rec_label, gc))
        gg_r = _lookup(g_label, g_head, label[gr - lo])
        keep = gg_r == _lookup(g_label, g_head, lab_c)
        ent = np.stack([gr[keep], gc[keep], gv[keep], gg_r[keep]], 1)
        allent = np.concatenate(comm.allgather(ent)) if comm.size > 1 else ent
        # Local node blocks (rows not in a merged group): in-block entries only.
        loc = ~in_group[erow - lo] & (lab_col == lab_row)
        r1, c1, z1, bad1 = _inverse_blocks(erow[loc], cols[loc], vals[loc], lab_row[loc])
        r2, c2, z2, bad2 = _inverse_blocks(allent[:, 0].astype(np.int64),
                                           allent[:, 1].astype(np.int64), allent[:, 2],
                                           allent[:, 3].astype(np.int64))
        if comm.allreduce(bad1 or bad2, op=MPI.LOR):
            raise SolveError("stiffness scaling: B diag(K)⁻¹ Bᵀ has a singular block (are the "
                             "rows of B redundant? use gluing='orthonormal')")
        own = (r2 >= lo) & (r2 < hi)
        r, c, z = (np.concatenate([r1, r2[own]]), np.concatenate([c1, c2[own]]),
                   np.concatenate([z1, z2[own]]))
        Zl = sp.csr_matrix((z, (r - lo, c)), shape=(n, sizes[1][1]))
        Zl.sort_indices()
        self.Z = PETSc.Mat().createAIJ(
            size=sizes, csr=(Zl.indptr.astype(PETSc.IntType), Zl.indices.astype(PETSc.IntType),
                             Zl.data), comm=B.getComm())
        self.Z.assemble()

    def apply(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = Z x."""
        self.Z.mult(x, y)

    def destroy(self) -> None:
        self.Z.destroy()


def _lookup(keys: np.ndarray, values: np.ndarray, query: np.ndarray) -> np.ndarray:
    """``values[k]`` where ``keys[k] == query`` (``keys`` sorted), else -1."""
    if keys.size == 0:
        return np.full(np.shape(query), -1, dtype=np.int64)
    pos = np.minimum(np.searchsorted(keys, query), keys.size - 1)
    return np.where(keys[pos] == query, values[pos], -1)


def _merge_groups(records: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Node blocks joined by couplings into groups of at most :data:`MERGE_MAX` rows.

    Args:
        records: One row per coupling between blocks, ``(row, its block label, the block's
            size, coupled row)``, from every rank (each coupling appears from both sides).

    Returns:
        The labels of the merged blocks (sorted) and the label of each one's group (its
        smallest block label).
    """
    empty = np.zeros(0, dtype=np.int64)
    if records.shape[0] == 0:
        return empty, empty
    rec_row, at = np.unique(records[:, 0], return_index=True)
    a = records[:, 1]
    b = _lookup(rec_row, records[at, 1], records[:, 3])
    ok = b >= 0
    labels, idx = np.unique(np.concatenate([a, b[ok]]), return_inverse=True)
    size = np.zeros(labels.size, dtype=np.int64)
    size[idx[:a.size]] = records[:, 2]
    m = labels.size
    graph = sp.coo_matrix((np.ones(int(ok.sum())), (idx[:a.size][ok], idx[a.size:])),
                          shape=(m, m))
    _, comp = connected_components(graph, directed=False)
    total = np.bincount(comp, weights=size)
    head = np.full(comp.max() + 1, np.iinfo(np.int64).max)
    np.minimum.at(head, comp, labels)
    merge = total[comp] <= MERGE_MAX
    return labels[merge], head[comp][merge]


def _inverse_blocks(row: np.ndarray, col: np.ndarray, val: np.ndarray,
                    block: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """Inverses of the diagonal blocks of a symmetric positive definite matrix.

    Args:
        row: Row (global index) of each entry; all entries of a block's rows are given.
        col: Column of each entry, in the same block as its row.
        val: Its value.
        block: The block of the entry's row (any integer label).

    Returns:
        The entries ``(row, col, value)`` of the inverse, and whether a block is singular (not
        positive definite or with a reciprocal condition number below 1e-12).
    """
    rws, ri = np.unique(row, return_inverse=True)
    n = rws.size
    ci = np.searchsorted(rws, col)
    blk = np.zeros(n, dtype=np.int64)
    blk[ri] = block
    _, bi = np.unique(blk, return_inverse=True)
    order = np.argsort(bi, kind="stable")
    size = np.bincount(bi) if n else np.zeros(0, dtype=np.int64)
    start = np.concatenate([[0], np.cumsum(size)])
    pos = np.empty(n, dtype=np.int64)  # position of each row inside its block
    pos[order] = np.arange(n) - start[bi[order]]
    out_r, out_c, out_v = [], [], []
    singular = False
    for s in np.unique(size):  # one batched inverse per block size (a handful of sizes)
        blocks = np.flatnonzero(size == s)
        index = np.full(size.size, -1)
        index[blocks] = np.arange(blocks.size)
        M = np.zeros((blocks.size, s, s))
        sel = index[bi[ri]] >= 0
        M[index[bi[ri[sel]]], pos[ri[sel]], pos[ci[sel]]] = val[sel]
        M = 0.5 * (M + M.transpose(0, 2, 1))
        w = np.linalg.eigvalsh(M)
        if not (w[:, 0] > 1e-12 * w[:, -1]).all():
            singular = True
            continue
        members = rws[order[start[blocks][:, None] + np.arange(s)]]  # (blocks, s) rows
        out_r.append(np.repeat(members, s, axis=1).ravel())
        out_c.append(np.tile(members, (1, s)).ravel())
        out_v.append(np.linalg.inv(M).ravel())
    if not out_r:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0), singular
    return (np.concatenate(out_r), np.concatenate(out_c), np.concatenate(out_v), singular)


class LumpedPreconditioner:
    """M⁻¹ = B K Bᵀ: one sparse matrix-vector product with the rank's block-diagonal K (cheap).

    With ``scaling="stiffness"``: M⁻¹ = Z B Δ K Δ Bᵀ Z (see the module docstring).
    """

    name = "lumped"

    def __init__(self, operands, scaling: str = "multiplicity", factor: str | None = None) -> None:
        """Use ``operands = (K, B, left_out[, row_blocks])`` of a primal system (module doc)."""
        if scaling not in SCALINGS:
            raise ValueError(f"preconditioner scaling must be one of {SCALINGS}, got "
                             f"{scaling!r}")
        ops = PreconditionerOperands(*operands)
        self.K, self.B, self.left_out, self.row_blocks = ops[:4]
        self.offsets = ops.offsets
        self.count = 0
        self._w = self.B.createVecRight()
        self._v = self.B.createVecRight()
        #: Notes for the report (a scaling that could not be applied).
        self.notes: list[str] = []
        self._scale = self._t = None
        if scaling == "stiffness":
            try:
                self._scale = _DualScaling(self.K, self.B, self.row_blocks)
                self._t = self.B.createVecLeft()  # a dual work vector for Z
            except SolveError as e:
                # Redundant rows of B (gluing="redundant", two obstacles on one surface) make
                # B Δ Bᵀ singular: keep the preconditioner, unscaled, and say so.
                scaling = "multiplicity"
                self.notes.append(f"{e}; the {self.name} preconditioner uses multiplicity "
                                  "scaling instead")
        self.scaling = scaling

    def _local(self, w: np.ndarray) -> np.ndarray:
        return self.K @ w

    def mult(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = B K Bᵀ x (or B S Bᵀ x for the Dirichlet preconditioner), scaled if asked."""
        self.count += 1
        z = self._scale
        if z is None:
            self.B.multTranspose(x, self._w)
            self._v.array[:] = self._local(self._w.array_r)
            self.B.mult(self._v, y)
            return
        z.apply(x, self._t)
        self.B.multTranspose(self._t, self._w)
        self._v.array[:] = z.delta * self._local(z.delta * self._w.array_r)
        self.B.mult(self._v, self._t)
        z.apply(self._t, y)

    def destroy(self) -> None:
        """Free the PETSc objects."""
        self._w.destroy()
        self._v.destroy()
        if self._scale is not None:
            self._scale.destroy()
            self._t.destroy()


class DirichletPreconditioner(LumpedPreconditioner):
    """M⁻¹ = B S Bᵀ with S_i = K_bb − K_bi K_ii⁻¹ K_ib on the dofs b that B touches.

    The interior blocks of all local subdomains are factored together (block diagonal). Dofs
    left out (``operands[2]``) that B does not touch are held: neither b nor interior.
    """

    name = "dirichlet"

    def __init__(self, operands, factor: str | None = None, scaling: str = "multiplicity") -> None:
        """Factor the interior blocks of the local subdomains."""
        super().__init__(operands, scaling, factor)
        K, B = self.K, self.B
        n = K.shape[0]
        # the dofs touched by some row (on any rank): Bᵀ w ≠ 0 for positive random weights w
        w = B.createVecLeft()
        w.array[:] = 1.0 + np.random.default_rng(B.getComm().getRank()).random(w.getLocalSize())
        t = B.createVecRight()
        B.multTranspose(w, t)
        self._b = np.flatnonzero(t.array_r != 0.0)
        w.destroy()
        t.destroy()
        inner = np.ones(n, dtype=bool)
        inner[self._b] = False
        if self.left_out is not None:
            inner &= ~self.left_out
        interior = np.flatnonzero(inner)
        self._Kbb = K[self._b][:, self._b].tocsr()
        self._Kib = K[interior][:, self._b].tocsr()
        try:
            self._chol = SparseCholesky(K[interior][:, interior], factor) if interior.size \
                else None
        except PETSc.Error as e:
            raise SolveError("Dirichlet preconditioner: an interior block is singular (the "
                             "constrained dofs of a subdomain do not fix it)") from e

    def _local(self, w: np.ndarray) -> np.ndarray:
        """S w for a vector, or for the columns of an array (:mod:`.precond_explicit`)."""
        out = np.zeros_like(w)
        wb = w[self._b]
        sb = self._Kbb @ wb
        if self._chol is not None:
            t = self._Kib @ wb
            sb -= self._Kib.T @ (self._chol.solve(t) if t.ndim == 1 else
                                 self._chol.solve_matrix(t))
        out[self._b] = sb
        return out

    def destroy(self) -> None:
        """Free the factorization."""
        super().destroy()
        if self._chol is not None:
            self._chol.destroy()
