"""Explicit local dual operators: F = B K⁺ Bᵀ as one dense matrix per subdomain.

The implicit F (:class:`.dualize.ImplicitDual`) applies Bᵀ, one sparse Cholesky solve of the
rank's block-diagonal K and B per multiplication. Since K⁺ = diag(K_s⁺) (Total FETI and
FETI-1),

    F = Σ_s B_s K_s⁺ B_sᵀ = Σ_s Π_s F_s Π_sᵀ,   F_s = B_s K_s⁺ B_sᵀ  (m_s × m_s, dense),

where B_s holds the m_s rows of B that touch subdomain s, restricted to its columns, and Π_s
picks those rows of a dual vector. Formed once, F_s makes a multiplication one dense GEMV per
subdomain between a gather of the rows a rank's subdomains touch and a scatter-add of the
results to their owners (Homola et al., SC 2025: explicit local dual operators). FETI-DP's
K̃⁺ = K_rr⁺ + Ψ-part adds a rank-n_c correction,

    F = Σ_s B_s,r K_s,rr⁺ B_s,rᵀ + H S_cc⁺ Hᵀ,   H = B̃_c − B̃_r Ψ,

applied as in the implicit operator (one allreduce of n_c numbers and the replicated S_cc⁺
solve), with B̃_r Ψ formed once per rank as a sparse matrix.

Set-up: the columns of the B_sᵀ of all subdomains of a rank are solved together, the j-th
column of every subdomain in one right-hand side (K⁺ is block diagonal, so they do not mix):
max_s m_s right-hand sides in batches of :data:`BATCH` (one MatMatSolve of the rank's factor
each), then F_s = B_s Y_s by one sparse product per batch.

When it pays (``dual_operator="auto"``, :func:`choose`): with t_I the measured time of an
implicit multiplication, t_E the predicted time of an explicit one and T the predicted set-up,

    explicit  ⇔  T < N (t_I − t_E)   and   8 Σ_s m_s² bytes ≤ :data:`MEMORY_MAX` on every rank,

N the expected number of F-multiplications (:data:`EXPECTED_MULTS`). t_I is the fastest of
five implicit multiplications (not counted as F-multiplications; on a shared machine the
others only add waiting), T = (max_s m_s) t_c with t_c the measured time per column of a
batched solve of a few random columns, and t_E = c_e Σ_s m_s² + c_b (subdomains) + c_0
(+ FETI-DP's corner correction: one S_cc⁺ solve, timed, and two sparse products with B̃_r Ψ,
by their nonzeros) with the constants :data:`NS_PER_ENTRY`, :data:`US_PER_BLOCK`,
:data:`US_FIXED`, :data:`NS_PER_SPARSE_ENTRY` measured by ``bench/explicit_dual.py``. Each
time is the slowest rank's (every multiplication waits for it), so the choice is the same on
every rank. Measured (docs/benchmarks_history.md § 12), the model predicted t_E within 0.5–2.3× and
T within 0.7–2.0×, so the choice is only as good as the break-even is far from N.

The same blocks serve the Dirichlet preconditioner (:mod:`.precond_explicit`):
:class:`LocalBlocks` forms Σ_s Π_s B_s A_s B_sᵀ Π_sᵀ for any block-diagonal A.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from .kplus import LocalInverse

#: Right-hand sides per batched solve of the set-up (memory: n_local × BATCH doubles).
BATCH = 64
#: The expected number of F-multiplications of a solve, N of the cost model: about the median
#: count of the solves of docs/benchmarks_history.md § 12 (35–218, median 43; 3D 35–53, 2D 118–218).
EXPECTED_MULTS = 50
#: Most memory the explicit blocks may take per rank for ``"auto"`` to pick them [bytes].
MEMORY_MAX = 2 * 1024**3
#: Measured time of a dense GEMV per matrix entry [ns] (bench/explicit_dual.py: 0.27–0.34 on
#: blocks of 5–65 MB per rank, memory bound; less when they fit in the cache).
NS_PER_ENTRY = 0.3
#: Measured time of a sparse (CSR) product per nonzero [ns] (FETI-DP's B̃_r Ψ: 0.31).
NS_PER_SPARSE_ENTRY = 0.35
#: Measured overhead per subdomain of an explicit multiplication [µs] (slicing, BLAS call).
US_PER_BLOCK = 0.5
#: Measured fixed cost of an explicit multiplication [µs] (gather, scatter-add).
US_FIXED = 15.0
#: Columns of the batched solve timed for the set-up estimate.
_PROBE = 8


class LocalBlocks:
    """y = Σ_s Π_s B_s A_s B_sᵀ Π_sᵀ x with the local blocks formed once, dense (collective).

    A = diag(A_s) is a rank's block-diagonal operator on its primal entries, given by its action
    on the columns of a dense array; B_s the rows of B touching block s, restricted to its
    columns, optionally scaled by columns (B Δ). The blocks are formed by max_s m_s applications
    of A in batches of :data:`BATCH` columns, the j-th column of every block in one column.

    Args:
        B: The rows (MPIAIJ: owned dual rows × the primal layout).
        offsets: Local offsets of the blocks of A.
        apply_matrix: A applied to the columns of a dense (n × k) array of the first
            ``offsets[-1]`` local primal entries.
        scale: Per local primal entry, a column scaling of B (Δ), or None.
    """

    def __init__(self, B: PETSc.Mat, offsets: np.ndarray, apply_matrix,
                 scale: np.ndarray | None = None) -> None:
        self.comm: MPI.Comm = B.getComm().tompi4py()
        p = self.pattern = DualPattern(B, offsets)
        n, E = p.n_blocked, p.pair_g.size
        vals = p.vals if scale is None else p.vals * scale[p.dof]
        self._Bexp = Bexp = sp.csr_matrix((vals, (p.pair_of_entry, p.dof)), shape=(E, n))
        # Z[:, j] = Σ over the pairs at position j of their row of B: one column per block in
        # each right-hand side (A is block diagonal, so the blocks do not mix).
        Z = (Bexp.T @ sp.csr_matrix((np.ones(E), (np.arange(E), p.pos)),
                                    shape=(E, p.m_max))).tocsc()
        blk_size = p.sizes[p.pair_blk]
        flat = np.zeros(p.entries)
        base = p.block_start[p.pair_blk] + p.pos * blk_size  # (pair, column 0) in ``flat``
        for j0 in range(0, p.m_max, BATCH):
            j1 = min(j0 + BATCH, p.m_max)
            W = Bexp @ apply_matrix(Z[:, j0:j1].toarray())  # E × (j1 − j0)
            J = np.arange(j0, j1)
            inside = J[None, :] < blk_size[:, None]
            flat[(base[:, None] + J[None, :])[inside]] = W[inside]
        # One view per block, as formed: symmetrizing F_s changes nothing but the round-off,
        # yet that alone moved CG's count by 3 of 39 on FETI-1 (tests/feti/test_explicit_dual.py).
        self.blocks = []
        for s, m in enumerate(p.sizes):
            if m:
                first = int(p.pair_start[s])
                self.blocks.append((flat[p.block_start[s]:p.block_start[s] + m * m]
                                    .reshape(m, m), slice(first, first + int(m))))
        self.memory = flat.nbytes
        self._flat = flat
        self._xe = np.empty(E)
        self._ye = np.empty(E)
        self._xg = PETSc.Vec().createSeq(p.ghosts.size, comm=PETSc.COMM_SELF)
        self._yg = self._xg.duplicate()
        template = B.createVecLeft()
        iset = PETSc.IS().createGeneral(p.ghosts.astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        self._scatter = PETSc.Scatter().create(template, iset, self._xg, None)
        iset.destroy()
        template.destroy()

    def mult(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = the operator times x (collective)."""
        self._scatter.scatter(x, self._xg, addv=PETSc.InsertMode.INSERT_VALUES,
                              mode=PETSc.ScatterMode.FORWARD)
        xg = self._xg.array_r
        np.take(xg, self.pattern.pair_g, out=self._xe)
        self._yg.array[:] = self._apply(xg, self._xe)
        y.set(0.0)
        self._scatter.scatter(self._yg, y, addv=PETSc.InsertMode.ADD_VALUES,
                              mode=PETSc.ScatterMode.REVERSE)

    def _apply(self, xg: np.ndarray, xe: np.ndarray) -> np.ndarray:
        """The local contributions to the ghost rows: one GEMV per block, summed per row."""
        ye = self._ye
        for Fs, sl in self.blocks:
            np.dot(Fs, xe[sl], out=ye[sl])
        return np.bincount(self.pattern.pair_g, ye, minlength=xg.size) if ye.size else \
            np.zeros(xg.size)

    def destroy(self) -> None:
        """Free the PETSc objects."""
        for obj in (self._scatter, self._xg, self._yg):
            obj.destroy()


