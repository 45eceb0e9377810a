"""MPRGP: modified proportioning with reduced gradient projections (Dostál) for box constraints.

Minimizes ``f(x) = 1/2 x^T A x - b^T x`` subject to ``l <= x <= u`` (infinite bounds allowed) for
a symmetric positive (semi)definite ``A``. See ALGORITHMS.md section 4 and Dostál, *Optimal
Quadratic Programming Algorithms* (2009), chapter 5. It is the loop of :func:`.mpgp.mpgp` on a
flat constraint set (a box): three expansion steps (the standard fixed-length one and the
variants ``'optimal'``, ``'projcg'``), an adaptive (Barzilai-Borwein) length of the fixed one
(``alpha='bb'``), and CG steps preconditioned in face.
"""

from __future__ import annotations

from collections.abc import Callable

from petsc4py import PETSc

from ..validation import Choice, Option, OptionSet, Real
from .mpgp import ALPHAS, EXPANSIONS, mpgp
from .result import QPResult

#: MPRGP's options (also those of MPGP): ``-feti_mprgp_<name>``, ``SolverOptions.mprgp_<name>``.
OPTIONS = OptionSet(
    "mprgp", "MPRGP (bounds) and MPGP (bounds and discs), alone or as SMALBE's inner solver",
    gamma=Option(1.0, Real(gt=0), "the proportioning parameter Γ"),
    expansion=Option("fixed", Choice(*EXPANSIONS), "the expansion step: 'fixed', 'optimal' or "
                     "'projcg' (see mprgp())"),
    alpha=Option("fixed", Choice(*ALPHAS), "the expansion step length: 'fixed' (1.95/||A||) or "
                 "'bb' (Barzilai–Borwein, kept only if the energy decreases; needs expansion "
                 "'fixed')"))


def mprgp(A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, *, lb=None, ub=None, rtol: float = 1e-6,
          atol: float = 0.0, gamma: float = 1.0, alpha_bar: float | None = None,
          norm_A: float | None = None, expansion: str = "fixed", max_it: int = 10000,
          stop: Callable[[float, PETSc.Vec, PETSc.Vec], bool | None] | None = None,
          monitor: Callable[[int, float, str], None] | None = None,
          b_norm: float | None = None, g: PETSc.Vec | None = None,
          g_valid: bool = False, preconditioner=None, alpha: str = "fixed") -> QPResult:
    """Solve ``min 1/2 x^T A x - b^T x`` s.t. ``lb <= x <= ub`` by MPRGP (collective).

    :func:`.mpgp.mpgp` without discs and with MPRGP's proportioning (the exact line search
    along the chopped gradient): the arguments, the steps, the counts and the result are
    described there.
    """
    return mpgp(A, b, x, lb=lb, ub=ub, rtol=rtol, atol=atol, gamma=gamma, alpha_bar=alpha_bar,
                norm_A=norm_A, expansion=expansion, max_it=max_it, stop=stop, monitor=monitor,
                b_norm=b_norm, g=g, g_valid=g_valid, preconditioner=preconditioner, alpha=alpha,
                proportioning="line", name="mprgp")


__all__ = ["ALPHAS", "EXPANSIONS", "OPTIONS", "mprgp"]
