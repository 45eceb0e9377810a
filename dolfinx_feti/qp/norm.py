"""Estimate ``||A||`` of a symmetric positive semidefinite operator by Lanczos."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from petsc4py import PETSc


@dataclass(frozen=True)
class NormEstimate:
    """Result of :func:`estimate_norm`.

    Attributes:
        value: Largest Ritz value: a lower bound on ``||A||`` (up to rounding).
        iterations: Multiplications by ``A`` spent.
        residual: ``||A y - value y||`` for the Ritz vector ``y``: some eigenvalue of ``A`` lies
            within this distance of ``value``, which tells how settled the estimate is.
        vector: The Ritz vector ``y`` (unit length) when asked for (``ritz=True``), else None.
    """

    value: float
    iterations: int
    residual: float = math.nan
    vector: PETSc.Vec | None = None


def _largest_ritz(alphas: list[float], betas: list[float]) -> tuple[float, np.ndarray]:
    """Largest eigenvalue of the Lanczos tridiagonal and its eigenvector."""
    if len(alphas) == 1:
        return alphas[0], np.ones(1)
    k = len(alphas)
    w, s = sla.eigh_tridiagonal(np.array(alphas), np.array(betas[:k - 1]), select="i",
                                select_range=(k - 1, k - 1))
    return float(w[0]), s[:, 0]


def estimate_norm(A: PETSc.Mat, template: PETSc.Vec, *, rtol: float = 1e-4, max_it: int = 100,
                  seed: int = 0, guess: PETSc.Vec | None = None,
                  ritz: bool = False) -> NormEstimate:
    """Estimate ``||A|| = lambda_max(A)`` for symmetric positive semidefinite ``A`` (collective).

    Lanczos without reorthogonalization: loss of orthogonality only duplicates converged Ritz
    values, it does not move the largest one outside the spectrum, and the three-term
    recurrence keeps the memory at three vectors. The start vector is drawn from
    ``numpy.random.default_rng(seed)`` over the *global* length and sliced by the ownership
    range, so the estimate does not depend on the number of ranks (up to rounding).

    The iteration stops when the largest Ritz value changes by at most ``rtol`` relative between
    two iterations, when an invariant subspace is found (the value is then exact for the start
    vector), or after ``max_it`` multiplications. The Ritz value never exceeds ``||A||``; from a
    random start its relative shortfall at stop is typically below ``rtol`` (measured: under
    3 rtol on dense, Laplacian and singular PSD spectra), but that is not a guarantee: when the
    top of the spectrum is a tight cluster the change test can stop before the cluster is
    resolved, short by up to the cluster's relative width (1e-3 in the tests). Hence MPRGP's
    margin ``alpha_bar = 1.95 / value`` (valid for a shortfall up to 2.5%);
    ``value + residual`` is a more conservative (still not guaranteed) choice.

    Args:
        A: The operator (any PETSc Mat with ``mult``).
        template: A Vec with the layout of ``A``'s columns.
        rtol: Relative change of the largest Ritz value that ends the iteration.
        max_it: Maximum number of multiplications.
        seed: Seed of the random start vector.
        guess: A guess of the top eigenvector (e.g. the Ritz vector of an estimate of a nearby
            operator): the start is it plus the random vector, each of unit length, so the
            top of the spectrum is found in fewer steps and every direction is still in the
            start (an eigenvalue the guess misses is found as from a random start).
        ritz: Return the Ritz vector too (keeps the Lanczos vectors: one vector per step).

    Returns:
        The estimate and its cost.
    """
    if max_it < 1:
        raise ValueError("estimate_norm: max_it must be at least 1")
    n = template.getSize()
    if n == 0:
        return NormEstimate(0.0, 0, 0.0)
    lo, hi = template.getOwnershipRange()
    rand = np.random.default_rng(seed).standard_normal(n)[lo:hi]
    v = template.duplicate()
    v.array[:] = rand
    v.scale(1.0 / v.norm())
    if guess is not None and guess.norm() > 0.0:
        v.axpy(1.0 / guess.norm(), guess)
        v.scale(1.0 / v.norm())
    basis: list[PETSc.Vec] = []
    v_old = template.duplicate()
    v_old.set(0.0)
    w = template.duplicate()
    alphas: list[float] = []
    betas: list[float] = []
    theta_old = -math.inf
    theta, residual = 0.0, math.inf
    beta_old = 0.0
    it = 0
    while it < max_it:
        it += 1
        if ritz:
            basis.append(v.copy())
        A.mult(v, w)
        alpha = w.dot(v)
        w.axpy(-alpha, v)
        w.axpy(-beta_old, v_old)
        beta = w.norm()
        alphas.append(alpha)
        theta, s_top = _largest_ritz(alphas, betas)
        residual = abs(beta * s_top[-1])
        if not math.isfinite(theta):
            raise ValueError("estimate_norm: A produced non-finite values")
        scale = max(abs(theta), abs(alpha), 1e-300)
        if beta <= 1e-14 * scale:
            # Invariant subspace: the Ritz values are eigenvalues, nothing more to learn.
            break
        if abs(theta - theta_old) <= rtol * abs(theta):
            break
        theta_old = theta
        betas.append(beta)
        beta_old = beta
        # Rotate the three vectors: v_old <- v, v <- w / beta, w reused as scratch.
        v_old, v, w = v, w, v_old
        v.scale(1.0 / beta)
    vector = None
    if ritz:
        vector = template.duplicate()
        vector.set(0.0)
        vector.maxpy(s_top, basis)
        vector.scale(1.0 / vector.norm())
    for u in (v, v_old, w, *basis):
        u.destroy()
    return NormEstimate(max(theta, 0.0), it, residual, vector)