class ExplicitDual(LocalBlocks):
    """y = F x with F = B K⁺ Bᵀ held as dense blocks per subdomain (collective set-up).

    Args:
        primal: A factored primal system with ``B`` and ``local_inverse()``
            (:class:`.system.BlockSystem`, :class:`.corners.CornerSystem`).
    """

    name = "explicit"

    def __init__(self, primal) -> None:
        inv: LocalInverse = primal.local_inverse()
        super().__init__(primal.B, inv.offsets, inv.kplus.solve_matrix)
        p = self.pattern
        self._coarse = None
        if inv.coarse is not None:
            c = inv.coarse
            C = (self._Bexp @ c.Psi).tocsr()  # B̃_r Ψ on this rank's pairs
            Bc = sp.csr_matrix((p.c_vals, (p.c_dof, p.c_g)), shape=(c.n_coarse, p.ghosts.size))
            self._coarse = (C, Bc, c.S_plus, np.empty(c.n_coarse), np.empty(c.n_coarse))

    def _apply(self, xg: np.ndarray, xe: np.ndarray) -> np.ndarray:
        yg = super()._apply(xg, xe)
        if self._coarse is not None:  # + H S_cc⁺ Hᵀ x, H = B̃_c − B̃_r Ψ
            C, Bc, S_plus, t, yc = self._coarse
            self.comm.Allreduce(np.ascontiguousarray(Bc @ xg - C.T @ xe), t, op=MPI.SUM)
            S_plus.solve(t, yc)
            if xe.size:
                yg -= np.bincount(self.pattern.pair_g, C @ yc, minlength=xg.size)
            yg += Bc.T @ yc
        return yg


