"""The dual QP of Total FETI, as a plain QP that any bound-constrained solver can take.

After dualization, homogenization (λ = λ̂ + x with G λ̂ = e) and projection the problem is

    min 1/2 xᵀ A x − bᵀ x   s.t.   x ≥ lb on the inequality rows,   G̃ x = 0,

with ``A = P F P`` (a PETSc shell Mat), ``b = P (d − F λ̂)``, ``lb = −λ̂`` on the inequality
rows (``−inf`` elsewhere) and ``G̃`` the orthonormalized natural coarse space. :func:`solve`
runs our solvers on it; :func:`dual_qp` hands the same objects to anyone else (e.g. PETSc TAO
in ``bench/peers``), so that solvers are compared on one problem.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .constraints import build_rows
from .errors import InputError, collective
from .feti import TotalFETI
from .mesh.decompose import decompose
from .problem import ContactProblem
from .qp import (
    Projector,
    RowBlockConstraint,
    estimate_norm,
    homogenize,
    orthonormalize,
    projected_operator,
)
from .timing import Timer

#: A load component along a free rigid motion above this, relative to the size of the load
#: (:func:`_unbalanced`), means the load cannot be balanced (e ∉ Im G).
BALANCE_TOL = 1e-8


@dataclass
class DualQP:
    """The homogenized, projected dual QP of one problem and the FETI objects behind it.

    Attributes:
        feti: The Total FETI operators (``F``, ``B``, ``d``, ``e``, kernels, primal recovery).
        dec: The decomposition.
        rows: The constraint rows.
        constraint: ``G̃`` with orthonormal rows (:class:`.qp.RowBlockConstraint`).
        projector: ``P = I − G̃ᵀG̃``.
        A: ``P F P``.
        b: ``P (d − F λ̂)``.
        lb: Lower bound of ``x``: ``−λ̂`` on the inequality rows, ``−inf`` elsewhere.
        lam_hat: The particular solution λ̂ of ``G λ = e``.
        ineq: Local mask of the inequality rows.
        norm_A: Lanczos estimate of ``||P F P||``.
        b_noise: Round-off level of ``b`` (a floor for absolute tolerances).
        warnings: Notes for the report (e.g. an unloaded rigid motion nothing fixes).
        mortar: What the contact search found for each mortar condition
            (:class:`.constraints.mortar_rows.MortarInfo`).
    """

    feti: TotalFETI
    dec: object
    rows: object
    constraint: object
    projector: Projector
    A: PETSc.Mat
    b: PETSc.Vec
    lb: PETSc.Vec
    lam_hat: PETSc.Vec
    ineq: np.ndarray
    norm_A: float
    b_noise: float
    warnings: list[str]
    mortar: list = field(default_factory=list)

    def start(self, out: PETSc.Vec | None = None) -> PETSc.Vec:
        """A feasible start ``x = max(0, lb)`` (λ = λ̂ where that is feasible).

        Written into ``out`` if given, else into a new Vec.
        """
        x = self.b.duplicate() if out is None else out
        x.array[:] = np.maximum(0.0, self.lb.array_r)
        return x

    def objective(self, x: PETSc.Vec) -> float:
        """``1/2 xᵀ A x − bᵀ x`` (one multiplication by ``A``; collective)."""
        y = x.duplicate()
        self.A.mult(x, y)
        value = 0.5 * y.dot(x) - self.b.dot(x)
        y.destroy()
        return float(value)

    def multipliers(self, x: PETSc.Vec) -> PETSc.Vec:
        """λ = λ̂ + x."""
        lam = x.copy()
        lam.axpy(1.0, self.lam_hat)
        return lam


def dual_qp(problem: ContactProblem, comm: MPI.Comm = MPI.COMM_WORLD, *,
            factor: str | None = None, norm_rtol: float = 1e-4,
            timer: Timer | None = None) -> DualQP:
    """Decompose, assemble and dualize ``problem``; homogenize and project its dual QP.

    Args:
        problem: The contact problem.
        comm: The ranks to spread the subdomains over.
        factor: Sparse Cholesky package for K⁺ (see :class:`.SolverOptions`).
        norm_rtol: Relative tolerance of the Lanczos estimate of ``||P F P||``.
        timer: Records the phases ``decomposition``, ``assembly``, ``factorization`` and
            ``coarse problem``; a new one if None.

    Returns:
        The dual QP (collective objects on ``comm``).

    Raises:
        InputError: When the load on a floating body cannot be balanced (``e ∉ Im G``).
    """
    timer = Timer() if timer is None else timer
    with timer.phase("decomposition"):
        with collective(comm, "decomposition"):
            dec = decompose(problem.mesh, problem.decomposition, comm,
                                problem.dof_points)
        mortar = []
        with collective(comm, "constraints"):
            rows = build_rows(problem, dec, mortar)
    feti = TotalFETI(problem, dec, rows, comm, timer, factor)
    ineq = rows.inequality[feti.rows_local]
    with timer.phase("coarse problem"):
        ocon = orthonormalize(RowBlockConstraint(feti.Gt_local, comm), rhs=feti.e)
        warnings = _check_balance(ocon, feti)
        lam_hat = feti.d.duplicate()
        homogenize(ocon, lam_hat)
        Flh = feti.d.duplicate()
        feti.F.mult(lam_hat, Flh)
        b_noise = 1e3 * np.finfo(float).eps * (feti.d.norm() + Flh.norm())
        Flh.aypx(-1.0, feti.d)  # d − F λ̂
        projector = Projector(ocon)
        b = Flh.duplicate()
        projector.apply(Flh, b)
        Flh.destroy()
        A = projected_operator(feti.F, ocon)
        norm = estimate_norm(A, b, rtol=norm_rtol)
        lb = b.duplicate()
        lb.array[:] = np.where(ineq, -lam_hat.array_r, -np.inf)
    return DualQP(feti=feti, dec=dec, rows=rows, constraint=ocon, projector=projector, A=A,
                  b=b, lb=lb, lam_hat=lam_hat, ineq=ineq, norm_A=float(norm.value),
                  b_noise=float(b_noise), warnings=warnings, mortar=mortar)


def _check_balance(ocon, feti: TotalFETI) -> list[str]:
    """Refuse a load that the constraints cannot balance; note undetermined motions."""
    N = ocon.null_space
    if N.shape[1] == 0:
        return []
    mesh, dec, k = feti.problem.mesh, feti.dec, feti.k
    weight = np.sqrt(np.add.reduceat(N**2, np.arange(0, N.shape[0], k), axis=0)).max(axis=1)
    subs = np.flatnonzero(weight > 1e-6 * weight.max())
    bodies = sorted({mesh.body_names[b] for b in dec.sub_body[subs]})
    ratio = _unbalanced(N, feti)
    if ratio > BALANCE_TOL:
        raise InputError(
            f"the load cannot be balanced: bodies {bodies} can move rigidly without meeting any "
            "Dirichlet or contact condition, and the load has a component along that motion "
            f"(relative size {ratio:.2e}), so the problem has no solution (e is "
            "not in Im G). Add a Dirichlet condition or a contact surface that stops it, or "
            "remove that load component")
    return [f"{N.shape[1]} rigid motion(s) of bodies {bodies} are not fixed by any condition "
            "(and not loaded); of the solutions, which differ by these motions, the one "
            "returned is orthogonal to them (zero nodal mean along each, in the nodal l2 inner "
            "product): the same for every decomposition and number of ranks"]


def _unbalanced(N: np.ndarray, feti: TotalFETI) -> float:
    """The largest load component along a free rigid motion, relative to the load's size.

    ``|n_kᵀ e|`` against ``|n_k|ᵀ ẽ + ||e||`` with ``ẽ = |R|ᵀ |f|`` (the size of the terms
    summed in e = Rᵀf; ``||e||`` for the round-off of n_k itself): a self-equilibrated load
    has ``n_kᵀ e`` at round-off of ẽ, not of ``||e||``, which is itself round-off then.
    """
    e_abs = np.zeros(feti.coarse_size[1])
    f = np.abs(feti.f.array_r)
    for s, seg in feti._segments():
        e_abs[feti.k * s:feti.k * (s + 1)] = np.abs(feti.R[s]).T @ f[seg]
    e_abs = feti.comm.allreduce(e_abs, op=MPI.SUM)
    scale = np.abs(N).T @ e_abs + np.linalg.norm(feti.e)
    along = np.abs(N.T @ feti.e)
    return float(np.max(along / np.maximum(scale, 1e-300), initial=0.0))


__all__ = ["DualQP", "dual_qp"]
