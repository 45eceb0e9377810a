"""The expansion steps of MPGP on a flat set, one class per variant, chosen once by name.

An expansion follows a CG direction ``p`` that leaves the set: the largest feasible step
``t_f`` along ``p`` (the *half-step*) and then a step that adds entries to the active set. The
variants (Dostál 2009, chapter 5; Kružík et al., *Active set expansion strategies in MPRGP
algorithm*, Adv. Eng. Softw. 2020) are registered in :data:`EXPANSIONS` by the name of the
option ``expansion`` (and ``alpha='bb'`` for the adaptive length of the fixed one); a new
variant is a class here with its entry in the registry. On a curved set (discs) only the
fixed-length step is implemented (:meth:`Expansion.check`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from .mpgp_steps import CURVATURE_RTOL

if TYPE_CHECKING:
    from .mpgp_steps import MPGPSolve


class Expansion:
    """The fixed-length expansion: ``x <- P(x_h - alpha_bar phi(x_h))``, a fresh gradient."""

    #: Whether a trial step may be rejected (the solve then counts ``counts['rejected']``).
    rejects = False
    #: Whether it is defined on a curved set.
    curved = True

    def __init__(self, expansion: str, alpha: str) -> None:
        self.expansion, self.alpha = expansion, alpha

    def check(self, name: str, curved: bool) -> None:
        """Refuse a variant that the constraint set does not allow.

        Raises:
            ValueError: On a curved set for a variant other than the fixed-length one.
        """
        if curved and not self.curved:
            raise ValueError(f"{name}: with discs only the fixed expansion is implemented, got "
                             f"expansion={self.expansion!r}, alpha={self.alpha!r}")

    def expand(self, s: MPGPSolve, t_cg: float, t_f: float, gp: float, pAp: float,
               positive: bool) -> bool:
        """Expand from ``s.x`` along ``s.p``; False if the energy is unbounded below.

        Args:
            s: The solve (its ``x``, ``g``, ``p``, ``Ap`` and steps).
            t_cg: The CG step length (``inf`` without positive curvature).
            t_f: The largest feasible step along ``p`` (finite).
            gp: ``g^T p``.
            pAp: ``p^T A p``.
            positive: Whether the curvature along ``p`` counts as positive.
        """
        s.half_step(t_f)
        s.projected_step(s.alpha_bar)
        return True


class OptimalExpansion(Expansion):
    """Exact line search along ``d = phi~(x_h)`` over its whole feasible segment.

    ``t_max >= alpha_bar`` (``x_h - alpha_bar d`` is the fixed step), so the energy decreases
    at least as much as with the fixed step; ``g`` is updated with ``A d`` (no product when
    ``phi(x_h) = 0``: ``x_h`` minimizes the face).
    """

    curved = False

    def expand(self, s: MPGPSolve, t_cg: float, t_f: float, gp: float, pAp: float,
               positive: bool) -> bool:
        """The half-step, then the line search along ``phi~(x_h)``."""
        s.half_step(t_f)
        S, x, g, d, Ad = s.S, s.x, s.g, s.p, s.Ap  # p and A p are free after the half-step
        xa = x.array_r
        phi_a = S.split(xa, g.array_r)[0]
        d.array[:] = S.reduced_free(xa, phi_a, s.alpha_bar)
        s.phi.array[:] = phi_a
        gd = s.phi.dot(d)  # = g^T d: d vanishes where phi does
        if gd <= 0.0:
            return True
        s.mult(d, Ad)
        dAd = d.dot(Ad)
        t_max = S.max_step(xa, d.array_r)
        curvature = dAd > CURVATURE_RTOL * s.scale_A * d.dot(d)
        t = min(gd / dAd if curvature else math.inf, t_max)
        if not math.isfinite(t):
            return False
        x.array[:] = S.step(xa, d.array_r, t)
        g.axpy(-t, Ad)
        return True


class ProjectedCGExpansion(Expansion):
    """The projected full CG step ``P(x - t_cg p)``, else the fixed step from ``x_h``.

    The step has a fresh gradient and is kept if its energy is not above that of the half-step
    ``x_h`` (known from scalars); otherwise (``counts['rejected']``) the fixed step.
    """

    rejects = True
    curved = False

    def expand(self, s: MPGPSolve, t_cg: float, t_f: float, gp: float, pAp: float,
               positive: bool) -> bool:
        """The projected CG step, or the fixed expansion."""
        if math.isfinite(t_cg) and self.projected(s, t_cg, t_f, gp, pAp):
            return True
        return super().expand(s, t_cg, t_f, gp, pAp, positive)

    @staticmethod
    def projected(s: MPGPSolve, t_cg: float, t_f: float, gp: float, pAp: float) -> bool:
        """``x <- P(x - t_cg p)`` (one product), kept if not above the half-step's energy.

        Otherwise ``x`` and ``g`` are restored and ``counts['rejected']`` counts it.
        """
        x, g = s.x, s.g
        f_half = s.energy() - t_f * gp + 0.5 * t_f * t_f * pAp  # from scalars
        x_old, g_old = x.array_r.copy(), g.copy()
        x.array[:] = s.S.project(x_old - t_cg * s.p.array_r)
        s.fresh_gradient()
        kept = s.energy() <= f_half
        if not kept:
            x.array[:] = x_old
            g_old.copy(g)
            s.counts["rejected"] = s.counts.get("rejected", 0) + 1
        g_old.destroy()
        return kept


class BarzilaiBorweinExpansion(Expansion):
    """The fixed step with the long Barzilai–Borwein length when it is longer.

    ``alpha_BB = p^T p / p^T A p`` (the secant pair of the half-step, no product); if
    ``alpha_BB > alpha_bar`` the step ``P(x_h - alpha_BB phi(x_h))`` is kept if the energy did
    not increase, else ``x_h`` is restored and the fixed step made (``counts['rejected']``).
    """

    rejects = True
    curved = False

    def expand(self, s: MPGPSolve, t_cg: float, t_f: float, gp: float, pAp: float,
               positive: bool) -> bool:
        """The half-step, then the long step or the fixed one."""
        s.half_step(t_f)
        step = s.p.dot(s.p) / pAp if positive else 0.0
        if step > s.alpha_bar:
            x, g = s.x, s.g
            saved_x, saved_g = x.array_r.copy(), g.copy()  # the half-step
            f_h = s.energy()
            s.projected_step(step)
            if s.energy() <= f_h:
                saved_g.destroy()
                return True
            x.array[:] = saved_x  # the energy increased: back to the half-step
            saved_g.copy(g)
            s.counts["rejected"] += 1
            saved_g.destroy()
        s.projected_step(s.alpha_bar)
        return True


class GalerkinExpansion(Expansion):
    """In a face started from the recycled directions: the projected full CG step first.

    A face that the Galerkin step on the recycled directions ``W`` started (:mod:`.recycle`)
    continues by CG; after an uncut Galerkin step the gradient is orthogonal to ``W`` and the
    face's CG directions are A-conjugate to it (deflated CG), so the full CG step
    ``x - t_cg p`` minimizes the energy over ``x_0 + span(W, p_1, …, p_j)`` in the face: the
    Galerkin solution on the recycled space and this face's directions (after a step cut at a
    bound, the CG step from the cut point). Where it leaves the set, its projection
    ``P(x - t_cg p)`` (one product: a fresh gradient) moves at once every entry that solution
    puts beyond its bound, where the fixed step adds the entries one short gradient step
    reaches (a warm start's contact edge grew by a ring of nodes: as many expansions). Kept if
    its energy is not above the half-step's (from scalars; the test of ``'projcg'``), else
    (``counts['rejected']``, one product spent) the solver's own expansion follows.

    Not in the inner solves of an outer iteration (a ``stop`` callback: SMALBE's), which the
    outer test cuts short at each multiplier update: there it moved the counts by ±10 % either
    way (the 2D Hertz path with SMALBE) and once stopped SMALBE with a 20× larger equality
    residual (a random QP of tests/qp), so those keep the solver's own expansion.
    """

    rejects = True
    curved = False

    def __init__(self, own: Expansion) -> None:
        super().__init__(own.expansion, own.alpha)
        self.own = own

    def expand(self, s: MPGPSolve, t_cg: float, t_f: float, gp: float, pAp: float,
               positive: bool) -> bool:
        """The projected Galerkin step (``counts['galerkin']``), or the variant's own.

        Each try is recorded in the store (:meth:`.recycle.Recycle.projected`), whose record
        decides whether the next expansions try it (:meth:`.recycle.Recycle.project_pays`).
        """
        if math.isfinite(t_cg):
            kept = ProjectedCGExpansion.projected(s, t_cg, t_f, gp, pAp)
            s.recycle.projected(kept)
            if kept:
                s.counts["galerkin"] = s.counts.get("galerkin", 0) + 1
                return True
        return self.own.expand(s, t_cg, t_f, gp, pAp, positive)


#: Expansion variants by ``(expansion, alpha)``.
EXPANSIONS = {("fixed", "fixed"): Expansion, ("optimal", "fixed"): OptimalExpansion,
              ("projcg", "fixed"): ProjectedCGExpansion,
              ("fixed", "bb"): BarzilaiBorweinExpansion}


def expansion_of(name: str, expansion: str, alpha: str) -> Expansion:
    """The expansion step of the options ``expansion`` and ``alpha``.

    Raises:
        ValueError: For a combination that is not a variant (``alpha='bb'`` adapts the fixed
            step only).
    """
    if alpha != "fixed" and expansion != "fixed":
        raise ValueError(f"{name}: alpha={alpha!r} adapts the fixed-length expansion; it needs "
                         f"expansion='fixed', got {expansion!r}")
    return EXPANSIONS[expansion, alpha](expansion, alpha)


__all__ = ["EXPANSIONS", "BarzilaiBorweinExpansion", "Expansion", "GalerkinExpansion",
           "OptimalExpansion",
           "ProjectedCGExpansion", "expansion_of"]