class DualPattern:
    """Which dual rows touch which local subdomain: the layout of the explicit blocks.

    From the local rows of Bᵀ (this rank's primal entries, global dual columns): the ghosts
    (the dual rows any local subdomain touches, sorted), and the pairs (subdomain, ghost)
    sorted by subdomain then row: pair e is row ``pair_pos[e]`` of its subdomain's block.

    Attributes:
        ghosts: Global dual rows touched by this rank's subdomains (sorted).
        sizes: m_s per local subdomain.
        m_max: The largest m_s on this rank.
        pair_blk, pair_g, pos: Per pair: subdomain, index into ``ghosts``, position.
        pair_start: First pair of each subdomain; ``block_start``: offset of its block in a
            flat array of all blocks (row-major).
        n_blocked: Local primal entries in the blocks (FETI-DP's corner unknowns follow).
        dof, vals, pair_of_entry: The nonzeros of B in the blocks: primal entry, value, pair.
        c_dof, c_g, c_vals: The nonzeros in FETI-DP's corner columns (rank 0).
    """

    def __init__(self, B: PETSc.Mat, offsets: np.ndarray) -> None:
        Bt = B.transpose(PETSc.Mat())  # a new matrix (no argument: in place)
        indptr, cols, vals = Bt.getValuesCSR()
        Bt.destroy()
        offsets = np.asarray(offsets, dtype=np.int64)
        n = self.n_blocked = int(offsets[-1]) if offsets.size else 0
        nb = max(offsets.size - 1, 0)
        dof = np.repeat(np.arange(indptr.size - 1), np.diff(indptr))
        self.ghosts, g = np.unique(cols.astype(np.int64), return_inverse=True)
        ng = max(self.ghosts.size, 1)
        blocked = dof < n
        corner = ~blocked
        self.c_dof, self.c_g, self.c_vals = dof[corner] - n, g[corner], vals[corner]
        blk = np.repeat(np.arange(nb), np.diff(offsets))[dof[blocked]]
        pairs, self.pair_of_entry = np.unique(blk * ng + g[blocked], return_inverse=True)
        self.dof, self.vals = dof[blocked], vals[blocked]
        self.pair_blk, self.pair_g = pairs // ng, pairs % ng
        self.sizes = np.bincount(self.pair_blk, minlength=nb).astype(np.int64)
        self.pair_start = np.concatenate([[0], np.cumsum(self.sizes)])
        self.block_start = np.concatenate([[0], np.cumsum(self.sizes ** 2)])
        self.pos = np.arange(pairs.size) - self.pair_start[self.pair_blk]
        self.m_max = int(self.sizes.max(initial=0))

    @property
    def entries(self) -> int:
        """Σ_s m_s²: the entries of the explicit blocks."""
        return int(self.block_start[-1])


