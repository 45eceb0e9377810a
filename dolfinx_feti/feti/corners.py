"""FETI-DP's primal step: the corner dofs become global unknowns, assembled over the subdomains.

Split the primal dofs into corners c (one global unknown per corner dof, shared by all the
subdomain copies of that dof) and the rest r (still one copy per subdomain). Then

    K̃ = [[K_rr, K_rc], [K_cr, K_cc]]   (K_rr = diag(K_s,rr), K_cc assembled),   B̃ = B E,

E the map that copies each corner unknown to its subdomain copies. Gluing rows between copies
of one corner dof vanish in B̃ and are removed. K̃⁺ is applied through the corner Schur
complement S_cc = K_cc − K_cr K_rr⁻¹ K_rc, assembled and factored once on every rank:

    y_c = S_cc⁺ (x_c − K_cr K_rr⁺ x_r),   y_r = K_rr⁺ x_r − Ψ y_c,   Ψ = K_rr⁺ K_rc,

one local solve per application (Ψ is kept as one dense block per subdomain, its rows × the
subdomain's corner unknowns: a column of Ψ is nonzero on the subdomains of its corner only).
K_rr is factored subdomain by subdomain (:class:`~.kplus.BlockwiseInverse`), so that Ψ costs
each subdomain as many solves as it has corner unknowns, not as many as the rank's fullest.
When every body is held, K̃ is positive definite, there is no coarse
space and contact is a bound-constrained QP for MPRGP alone. A floating body leaves S_cc
singular with its rigid motions as kernel (the semicoercive FETI-DP): they are the kernel R̃ of
K̃ handed to the dualization, i.e. the natural coarse space on top, and S_cc⁺ fixes a few
corner dofs per floating body as the subdomain inverses do.

Layout of the new primal vector: every rank keeps its subdomains' dofs in place (a corner copy
is an unused entry with an identity row in K_rr), and rank 0 holds the corner unknowns after
its own entries.
"""

from __future__ import annotations

import copy

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError, SolveError, collective
from .kplus import BlockwiseInverse, CornerCoarse, FixingNodesInverse, LocalInverse
from .system import (
    EQUALITY,
    BlockSystem,
    PreconditionerOperands,
    RowOperands,
    local_csr,
    petsc_aij,
    same_matrix,
)
from .transforms import drop_small, recover_multipliers, row_max, select_rows

#: Entries of B̃ = B E below this times the largest entry of their row are cancellations
#: (the two copies of a corner dof in a gluing row).
CANCEL_RTOL = 1e-12


def _cat(parts: list[np.ndarray], dtype) -> np.ndarray:
    return np.concatenate(parts) if parts else np.zeros(0, dtype)


