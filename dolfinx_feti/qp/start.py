"""What the projected-gradient solvers (MPRGP, MPGP) share before their first iteration.

The counted product by ``A`` (the count is the solvers' figure of merit), the step length
``alpha_bar`` from ``||A||``, and the feasible start with its gradient ``A x - b``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..parallel.reduce import any_rank
from .box import check_finite
from .norm import estimate_norm


class Counter:
    """Multiplies by ``A`` and counts it: the count is the solver's figure of merit."""

    def __init__(self, A: PETSc.Mat) -> None:
        self.A = A
        self.n = 0

    def __call__(self, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = A x."""
        self.A.mult(x, y)
        self.n += 1


def step_length(name: str, mult: Counter, x: PETSc.Vec, counts: dict,
                alpha_bar: float | None, norm_A: float | None) -> tuple[float, float]:
    """Return ``(alpha_bar, scale_A)``: the projected step and the scale of ``||A||``.

    Without ``alpha_bar``, ``alpha_bar = 1.95 / ||A||`` with ``||A||`` given or estimated by
    Lanczos from ``x`` (its multiplications counted in ``mult`` and ``counts['norm']``).
    """
    if alpha_bar is None:
        if norm_A is None:
            est = estimate_norm(mult.A, x)
            counts["norm"] = est.iterations
            mult.n += est.iterations
            norm_A = est.value
        if not (math.isfinite(norm_A) and norm_A > 0):
            raise ValueError(f"{name}: ||A|| must be positive and finite, got {norm_A}")
        alpha_bar = 1.95 / norm_A
    if not (math.isfinite(alpha_bar) and alpha_bar > 0):
        raise ValueError(f"{name}: alpha_bar must be positive and finite, got {alpha_bar}")
    return alpha_bar, (norm_A if norm_A is not None else 1.95 / alpha_bar)


def feasible_start(name: str, project: Callable[[np.ndarray], np.ndarray], mult: Counter,
                   x: PETSc.Vec, b: PETSc.Vec, g: PETSc.Vec | None, g_valid: bool,
                   comm: MPI.Comm) -> PETSc.Vec:
    """Project ``x`` onto the feasible set and return the gradient ``g = A x - b`` there.

    A supplied valid ``g`` is kept (no multiplication) only if the projection moved nothing.
    """
    xa = x.array_r
    xp = project(xa)
    moved = any_rank(comm, bool(np.any(xp != xa)))
    if moved:
        x.array[:] = xp
    if g is None:
        g, g_valid = x.duplicate(), False
    if not g_valid or moved:
        mult(x, g)
        g.axpy(-1.0, b)
    check_finite(comm, f"{name}: the initial gradient A x - b", g.array_r)
    return g
