"""The dual half of the chain: homogenize, then project; each maps a solution back.

After :class:`~.dualize.Dualization` the dual problem is

    min ½ λᵀ F λ − dᵀ λ   s.t.   G λ = e,   λ_I ≥ 0.

:class:`Homogenize` shifts it by a particular solution λ̂ of G λ̂ = e (the least-squares one
through the orthonormalized coarse space G̃), so that λ = λ̂ + x with G̃ x = 0 and x_I ≥ −λ̂_I;
:class:`Project` restricts it to ker G̃ with P = I − G̃ᵀG̃:

    min ½ xᵀ P F P x − bᵀ x,   b = P (d − F λ̂),   s.t.  x ≥ lb,  G̃ x = 0.

Both depend on the load only through e and d: :meth:`Homogenize.for_load` and
:meth:`Project.for_load` rebuild λ̂, lb and b of a new load case and share the coarse factor,
the projector, P F P and the estimate of ‖P F P‖ (Dostál 2009, ch. 11: the projector and the
Hessian do not depend on the right-hand sides).
"""

from __future__ import annotations

import copy

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..qp import Projector, estimate_norm, homogenize, projected_operator
from .dualize import Dualization


class Homogenize:
    """λ = λ̂ + x with G λ̂ = e: the equality becomes homogeneous, the bound moves to −λ̂.

    Args:
        dual: The dualized problem (its ``e`` is the coarse right-hand side).
        constraint: The orthonormalized coarse space G̃ (any right-hand side: ``dual.e`` is
            set here).
        ineq: Local mask of the inequality rows.

    Attributes:
        constraint: G̃ with the right-hand side ``dual.e``.
        lam_hat: λ̂ = G̃ᵀ T e, the least-squares particular solution.
        lb: The bound of x: −λ̂ on the inequality rows, −∞ elsewhere.
        rhs: d − F λ̂, the linear term of the homogenized problem.
        b_noise: Round-off level of ``rhs`` (a floor for absolute tolerances).
    """

    def __init__(self, dual: Dualization, constraint, ineq: np.ndarray) -> None:
        self.dual, self.ineq = dual, ineq
        self.constraint = constraint.with_rhs(dual.e)
        self.lam_hat = dual.d.duplicate()
        homogenize(self.constraint, self.lam_hat)
        self.rhs = dual.d.duplicate()
        if self.lam_hat.norm(PETSc.NormType.NORM_INFINITY) > 0.0:
            dual.F.mult(self.lam_hat, self.rhs)
        else:  # no coarse space or e = 0: F λ̂ = 0 without an F-multiplication
            self.rhs.set(0.0)
        self.b_noise = float(1e3 * np.finfo(float).eps * (dual.d.norm() + self.rhs.norm()))
        self.rhs.aypx(-1.0, dual.d)  # d − F λ̂
        self.lb = self.lam_hat.duplicate()
        self.lb.array[:] = np.where(ineq, -self.lam_hat.array_r, -np.inf)

    def for_load(self, dual: Dualization) -> Homogenize:
        """This step for a new load case (same F and G): λ̂, lb and d − F λ̂ recomputed."""
        return Homogenize(dual, self.constraint, self.ineq)

    def map_back(self, x: PETSc.Vec, at_bound: np.ndarray | None) -> PETSc.Vec:
        """λ = λ̂ + x, exactly 0 on the inequality rows the solver left on the bound."""
        lam = x.copy()
        lam.axpy(1.0, self.lam_hat)
        if at_bound is not None:  # on the bound: λ = 0, not λ̂ − λ̂ rounded
            lam.array[self.ineq & at_bound] = 0.0
        return lam

    def destroy(self) -> None:
        """Free the vectors."""
        for v in (self.lam_hat, self.rhs, self.lb):
            v.destroy()


class Project:
    """Restrict the homogenized problem to ker G̃: A = P F P, b = P (d − F λ̂).

    Args:
        hom: The homogenized problem.
        norm_rtol: Relative tolerance of the Lanczos estimate of ‖P F P‖.
        norm_guess: The top Ritz vector of a nearby P F P (:attr:`top` of the chain this one
            replaces: the same rows with new coefficients, or a new stiffness); the Lanczos
            estimate starts from it plus its random start (:func:`~dolfinx_feti.qp.
            estimate_norm`): 4 F-multiplications instead of 10 on a moving sphere's rows.

    Attributes:
        projector: P = I − G̃ᵀ G̃.
        A: P F P (a PETSc shell).
        b: P (d − F λ̂).
        norm_A: The estimate of ‖P F P‖.
        norm_mults: The F-multiplications the estimate took.
        top: Its Ritz vector (unit length; the next chain's ``norm_guess``).
    """

    def __init__(self, hom: Homogenize, norm_rtol: float = 1e-4,
                 norm_guess: PETSc.Vec | None = None) -> None:
        self.hom = hom
        self.projector = Projector(hom.constraint)
        self.b = hom.rhs.duplicate()
        self.projector.apply(hom.rhs, self.b)
        self.A = projected_operator(hom.dual.F, hom.constraint)
        if norm_guess is not None and self.b.getComm().tompi4py().allreduce(
                norm_guess.getSizes() != self.b.getSizes(), op=MPI.LOR):
            norm_guess = None  # another layout of rows (on any rank): nothing to start from
        est = estimate_norm(self.A, self.b, rtol=norm_rtol, guess=norm_guess, ritz=True)
        self.norm_A, self.norm_mults, self.top = float(est.value), est.iterations, est.vector

    def for_load(self, hom: Homogenize) -> Project:
        """This step for a new load case: only b; P, P F P and ‖P F P‖ are shared."""
        new = copy.copy(self)
        new.hom = hom
        new.b = hom.rhs.duplicate()
        self.projector.apply(hom.rhs, new.b)
        return new

    def map_back(self, multiplier: np.ndarray | None, gradient: PETSc.Vec) -> np.ndarray | None:
        """The coarse amplitudes the solver's equality multiplier μ implies, or None.

        With SMALBE's μ for G̃ x = 0, the dual KKT conditions give α = −T̃ᵀ(μ − G̃ g) for the
        dual gradient g = F λ − d (:meth:`Dualization.rigid_amplitudes` takes it as a hint).
        """
        if multiplier is None:
            return None
        con = self.hom.constraint
        return -con.transform_transpose(multiplier - con.mult(gradient))


__all__ = ["Homogenize", "Project"]