def predicted_mult_time(pattern: DualPattern) -> float:
    """t_E of the cost model: the predicted time of one explicit multiplication [s]."""
    blocks = int(np.count_nonzero(pattern.sizes))
    return 1e-9 * NS_PER_ENTRY * pattern.entries + 1e-6 * (US_PER_BLOCK * blocks + US_FIXED)


def choose(setup: float, t_implicit: float, t_explicit: float, memory: float,
           expected_mults: float = EXPECTED_MULTS) -> bool:
    """Whether the explicit operator pays: set-up < N × saving per multiplication, in memory.

    All arguments are the slowest rank's (times in seconds, memory in bytes).
    """
    saving = t_implicit - t_explicit
    return bool(memory <= MEMORY_MAX and saving > 0 and setup < expected_mults * saving)


def _coarse_time(inv: LocalInverse, pattern: DualPattern) -> float:
    """The time of FETI-DP's corner correction in an explicit multiplication (0 without).

    The S_cc⁺ solve is timed; the two products with B̃_r Ψ (m_s rows × the corner unknowns of
    subdomain s, per subdomain) are predicted from their nonzeros.
    """
    if inv.coarse is None:
        return 0.0
    c = inv.coarse
    Psi = c.Psi.tocoo()
    blk = np.repeat(np.arange(pattern.sizes.size), np.diff(inv.offsets))[Psi.row]
    corners = np.unique(blk * max(c.n_coarse, 1) + Psi.col) // max(c.n_coarse, 1)
    nnz = float(np.sum(pattern.sizes[corners]))
    t = np.random.default_rng(2).standard_normal(c.n_coarse)
    yc = np.empty(c.n_coarse)
    t0 = time.perf_counter()
    c.S_plus.solve(t, yc)
    return time.perf_counter() - t0 + 2e-9 * NS_PER_SPARSE_ENTRY * nnz


def measured_costs(primal, implicit, expected_mults: float = EXPECTED_MULTS) -> dict:
    """The cost model's figures on this problem, the slowest rank's (collective).

    Args:
        primal: The factored primal system.
        implicit: The implicit operator (its ``mult(x, y)`` is timed, not counted).
        expected_mults: N of the model.

    Returns:
        ``t_implicit``, ``t_explicit`` (predicted), ``setup`` (predicted), ``memory`` and
        ``explicit`` (the choice), the same on every rank.
    """
    comm = primal.comm
    inv = primal.local_inverse()
    pattern = DualPattern(primal.B, inv.offsets)
    x = primal.B.createVecLeft()
    x.array[:] = np.random.default_rng(comm.rank).standard_normal(x.getLocalSize())
    y = x.duplicate()
    times = []
    for _ in range(5):
        comm.Barrier()
        t0 = time.perf_counter()
        implicit.mult(x, y)
        times.append(time.perf_counter() - t0)
    x.destroy()
    y.destroy()
    k = min(_PROBE, pattern.m_max)
    t_col = 0.0
    if k:
        Z = np.random.default_rng(1).standard_normal((pattern.n_blocked, k))
        t0 = time.perf_counter()
        inv.kplus.solve_matrix(Z)
        t_col = (time.perf_counter() - t0) / k
    local = np.array([min(times), predicted_mult_time(pattern) +
                      _coarse_time(inv, pattern), pattern.m_max * t_col, 8.0 * pattern.entries])
    worst = np.empty_like(local)
    comm.Allreduce(local, worst, op=MPI.MAX)
    out = dict(zip(("t_implicit", "t_explicit", "setup", "memory"), map(float, worst),
                   strict=True))
    out["explicit"] = choose(out["setup"], out["t_implicit"], out["t_explicit"],
                             out["memory"], expected_mults)
    return out
