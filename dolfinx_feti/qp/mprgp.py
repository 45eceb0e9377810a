"""MPRGP: modified proportioning with reduced gradient projections (Dostál) for box constraints.

Minimizes ``f(x) = 1/2 x^T A x - b^T x`` subject to ``l <= x <= u`` (infinite bounds allowed) for
a symmetric positive (semi)definite ``A``. See ALGORITHMS.md section 4 and Dostál, *Optimal
Quadratic Programming Algorithms* (2009), chapter 5. It is :class:`.mpgp.MPGP` on a flat
constraint set (a box) with MPRGP's proportioning step (the exact line search along the
chopped gradient): three expansion steps (the standard fixed-length one and the variants
``'optimal'``, ``'projcg'``), an adaptive (Barzilai-Borwein) length of the fixed one
(``alpha='bb'``), and CG steps preconditioned in face.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar

from petsc4py import PETSc

from .mpgp import ALPHAS, EXPANSIONS, MPGP, OPTIONS
from .problem import QP
from .result import QPResult


class MPRGP(MPGP):
    """MPGP on a box with MPRGP's proportioning step (the line search along β).

    Same constructor and :meth:`~.mpgp.MPGP.solve` as :class:`.mpgp.MPGP`, with
    ``proportioning='line'`` by default; a QP with discs is refused (that is MPGP's).
    """

    name: ClassVar[str] = "mprgp"
    default_proportioning: ClassVar[str] = "line"

    def solve(self, qp: QP, x: PETSc.Vec, **kwargs) -> QPResult:  # noqa: D102
        if qp.constraints is not None and qp.constraints.curved:
            raise ValueError("mprgp: the QP has disc constraints; solve it by MPGP")
        return super().solve(qp, x, **kwargs)


def mprgp(A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, *, lb=None, ub=None, rtol: float = 1e-6,
          atol: float = 0.0, gamma: float = 1.0, alpha_bar: float | None = None,
          norm_A: float | None = None, expansion: str = "fixed", max_it: int = 10000,
          stop: Callable[[float, PETSc.Vec, PETSc.Vec], bool | None] | None = None,
          monitor: Callable[[int, float, str], None] | None = None,
          b_norm: float | None = None, g: PETSc.Vec | None = None,
          g_valid: bool = False, preconditioner=None, alpha: str = "fixed", reuse: int = 80,
          deflate: bool = True, project: bool = True, carry: bool = True) -> QPResult:
    """Solve ``min 1/2 x^T A x - b^T x`` s.t. ``lb <= x <= ub`` by MPRGP (collective).

    The function form of :class:`MPRGP` (see :class:`.mpgp.MPGP` for the arguments, the steps,
    the counts and the result); ``reuse`` recycles CG directions within this one solve
    (``deflate``, ``project`` as there; ``carry`` is accepted with the option set and has
    nothing to carry across in one solve).
    """
    solver = MPRGP(rtol=rtol, atol=atol, max_it=max_it, gamma=gamma, expansion=expansion,
                   alpha=alpha, alpha_bar=alpha_bar, monitor=monitor, reuse=reuse,
                   deflate=deflate, project=project, carry=carry)
    qp = QP.create(A, b, lb=lb, ub=ub, norm_A=norm_A, preconditioner=preconditioner)
    return solver.solve(qp, x, stop=stop, b_norm=b_norm, g=g, g_valid=g_valid)


__all__ = ["ALPHAS", "EXPANSIONS", "MPRGP", "OPTIONS", "mprgp"]
