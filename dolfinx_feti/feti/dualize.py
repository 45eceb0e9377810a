"""Dualization: from a primal FETI problem to F, d, G, e, and from λ back to u.

    F = B K⁺ Bᵀ (a PETSc shell),  d = B K⁺ f − c,  Gᵀ = B R (local rows),  e = Rᵀ f,

    u = K⁺ (f − Bᵀ λ) + R α.

The primal problem is anything with ``B``, ``f``, ``c``, ``apply_kplus`` and ``kernel_matrix``
(:class:`.system.BlockSystem` for Total FETI and FETI-1, :class:`.corners.CornerSystem` for
FETI-DP), so the same step serves every method. F is applied implicitly (Bᵀ, the local solves,
B: :class:`ImplicitDual`) or through dense local blocks formed once (``local_inverse()``
needed: :class:`.explicit.ExplicitDual`), as ``dual_operator`` says; ``"auto"`` picks by the
measured cost model of :mod:`.explicit`. Either way an application of F counts once.
"""

from __future__ import annotations

import copy

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError
from ..qp.equality import RowBlockConstraint, orthonormalize
from ..qp.shell import python_shell
from .explicit import EXPECTED_MULTS, ExplicitDual, measured_costs
from .system import petsc_aij


class ImplicitDual:
    """y = B K⁺ Bᵀ x applied as it reads: Bᵀ, the local solves, B (no set-up)."""

    name = "implicit"

    def __init__(self, primal) -> None:
        self.primal = primal
        self._w = primal.B.createVecRight()
        self._v = primal.B.createVecRight()

    def mult(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = F x (collective)."""
        self.primal.B.multTranspose(x, self._w)
        self.primal.apply_kplus(self._w, self._v)
        self.primal.B.mult(self._v, y)

    def destroy(self) -> None:
        """Free the work vectors."""
        self._w.destroy()
        self._v.destroy()


#: The ways to apply F, by the option ``dual_operator`` (``"auto"``: :func:`.explicit.choose`).
OPERATORS = {"implicit": ImplicitDual, "explicit": ExplicitDual}


class _DualShell:
    """The python context of the F shell: y = F x by ``operator``, counting applications."""

    def __init__(self, operator) -> None:
        self.operator = operator
        self.count = 0

    def mult(self, mat: PETSc.Mat, x: PETSc.Vec, y: PETSc.Vec) -> None:
        self.count += 1
        self.operator.mult(x, y)


class Dualization:
    """The dual operators of a primal problem, and the primal recovery (collective).

    Attributes:
        primal: The primal problem.
        B: Its constraint matrix.
        F: Dual operator B K⁺ Bᵀ, a PETSc shell Mat.
        d: Dual linear term B K⁺ f − c.
        c: Right-hand sides of the rows.
        Gt_local: Local rows of Gᵀ = B R (owned dual rows × coarse dofs), SciPy CSR.
        e: Rᵀ f, the same array on every rank.
        kernel_bodies: The body of each column of R (for messages).
        coarse_size: Number of columns of R (the coarse space before orthonormalization).
        rows_local: The global rows owned by this rank.
        operator: How F is applied: ``"implicit"`` or ``"explicit"``.
        operator_costs: With ``dual_operator="auto"``, the cost model's figures
            (:func:`.explicit.measured_costs`), else empty.

    Args:
        primal: The factored primal problem.
        dual_operator: ``"implicit"``, ``"explicit"`` or ``"auto"``.
        expected_mults: N of the cost model of ``"auto"``.
        same_load: The dualization of a chain of the same factors (other rows: a row update),
            whose kernel R this one takes, and its K⁺f where f is the same.
    """

    def __init__(self, primal, dual_operator: str = "implicit",
                 expected_mults: float = EXPECTED_MULTS, same_load: Dualization | None = None
                 ) -> None:
        self.primal = primal
        self.comm: MPI.Comm = primal.comm
        self.B, self.c, self.f = primal.B, primal.c, primal.f
        self.rows_local = primal.rows_local
        self.dual_size, self.primal_size = primal.dual_size, primal.primal_size
        if dual_operator not in (*OPERATORS, "auto"):
            raise InputError(f"dual_operator must be one of {(*OPERATORS, 'auto')}, got "
                             f"{dual_operator!r}")
        operator = ImplicitDual(primal)
        self.operator_costs: dict = {}
        if dual_operator == "auto":
            self.operator_costs = measured_costs(primal, operator, expected_mults)
            dual_operator = "explicit" if self.operator_costs["explicit"] else "implicit"
        if dual_operator != operator.name:
            operator.destroy()
            operator = OPERATORS[dual_operator](primal)
        self.operator = operator.name
        self._shell = _DualShell(operator)
        self.F = python_shell(self._shell, self.c)
        if self._same_inverse(same_load):  # the same K: its kernel too
            self.R, self.kernel_bodies = same_load.R, same_load.kernel_bodies
        else:
            self.R, self.kernel_bodies = primal.kernel_matrix()
        m = self.coarse_size = self.R.shape[1]
        Rmat = petsc_aij(self.R, self.primal_size, (PETSc.DECIDE, m), self.comm)
        Gt = self.B.matMult(Rmat)
        indptr, indices, data = Gt.getValuesCSR()
        self.Gt_local = sp.csr_matrix((data, indices, indptr), shape=(self.dual_size[0], m))
        Gt.destroy()
        Rmat.destroy()
        self._kplus_f: np.ndarray | None = None
        self.e, self.d = self._linear_terms(same_load)

    def _linear_terms(self, same_load: Dualization | None = None
                      ) -> tuple[np.ndarray, PETSc.Vec]:
        """e = Rᵀ f and d = B K⁺ f − c (one application of K⁺).

        ``same_load``: a dualization of the same factored K (other rows, e.g. a moved curved
        obstacle's): where its f is this one's on every rank, its K⁺f is taken (a row update
        of an unchanged load costs no K⁺ application for d).
        """
        e = self.comm.allreduce(self.R.T @ self.f.array_r, op=MPI.SUM) if self.coarse_size \
            else np.zeros(0)
        d = self.B.createVecLeft()
        v = self.B.createVecRight()
        if self._same_kplus_f(same_load):
            v.array[:] = same_load._kplus_f
        else:
            self.primal.apply_kplus(self.f, v)
        self._kplus_f = v.array_r.copy()
        self.B.mult(v, d)
        d.axpy(-1.0, self.c)
        v.destroy()
        return e, d

    def _same_inverse(self, other: Dualization | None) -> bool:
        """Whether ``other``'s primal applies this one's K⁺ (the same factor; collective)."""
        kplus = getattr(self.primal, "Kplus", None)
        same = other is not None and kplus is not None and \
            getattr(other.primal, "Kplus", None) is kplus
        return bool(self.comm.allreduce(bool(same), op=MPI.LAND))

    def _same_kplus_f(self, other: Dualization | None) -> bool:
        """Whether ``other`` holds K⁺f of this f and this K⁺ (collective)."""
        same = self._same_inverse(other) and other._kplus_f is not None and \
            other._kplus_f.shape == self.f.array_r.shape and \
            np.array_equal(other.f.array_r, self.f.array_r)
        return bool(self.comm.allreduce(bool(same), op=MPI.LAND))

    def for_load(self, primal) -> Dualization:
        """The dualization of ``primal``, a new load case of this one's primal (same K, B).

        F, G and R are shared (and so is the count of F applications); d and e are new.
        """
        new = copy.copy(self)
        new.primal, new.c, new.f = primal, primal.c, primal.f
        new.e, new.d = new._linear_terms()
        new._shares_operators = True
        return new

    @property
    def hessian_mults(self) -> int:
        """Number of F applications so far."""
        return self._shell.count

    def apply_kplus(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = K⁺ x."""
        self.primal.apply_kplus(x, y)

    def primal_solution(self, lam: PETSc.Vec, alpha: np.ndarray) -> PETSc.Vec:
        """u = K⁺(f − Bᵀλ) + R α."""
        w = self.B.createVecRight()
        self.B.multTranspose(lam, w)
        w.aypx(-1.0, self.f)
        u = self.B.createVecRight()
        self.primal.apply_kplus(w, u)
        if self.R.shape[1]:
            u.array[:] += self.R @ alpha
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

    def destroy(self, operators: bool | None = None) -> None:
        """Free the PETSc objects of the dual (not the primal's).

        ``operators``: also F and its operator, shared by every :meth:`for_load` copy
        (default: only when this is the original, not a copy).
        """
        self.d.destroy()
        if operators is None:
            operators = not getattr(self, "_shares_operators", False)
        if operators:
            self.F.destroy()
            self._shell.operator.destroy()
