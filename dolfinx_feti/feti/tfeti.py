"""Total FETI: every subdomain floats, Dirichlet conditions are rows of B.

Builds, on the ranks that own them, the subdomain matrices and their generalized inverses, the
distributed B, and the dual quantities

    F = B K⁺ Bᵀ (a PETSc shell),  d = B K⁺ f − c,  Gᵀ = B R (local rows),  e = Rᵀ f,

and recovers the primal solution u = K⁺(f − Bᵀλ) + R α.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..constraints.rows import Rows
from ..errors import collective
from ..fem.rigid import rigid_modes
from ..fem.subdomain import Subdomain
from ..mesh.decompose import Decomposition
from ..mesh.topology import locate_facets
from ..problem import ContactProblem
from ..qp.equality import RowBlockConstraint, orthonormalize
from ..qp.shell import python_shell
from ..timing import Timer
from .kplus import FixingNodesInverse


def _petsc_aij(csr: sp.csr_matrix, rows: tuple[int, int], cols: tuple[int, int],
               comm: MPI.Comm) -> PETSc.Mat:
    csr = csr.tocsr()
    csr.sort_indices()
    M = PETSc.Mat().createAIJ(size=(rows, cols), csr=(csr.indptr.astype(PETSc.IntType),
                                                      csr.indices.astype(PETSc.IntType),
                                                      csr.data), comm=comm)
    M.assemble()
    return M


def _cells_by_subdomain(cell_sub: np.ndarray, subs: np.ndarray) -> dict[int, np.ndarray]:
    """The cells of each given subdomain (one sort, not one scan per subdomain)."""
    order = np.argsort(cell_sub, kind="stable")
    start = np.searchsorted(cell_sub[order], subs)
    stop = np.searchsorted(cell_sub[order], subs, side="right")
    return {int(s): order[a:b] for s, a, b in zip(subs, start, stop, strict=True)}


def _runs_of_equal_bodies(mesh, dec, subs, cells_of) -> list[list[int]]:
    """Consecutive subdomains with the same set of bodies, each run to be assembled as one mesh.

    Grouping by bodies keeps ``sub.body`` meaningful in the user's forms callback.
    """
    runs, key = [], None
    for s in subs:
        k = tuple(np.unique(mesh.cell_body[cells_of[int(s)]]))
        if k != key:
            runs.append([])
            key = k
        runs[-1].append(int(s))
    return runs


class _DualShell:
    """The python context of the F shell: y = B K⁺ Bᵀ x, counting applications."""

    def __init__(self, feti: TotalFETI) -> None:
        self.feti = feti
        self.count = 0
        self._w = feti.B.createVecRight()
        self._v = feti.B.createVecRight()

    def mult(self, mat: PETSc.Mat, x: PETSc.Vec, y: PETSc.Vec) -> None:
        self.count += 1
        self.feti.B.multTranspose(x, self._w)
        self.feti.apply_kplus(self._w, self._v)
        self.feti.B.mult(self._v, y)


class TotalFETI:
    """The Total FETI decomposition of a contact problem on one communicator.

    Attributes:
        B: Constraint matrix (dual rows × primal dofs), MPIAIJ.
        F: Dual operator B K⁺ Bᵀ, a PETSc shell Mat.
        d: Dual linear term B K⁺ f − c.
        c: Right-hand sides of the rows.
        f: Primal load vector.
        Gt_local: Local rows of Gᵀ = B R (owned dual rows × coarse dofs), scipy CSR.
        e: Rᵀ f, the same array on every rank.
        rows_local: Slice of the global rows owned by this rank.
    """

    def __init__(self, problem: ContactProblem, dec: Decomposition, rows: Rows,
                 comm: MPI.Comm, timer: Timer, factor: str | None = None) -> None:
        """Assemble, factor and build the dual operators (collective on ``comm``)."""
        self.comm, self.problem, self.dec, self.rows = comm, problem, dec, rows
        mesh, bs = problem.mesh, problem.value_size
        self.bs = bs
        rank = comm.rank
        self.local_subs = dec.local_subdomains(rank)
        sub_dofs = bs * np.diff(dec.sub_ptr)
        self.sub_offset = np.concatenate([[0], np.cumsum(sub_dofs)])  # global primal offsets
        first = self.local_subs[0] if self.local_subs.size else dec.num_subdomains
        self.primal_start = int(self.sub_offset[first]) if self.local_subs.size else 0
        n_loc = int(sub_dofs[self.local_subs].sum())
        self.primal_size = (n_loc, int(self.sub_offset[-1]))

        with timer.phase("assembly"), collective(comm, "assembly"):
            facets = self._subdomain_facets(mesh, dec)
            cells_of = _cells_by_subdomain(dec.cell_sub, self.local_subs)
            K_parts, f_parts = [], []
            for group in _runs_of_equal_bodies(mesh, dec, self.local_subs, cells_of):
                sub = Subdomain(group, mesh, [cells_of[s] for s in group],
                                [dec.nodes(s) for s in group], [facets.get(s, {}) for s in group],
                                problem.dof_points)
                K, f = sub.assemble(problem.forms, bs)
                K_parts.append(K)
                f_parts.append(f)
            self.K_local = sp.block_diag(K_parts, format="csr") if K_parts else \
                sp.csr_matrix((0, 0))
            # The rigid motions are linear: their nodal interpolation at the dof points is exact.
            x = problem.dof_points.x
            self.R = {int(s): rigid_modes(x[dec.nodes(s)], bs) for s in self.local_subs}
            self.k = 1 if bs == 1 else (3 if mesh.gdim == 2 else 6)
        with timer.phase("factorization"), collective(comm, "factorization"):
            self.Kplus = FixingNodesInverse(
                self.K_local, list(self.R.values()), factor,
                [f"subdomain {s} of body {mesh.body_names[dec.sub_body[s]]!r}" for s in self.R])

        with timer.phase("constraints"):
            owner = dec.sub_rank[rows.min_subdomain()]
            counts = np.bincount(owner, minlength=comm.size)
            start = int(counts[:rank].sum())
            self.rows_local = slice(start, start + int(counts[rank]))
            self.dual_size = (int(counts[rank]), rows.size)
            mine = (rows.e_row >= start) & (rows.e_row < start + counts[rank])
            col = bs * dec.pair_index(rows.e_sub[mine], rows.e_node[mine]) + rows.e_comp[mine]
            Bloc = sp.csr_matrix((rows.e_coef[mine], (rows.e_row[mine] - start, col)),
                                 shape=(counts[rank], self.primal_size[1]))
            self.B = _petsc_aij(Bloc, self.dual_size, self.primal_size, comm)
            self.c = self.B.createVecLeft()
            self.c.array[:] = rows.rhs[self.rows_local]
            self.f = self.B.createVecRight()
            # every rank writes (also an empty part): a write moves the Vec's state, and PETSc
            # reuses a norm cached at the old state (VecSet caches one) on a rank that did not
            # write, so that rank would skip the reduction of the next norm and hang the others
            self.f.array[:] = np.concatenate(f_parts) if f_parts else 0.0
            self._shell = _DualShell(self)
            self.F = python_shell(self._shell, self.c)

        with timer.phase("dual operators"):
            m_loc = self.k * self.local_subs.size
            self.coarse_size = (m_loc, self.k * dec.num_subdomains)
            if self.R:  # columns are global coarse indices: k per subdomain, in order
                Rloc = sp.block_diag([sp.csr_matrix(R) for R in self.R.values()], format="csr")
                Rloc = sp.csr_matrix((Rloc.data, Rloc.indices + self.k * int(self.local_subs[0]),
                                      Rloc.indptr), shape=(Rloc.shape[0], self.coarse_size[1]))
            else:
                Rloc = sp.csr_matrix((0, self.coarse_size[1]))
            Rmat = _petsc_aij(Rloc, self.primal_size, self.coarse_size, comm)
            Gt = self.B.matMult(Rmat)
            indptr, indices, data = Gt.getValuesCSR()
            self.Gt_local = sp.csr_matrix((data, indices, indptr),
                                          shape=(self.dual_size[0], self.coarse_size[1]))
            Gt.destroy()
            Rmat.destroy()
            e = np.zeros(self.coarse_size[1])
            f_loc = self.f.array_r
            for s, seg in self._segments():
                e[self.k * s:self.k * (s + 1)] = self.R[s].T @ f_loc[seg]
            self.e = comm.allreduce(e, op=MPI.SUM)
            self.d = self.B.createVecLeft()
            v = self.B.createVecRight()
            self.apply_kplus(self.f, v)
            self.B.mult(v, self.d)
            self.d.axpy(-1.0, self.c)
            v.destroy()

    @staticmethod
    def _subdomain_facets(mesh, dec) -> dict[int, dict[str, np.ndarray]]:
        """Boundary groups split by the subdomain of the cell each facet bounds."""
        out: dict[int, dict[str, np.ndarray]] = {}
        for name, f in mesh.facet_groups.items():
            if f.shape[0] == 0:
                continue
            cell, _ = locate_facets(mesh.cells, f, mesh.cell_type)
            sub = np.where(cell >= 0, dec.cell_sub[np.maximum(cell, 0)], -1)
            for s in np.unique(sub[sub >= 0]):
                out.setdefault(int(s), {})[name] = f[sub == s]
        return out

    @property
    def hessian_mults(self) -> int:
        """Number of F applications so far."""
        return self._shell.count

    def _segments(self):
        for s in self.R:
            lo = int(self.sub_offset[s]) - self.primal_start
            yield s, slice(lo, lo + self.R[s].shape[0])

    def apply_kplus(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = K⁺ x, subdomain by subdomain (the local solves)."""
        self.Kplus.solve(x.array_r, y.array)

    def primal(self, lam: PETSc.Vec, alpha: np.ndarray) -> PETSc.Vec:
        """u = K⁺(f − Bᵀλ) + R α."""
        w = self.B.createVecRight()
        self.B.multTranspose(lam, w)
        w.aypx(-1.0, self.f)
        u = self.B.createVecRight()
        self.apply_kplus(w, u)
        ua = u.array
        for s, seg in self._segments():
            ua[seg] += self.R[s] @ alpha[self.k * s:self.k * (s + 1)]
        w.destroy()
        return u

    def rigid_amplitudes(self, gradient: PETSc.Vec, active: np.ndarray,
                         hint: np.ndarray | None = None) -> np.ndarray:
        """α with G_Aᵀ α = g_A on the active rows, g = Fλ − d the dual gradient.

        On the active rows B_A u = c_A, which with u = K⁺(f − Bᵀλ) + Rα reads G_Aᵀ α = g_A;
        that is solved by least squares. A rigid motion that no active row sees (a body that
        touches nothing with a positive force) is not fixed by it: its amplitude is taken
        from ``hint`` (the QP solver's equality multiplier, which the dual KKT conditions
        tie to α so that the inactive contact rows hold too), or zero without a hint.
        """
        GA = self.Gt_local[np.flatnonzero(active)]
        r = self.comm.allreduce(GA.T @ gradient.array_r[active], op=MPI.SUM)
        # (G_A G_Aᵀ)⁺ r through the coarse machinery (sparse when it is large), not eigh.
        con = orthonormalize(RowBlockConstraint(GA, self.comm), rtol=1e-12)
        alpha = con.gram_solve(r)
        N = con.null_space
        if hint is not None and N.shape[1]:
            alpha += N @ (N.T @ hint)
        return alpha

    def residuals(self, u: PETSc.Vec, lam: PETSc.Vec) -> dict[str, float]:
        """Equilibrium residual ||K u − f + Bᵀλ|| / max(||f||, ||Bᵀλ||, κ ||u||).

        κ = max_i ||K_i||_∞ keeps the measure meaningful when no load acts (a problem driven
        by prescribed displacements only, where f and Bᵀλ may both vanish).
        """
        w = self.B.createVecRight()
        self.B.multTranspose(lam, w)
        ua, wa, fa = u.array_r, w.array_r, self.f.array_r
        r2 = float(np.sum((self.K_local @ ua - fa + wa) ** 2))
        kappa = float(abs(self.K_local).sum(axis=1).max()) if self.R else 0.0
        r2 = self.comm.allreduce(r2, op=MPI.SUM)
        kappa = self.comm.allreduce(kappa, op=MPI.MAX)
        ref = max(self.f.norm(), w.norm(), kappa * u.norm(), 1e-300)
        w.destroy()
        return {"equilibrium": float(np.sqrt(r2) / ref)}

    def energy(self, u: PETSc.Vec) -> float:
        """½ uᵀ K u − fᵀ u summed over subdomains."""
        ua, fa = u.array_r, self.f.array_r
        e = 0.5 * float(ua @ (self.K_local @ ua)) - float(fa @ ua)
        return self.comm.allreduce(e, op=MPI.SUM)

    def destroy(self) -> None:
        """Free the PETSc objects."""
        self.Kplus.destroy()
        for obj in (self.B, self.F, self.c, self.f, self.d):
            obj.destroy()
