"""A stopping test in the caller's units: the largest weighted entry of the projected gradient.

The solvers' own test, ``||g^P|| <= rtol ||b||``, measures the gradient against the linear
term, whose size depends on data that need not affect the solution (in FETI the gaps of contact
rows out of reach, the rows a method keeps). :class:`MaxGradientTest` lets the caller say what
small means: ``max_i w_i |g^P_i| <= tol`` (with ``w_i`` per entry, e.g. the reciprocal of a
row's scale, so that ``w_i g^P_i`` is a length), and for SMALBE also ``||D x|| <= eq_tol``.
Given to :meth:`.mpgp.MPGP.solve`, :meth:`.cg.CG.solve` or :meth:`.smalbe.SMALBE.solve` as
``test``, it replaces the relative test (the result's reason is then ``'rtol'``, or SMALBE's
``'converged'``).
"""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..parallel.reduce import max_scalar


class MaxGradientTest:
    """``max_i w_i |g^P_i| <= tol`` and ``||D x|| <= eq_tol`` (collective).

    Args:
        weight: Local array of the weights ``w_i >= 0`` (the layout of the unknowns).
        tol: Tolerance of the weighted gradient.
        comm: The communicator of the unknowns.
        eq_tol: Tolerance of ``||D x||`` (SMALBE's equality); infinite: not tested.

    Attributes:
        last: The weighted maximum of the last gradient tested.
    """

    def __init__(self, weight: np.ndarray, tol: float, comm: MPI.Comm,
                 eq_tol: float = math.inf) -> None:
        if not (tol >= 0 and eq_tol >= 0):
            raise ValueError(f"stopping test: need tol, eq_tol >= 0 (got {tol}, {eq_tol})")
        self.weight, self.tol, self.eq_tol, self.comm = weight, tol, eq_tol, comm
        self.last = math.inf

    def value(self, gP: np.ndarray) -> float:
        """``max_i w_i |g^P_i|`` over all ranks."""
        local = float(np.max(self.weight * np.abs(gP), initial=0.0))
        return max_scalar(self.comm, local)

    def __call__(self, gP: np.ndarray, x: PETSc.Vec | None = None) -> bool:
        """Whether the gradient test holds for the local projected gradient ``gP``."""
        self.last = self.value(gP)
        return self.last <= self.tol


__all__ = ["MaxGradientTest"]