class CornerSystem(RowOperands):
    """The primal problem after the corners are assembled (built by :class:`EliminateCorners`).

    Has what :class:`~dolfinx_feti.feti.dualize.Dualization` needs: ``B``, ``f``, ``c``,
    ``apply_kplus``, ``kernel_matrix``.

    Attributes:
        n_coarse: Number of corner unknowns.
        types: Local row types of the kept rows.
    """

    def __init__(self, step: CornerAlgebra, B: PETSc.Mat, c: np.ndarray, f: PETSc.Vec,
                 types: np.ndarray) -> None:
        self._step = step
        self.comm = step.parent.comm
        self._set_rows(B, c, types)
        self.f = f
        self.n_coarse = step.n_coarse

    def factorize(self, factor: str | None = None, site: str = "") -> None:
        """Factor K_rr, build Ψ and S_cc, factor S_cc (collective; ``site``: the guard's)."""
        self._step.factorize(factor, site)

    @property
    def factored(self) -> bool:
        """Whether K̃⁺ is there (:meth:`factorize` done, or factors adopted)."""
        return self._step.Krr_plus is not None

    @property
    def Kplus(self) -> BlockwiseInverse | None:  # noqa: N802  (as BlockSystem.Kplus)
        """The factor that identifies K̃⁺: K_rr⁺ (Ψ, S_cc⁺ are shared with it, never alone).

        Two corner systems with the same object here apply the same K̃⁺, so a row update of an
        unchanged load takes the last K̃⁺f (:class:`~.dualize.Dualization`'s ``same_load``).
        """
        return self._step.Krr_plus

    def apply_kplus(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = K̃⁺ x."""
        self._step.apply_kplus(x.array_r, y.array)

    def local_inverse(self) -> LocalInverse:
        """K̃⁺ as K_rr⁺ by subdomains plus the corner correction (for :mod:`.explicit`)."""
        step = self._step
        coarse = CornerCoarse(step.Psi, step.S_plus, step.n_coarse) if step.n_coarse else None
        return LocalInverse(step.Krr_plus, step.parent.offsets, coarse)

    def kernel_matrix(self):
        """The rigid motions of the floating bodies in the new layout, and their bodies."""
        return self._step.kernel_local, list(self._step.kernel_bodies)

    def preconditioner_operands(self) -> PreconditionerOperands:
        """The parent's K and rows (kept), with the corner dofs left out of the interiors."""
        step = self._step
        blocks = step.parent.blocks
        return PreconditionerOperands(step.parent.K, step.B_parent, step.is_corner,
                                      None if blocks is None else blocks[step.kept],
                                      step.parent.offsets)

    def assembled(self) -> PETSc.Mat:
        """K̃ = Eᵀ K E as an MPIAIJ matrix (for checks)."""
        return self._step.assembled()

    def destroy(self) -> None:
        """Free the PETSc objects (of a :meth:`with_rhs` copy: its vectors only)."""
        self._destroy_rows()

    def destroy_factors(self) -> None:
        """Free K_rr⁺ and S_cc⁺ (shared with every copy and adopter of the step)."""
        step = self._step
        for name in ("Krr_plus", "S_plus"):
            inverse = getattr(step, name, None)
            if inverse is not None:
                inverse.destroy()
                setattr(step, name, None)


class CornerAlgebra:
    """The operators of :class:`EliminateCorners`: everything of the step but its child.

    E, B̃, the blocks of K̃, K_rr⁺, Ψ, S_cc. Kept apart so that the child can hold it without
    holding the step that holds the child: no reference cycle, so the PETSc objects go when
    the last owner drops them (a cycle is
    collected by each rank's garbage collector at its own moment, and petsc4py destroys a
    parallel object only when every rank has let it go). Arguments as
    :class:`EliminateCorners`'.
    """

    def __init__(self, parent: BlockSystem, coarse: np.ndarray, n_coarse: int,
                 modes: np.ndarray, mode_bodies: list[str]) -> None:
        self.parent = parent
        comm = parent.comm
        self.n_coarse = nc = int(n_coarse)
        coarse = np.asarray(coarse, dtype=np.int64)
        n = parent.K.shape[0]
        self.is_corner = coarse >= 0
        self.coarse = coarse
        rank = comm.rank
        n0 = comm.bcast(n if rank == 0 else None, root=0)
        self._c0 = n0  # global index of the first corner unknown
        start = parent.primal_start + (nc if rank > 0 else 0)
        self._n_local = n
        n_dp = n + (nc if rank == 0 else 0)
        N_dp = parent.primal_size[1] + nc
        col = np.where(self.is_corner, n0 + coarse, start + np.arange(n))
        E = sp.csr_matrix((np.ones(n), (np.arange(n), col)), shape=(n, N_dp))
        self.E = petsc_aij(E, parent.primal_size, (n_dp, N_dp), comm)
        self._set_rows(parent)

        # the blocks of K̃
        K = parent.K
        rr = (~self.is_corner).astype(float)
        ci = np.flatnonzero(self.is_corner)
        Pc = sp.csr_matrix((np.ones(ci.size), (ci, coarse[ci])), shape=(n, nc))
        self.K_rr, self.kernels_rr = parent.held(self.is_corner)
        self.K_rc = (sp.diags(rr) @ K @ Pc).tocsr()
        self.K_rc.eliminate_zeros()
        self._K_cc_local = (Pc.T @ K @ Pc).tocoo()

        # the kernel of K̃: the given rigid motions, checked, in the new layout
        modes = np.asarray(modes, dtype=float)
        m = modes.shape[1]
        if m:
            KZ = comm.allreduce(float(np.linalg.norm(K @ modes)) ** 2)
            kn = comm.allreduce(float(abs(K).sum(axis=1).max()) if n else 0.0, op=MPI.MAX)
            zn = comm.allreduce(float(np.linalg.norm(modes)) ** 2)
            if not np.sqrt(KZ) <= 1e-8 * kn * np.sqrt(zn):
                raise SolveError("FETI-DP: the rigid motions given as the kernel of the "
                                 "floating bodies are not in the kernel of K")
        mult = comm.allreduce(np.bincount(coarse[ci], minlength=nc).astype(float))
        Zc = comm.allreduce(Pc.T @ modes) / np.maximum(mult, 1.0)[:, None] if m else \
            np.zeros((nc, 0))
        self.Z_c = Zc
        Zr = np.where(self.is_corner[:, None], 0.0, modes)
        self.kernel_local = sp.csr_matrix(np.vstack([Zr, Zc]) if rank == 0 else Zr)
        self.kernel_bodies = list(mode_bodies)
        self.Krr_plus: BlockwiseInverse | None = None
        self.S_plus: FixingNodesInverse | None = None
        self._psi: list = []  # ((first row, end), corner unknowns, dense Ψ block) per block
        self._psi_csr: sp.csr_matrix | None = None

    def _set_rows(self, parent: BlockSystem) -> None:
        """B̃ = B E of ``parent``'s rows, without those that vanished (collective).

        The gluing rows between copies of one corner dof vanish in B̃ and are left out.
        """
        comm = parent.comm
        Bt = parent.B.matMult(self.E)
        Bl = drop_small(local_csr(Bt), CANCEL_RTOL, row_max(local_csr(parent.B)))
        Bt.destroy()
        empty = np.diff(Bl.indptr) == 0
        self.kept = ~(empty & (parent.types == EQUALITY))
        nk = int(self.kept.sum())
        self.B = petsc_aij(Bl[np.flatnonzero(self.kept)], (nk, comm.allreduce(nk)),
                           self.E.getSizes()[1], comm)  # the child's (it destroys it)
        self.B_parent = select_rows(parent.B, self.kept)

    def with_rows(self, parent: BlockSystem) -> CornerAlgebra:
        """These operators for ``parent``: the same K, decomposition and corners, other rows.

        Everything of K — E, K_rr and its kernels, K_rc, K_cc, the kernel of K̃, K_rr⁺, Ψ,
        S_cc and S_cc⁺ — is shared (none of it depends on B); only B̃ = B E and the rows kept
        are new. A row update (a moved curved obstacle: new contact coefficients) costs one
        sparse product with E instead of the whole step.

        Raises:
            SolveError: When ``parent``'s layout or K differs (then its corner blocks are of
                another K̃).
        """
        if not parent.comm.allreduce(same_matrix(parent.K, self.parent.K), op=MPI.LAND):
            raise SolveError("CornerAlgebra.with_rows: the new system has another K")
        new = copy.copy(self)
        new.parent = parent
        new._set_rows(parent)
        return new

    def rhs(self, parent: BlockSystem) -> tuple[PETSc.Vec, np.ndarray]:
        """The child's load Eᵀ f and kept right-hand sides (local) of ``parent``'s, checked."""
        c = parent.c.array_r
        bad = np.abs(c[~self.kept]) > 1e-12 * max(np.abs(c).max(initial=0.0), 1e-300)
        if parent.comm.allreduce(bool(np.any(bad)), op=MPI.LOR):
            raise InputError("FETI-DP: an equality row between copies of one corner dof has a "
                             "nonzero right-hand side")
        f = self.B.createVecRight()
        self.E.multTranspose(parent.f, f)
        return f, c[self.kept]

    def adopt_factors(self, other: CornerAlgebra) -> None:
        """Take K_rr⁺, Ψ, S_cc and S_cc⁺ of ``other``: same matrices and corners (collective).

        Raises:
            SolveError: When ``other`` has other corners (its factors are of another K̃).
        """
        same = np.array_equal(self.coarse, other.coarse)
        if not self.parent.comm.allreduce(bool(same), op=MPI.LAND):
            raise SolveError("the new rows give other corners than the set-up's: create a new "
                             "FetiSolver")
        for name in ("Krr_plus", "_psi", "_psi_csr", "S", "S_plus", "_t"):
            if hasattr(other, name):
                setattr(self, name, getattr(other, name))

    # --- the coarse problem ----------------------------------------------------------------
    @property
    def Psi(self) -> sp.csr_matrix:
        """Ψ = K_rr⁺ K_rc as one SciPy CSR matrix (local rows × corner unknowns).

        For the explicit dual operator; made from the dense blocks once, when first asked for.
        """
        if self._psi_csr is None:
            rows, cols, vals = [], [], []
            for (lo, _), corners, block in self._psi:
                r, k = np.nonzero(block)
                rows.append(lo + r)
                cols.append(corners[k])
                vals.append(block[r, k])
            n = self._n_local
            self._psi_csr = sp.csr_matrix(
                (_cat(vals, float), (_cat(rows, np.int64), _cat(cols, np.int64))),
                shape=(n, self.n_coarse))
        return self._psi_csr

    def factorize(self, factor: str | None = None, site: str = "") -> None:
        """K_rr⁺ (one factor per subdomain), Ψ = K_rr⁺ K_rc, S_cc and its generalized inverse.

        Ψ by subdomains: block b's rows × b's corner unknowns, one batched solve of b's factor
        with b's columns of K_rc (a column of K_rc is nonzero on its corner's subdomains only).
        The rank-local part runs in one guard (:func:`~dolfinx_feti.errors.collective`, phase
        ``site``); the assembly of S_cc after it is collective.
        """
        comm, parent, nc = self.parent.comm, self.parent, self.n_coarse
        with collective(comm, site):
            self.Krr_plus = BlockwiseInverse(self.K_rr, self.kernels_rr, factor, parent.labels)
            offsets = parent.offsets
            self._psi, self._psi_csr = [], None
            Kcc = self._K_cc_local
            rows, cols, vals = [Kcc.row], [Kcc.col], [Kcc.data]
            for b in range(len(offsets) - 1):  # a loop over the rank's subdomains
                lo, hi = int(offsets[b]), int(offsets[b + 1])
                corners = np.unique(self.coarse[lo:hi][self.is_corner[lo:hi]])
                if corners.size == 0:
                    self._psi.append(((lo, hi), corners, np.zeros((hi - lo, 0))))
                    continue
                Krc_b = self.K_rc[lo:hi][:, corners]
                psi = self.Krr_plus.solve_block(b, Krc_b.toarray(order="F"), overwrite=True)
                psi[self.is_corner[lo:hi]] = 0.0  # a corner copy is no unknown of K_rr
                self._psi.append(((lo, hi), corners, psi))
                Sb = np.asarray(Krc_b.T @ psi)  # S_cc −= K_rc,bᵀ Ψ_b on b's corner unknowns
                rows.append(np.tile(corners, corners.size))  # column-major, as Ψ_b: no copy
                cols.append(np.repeat(corners, corners.size))
                vals.append(-Sb.ravel(order="F"))
            S_loc = sp.csr_matrix((_cat(vals, float), (_cat(rows, np.int64),
                                                       _cat(cols, np.int64))),
                                  shape=(nc, nc)).tocoo()
        parts = comm.allgather((S_loc.row, S_loc.col, S_loc.data))
        S = sp.csr_matrix((np.concatenate([p[2] for p in parts]),
                           (np.concatenate([p[0] for p in parts]),
                            np.concatenate([p[1] for p in parts]))), shape=(nc, nc))
        S = (0.5 * (S + S.T)).tocsr()
        S.eliminate_zeros()
        self.S = S
        self._t = np.empty(nc)
        if nc == 0:  # no corners (e.g. one subdomain per body): K̃ = K
            return
        kernel = self._coarse_kernel()
        try:
            self.S_plus = FixingNodesInverse(S, [kernel], factor,
                                             ["the FETI-DP corner problem S_cc"])
        except SolveError as e:
            raise SolveError(
                f"FETI-DP: {e}. The corners do not join the subdomains rigidly (a mechanism "
                "in the corner problem); use method='tfeti' or 'feti1'") from None

    def _coarse_kernel(self) -> np.ndarray:
        """Orthonormal basis of ker S_cc: the corner values of the floating bodies' motions."""
        Zc = self.Z_c
        if Zc.shape[1] == 0 or Zc.shape[0] == 0:
            return np.zeros((Zc.shape[0], 0))
        U, sv, _ = np.linalg.svd(Zc, full_matrices=False)
        return U[:, sv > 1e-10 * sv.max(initial=0.0)] if sv.size and sv.max() > 0 else \
            np.zeros((Zc.shape[0], 0))

    def apply_kplus(self, x: np.ndarray, out: np.ndarray) -> None:
        """out = K̃⁺ x on the local array of the new layout (collective)."""
        n, comm = self._n_local, self.parent.comm
        yr = out[:n]
        self.Krr_plus.solve(x[:n], yr)
        if self.n_coarse == 0:
            return
        t = -(self.K_rc.T @ yr) if n else np.zeros(self.n_coarse)
        if comm.rank == 0:
            t += x[n:]
        comm.Allreduce(np.ascontiguousarray(t), self._t, op=MPI.SUM)
        yc = np.empty(self.n_coarse)
        self.S_plus.solve(self._t, yc)
        for (lo, hi), corners, block in self._psi:  # yr −= Ψ yc, subdomain by subdomain
            if corners.size:
                yr[lo:hi] -= block @ yc[corners]
        if comm.rank == 0:
            out[n:] = yc

    def assembled(self) -> PETSc.Mat:
        """K̃ = Eᵀ K E (MPIAIJ; for checks, not used by the solve)."""
        Kl = self.parent.K.tocsr()
        start = self.parent.primal_start
        Kg = sp.csr_matrix((Kl.data, Kl.indices + start, Kl.indptr),
                           shape=(Kl.shape[0], self.parent.primal_size[1]))
        K = petsc_aij(Kg, self.parent.primal_size, self.parent.primal_size, self.parent.comm)
        Kt = K.PtAP(self.E)
        K.destroy()
        return Kt

    def map_primal(self, Z: np.ndarray) -> np.ndarray:
        """Primal vectors (columns, local rows) of the child → of the parent: E Z."""
        comm, n = self.parent.comm, self._n_local
        Zc = comm.bcast(Z[n:] if comm.rank == 0 else None, root=0)
        out = Z[:n].copy()
        out[self.is_corner] = Zc[self.coarse[self.is_corner]]
        return out

    def map_back(self, u: PETSc.Vec, lam: PETSc.Vec) -> tuple[PETSc.Vec, PETSc.Vec]:
        """(u, λ) of the child → of the parent: u = E ũ, the removed rows' λ recovered."""
        up = self.parent.B.createVecRight()
        self.E.mult(u, up)
        lp = self.parent.B.createVecLeft()
        lp.set(0.0)
        lp.array[self.kept] = lam.array_r
        recover_multipliers(self.parent, up, lp, ~self.kept)
        return up, lp


class EliminateCorners:
    """Keep the corner dofs primal: the FETI-DP transform of a block system.

    Args:
        parent: The system (FETI-1 form: Dirichlet conditions eliminated).
        coarse: Per local dof of ``parent``, the index of its corner unknown, or −1.
        n_coarse: Number of corner unknowns.
        modes: Candidate kernel of K̃: the rigid motions of each floating body (connected set
            of subdomains) evaluated at the parent's local dofs, n_local × m with the same
            m columns on every rank (m = 0 when every body is held). They must vanish on the
            parent's fixed dofs and be continuous across subdomain copies.
        mode_bodies: The body of each column of ``modes``, for messages.

    The operators (E, the blocks of K̃, K_rr⁺, Ψ, S_cc) live in a :class:`CornerAlgebra`
    that the child shares; the child holds that, not this step, so that the step and its child
    form no reference cycle.

    Attributes:
        child: The :class:`CornerSystem`.
        algebra: The :class:`CornerAlgebra` (shared with the child).
    """

    def __init__(self, parent: BlockSystem, coarse: np.ndarray, n_coarse: int,
                 modes: np.ndarray, mode_bodies: list[str]) -> None:
        self.algebra = core = CornerAlgebra(parent, coarse, n_coarse, modes, mode_bodies)
        f, c = core.rhs(parent)
        self.child = CornerSystem(core, core.B, c, f, parent.types[core.kept])

    @property
    def parent(self) -> BlockSystem:
        """The system the step was applied to."""
        return self.algebra.parent

    @property
    def kept(self) -> np.ndarray:
        """Local mask of the parent's rows that the child keeps."""
        return self.algebra.kept

    @property
    def is_corner(self) -> np.ndarray:
        """Local mask of the parent's dofs that are corner copies."""
        return self.algebra.is_corner

    @property
    def coarse(self) -> np.ndarray:
        """Per local dof of the parent, the index of its corner unknown, or −1."""
        return self.algebra.coarse

    @property
    def n_coarse(self) -> int:
        """Number of corner unknowns."""
        return self.algebra.n_coarse

    @property
    def kernels_rr(self) -> list:
        """Per subdomain, the kernel of its K_rr (the corners held)."""
        return self.algebra.kernels_rr

    def factorize(self, factor: str | None = None, site: str = "") -> None:
        """Factor K_rr, build Ψ and S_cc, factor S_cc (collective)."""
        self.algebra.factorize(factor, site)

    def adopt_factors(self, other: EliminateCorners) -> None:
        """Take K_rr⁺, Ψ, S_cc and S_cc⁺ of ``other``: same matrices and corners (collective)."""
        self.algebra.adopt_factors(other.algebra)

    def map_primal(self, Z: np.ndarray) -> np.ndarray:
        """Primal vectors (columns, local rows) of the child → of the parent: E Z."""
        return self.algebra.map_primal(Z)

    def map_back(self, u: PETSc.Vec, lam: PETSc.Vec) -> tuple[PETSc.Vec, PETSc.Vec]:
        """The parent's (u, λ) of the child's."""
        return self.algebra.map_back(u, lam)

    def with_rows(self, parent: BlockSystem) -> EliminateCorners:
        """This step applied to ``parent``: the same K and corners, other rows (collective).

        K_rr⁺, Ψ and S_cc are shared (:meth:`CornerAlgebra.with_rows`); B̃, f̃ and c are new.
        """
        new = EliminateCorners.__new__(EliminateCorners)
        new.algebra = core = self.algebra.with_rows(parent)
        f, c = core.rhs(parent)
        new.child = CornerSystem(core, core.B, c, f, parent.types[core.kept])
        return new

    def for_load(self, parent: BlockSystem) -> EliminateCorners:
        """This step applied to ``parent``, a new load case of its parent (same K and B).

        The corner factorizations, Ψ and S_cc are shared; only the child's f and c are new.
        """
        core = copy.copy(self.algebra)
        core.parent = parent
        f, c = core.rhs(parent)
        child = self.child.with_rhs(f.array_r, c)
        f.destroy()
        child._step = core
        new = EliminateCorners.__new__(EliminateCorners)
        new.algebra, new.child = core, child
        return new
