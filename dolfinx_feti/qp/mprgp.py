"""MPRGP: modified proportioning with reduced gradient projections (Dostál) for box constraints.

Minimizes ``f(x) = 1/2 x^T A x - b^T x`` subject to ``l <= x <= u`` (infinite bounds allowed) for
a symmetric positive (semi)definite ``A``. See ALGORITHMS.md section 4 and Dostál, *Optimal
Quadratic Programming Algorithms* (2009), chapter 5. Three expansion steps are available:
the standard fixed-length one and two variants measured against it (``'optimal'``,
``'projcg'``); the fixed-length one can take an adaptive (Barzilai-Borwein) length
(``alpha='bb'``); the CG steps can be preconditioned in face. See :func:`mprgp`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from petsc4py import PETSc

from ..validation import Choice, Option, OptionSet, Real
from .box import Box, check_finite
from .precond import Preconditioner
from .result import QPResult
from .start import Counter, feasible_start, step_length

EXPANSIONS = ("fixed", "optimal", "projcg")
ALPHAS = ("fixed", "bb")

#: MPRGP's options (also those of MPGP): ``-feti_mprgp_<name>``, ``SolverOptions.mprgp_<name>``.
OPTIONS = OptionSet(
    "mprgp", "MPRGP (bounds) and MPGP (bounds and discs), alone or as SMALBE's inner solver",
    gamma=Option(1.0, Real(gt=0), "the proportioning parameter Γ"),
    expansion=Option("fixed", Choice(*EXPANSIONS), "the expansion step: 'fixed', 'optimal' or "
                     "'projcg' (see mprgp())"),
    alpha=Option("fixed", Choice(*ALPHAS), "the expansion step length: 'fixed' (1.95/||A||) or "
                 "'bb' (Barzilai–Borwein, kept only if the energy decreases; needs expansion "
                 "'fixed')"))
# z^T phi below this fraction of ||z|| ||phi|| means that the preconditioned free gradient is
# no descent direction (M^{-1} singular or not positive there): the step falls back to phi.
_DESCENT_RTOL = 1e-12
# p^T A p below this fraction of ||A|| p^T p is treated as zero curvature: rounding makes the
# curvature of a PSD operator along a null direction tiny but positive, not zero.
_CURVATURE_RTOL = 1e-14


def mprgp(A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, *, lb=None, ub=None, rtol: float = 1e-6,
          atol: float = 0.0, gamma: float = 1.0, alpha_bar: float | None = None,
          norm_A: float | None = None, expansion: str = "fixed", max_it: int = 10000,
          stop: Callable[[float, PETSc.Vec, PETSc.Vec], bool | None] | None = None,
          monitor: Callable[[int, float, str], None] | None = None,
          b_norm: float | None = None, g: PETSc.Vec | None = None,
          g_valid: bool = False, preconditioner=None, alpha: str = "fixed") -> QPResult:
    """Solve ``min 1/2 x^T A x - b^T x`` s.t. ``lb <= x <= ub`` by MPRGP (collective).

    Each iteration splits the gradient ``g = A x - b`` into the free gradient ``phi`` and the
    chopped gradient ``beta`` (``g^P = phi + beta``) and, with the reduced free gradient
    ``phi~`` (the part of ``phi`` that keeps ``x - alpha_bar phi~`` feasible):

    - if ``||beta||^2 <= gamma^2 phi~^T phi`` (proportional): a CG step along ``p`` if the full
      step is feasible; otherwise an *expansion*: the largest feasible step along ``p``, then a
      projected gradient step from that point, and ``p`` restarts from ``phi``;
    - otherwise a *proportioning* step along ``beta`` with the exact line search (cut at the
      opposite bound of a box), and ``p`` restarts.

    Expansion variants (``expansion``):

    - ``'fixed'``: ``x <- P(x_h - alpha_bar phi(x_h))`` and a fresh ``g = A x - b``.
    - ``'optimal'``: exact line search along ``d = phi~(x_h)`` over its whole feasible segment
      ``[0, t_max]`` (``t_max >= alpha_bar``; ``x_h - alpha_bar d`` is the fixed step), so the
      energy decreases at least as much as with ``'fixed'``; ``g`` is updated with ``A d``.
    - ``'projcg'``: the projected full CG step ``P(x - t_cg p)`` with a fresh gradient, kept if
      its energy is not above that of the half-step ``x_h``; otherwise (counted in
      ``counts['rejected']``) the ``'fixed'`` expansion is done from ``x_h``.

    Adaptive expansion length (``alpha``, with ``expansion='fixed'``):

    - ``'fixed'`` (default): the step ``alpha_bar`` of the theory, ``(0, 2/||A||]``.
    - ``'bb'``: the long Barzilai-Borwein step ``alpha_BB = p^T p / p^T A p`` of the secant pair
      of the feasible half-step (``x_h - x = -t_f p``, ``g_h - g = -t_f A p``), i.e. the
      reciprocal curvature of ``A`` along the direction that just hit the boundary, known
      without a multiplication. If ``alpha_BB > alpha_bar`` the expansion tries
      ``x <- P(x_h - alpha_BB phi(x_h))`` and keeps it if ``f`` did not increase (``f`` from
      the fresh gradient, two dot products); otherwise it restores ``x_h`` and makes the
      ``'fixed'`` step (``counts['rejected']``, one extra multiplication). If
      ``alpha_BB <= alpha_bar`` it is the ``'fixed'`` step. The proportioning test and the
      reduced free gradient keep ``alpha_bar``. Sources: Barzilai & Borwein, IMA J. Numer.
      Anal. 8 (1988) 141-148; the ``'bb'`` expansion step length of PERMON's MPGP
      (``-qps_mpgp_expansion_length_type bb``, permon/permon PR #56, Kruzik et al., *Active
      set expansion strategies in MPRGP algorithm*, Adv. Eng. Softw. 2020). Departure from
      the theory: an accepted ``alpha_BB`` exceeds ``2/||A||`` (``alpha_BB >= 1/||A||``
      always), so Dostal's R-linear rate bound, proved for ``alpha_bar`` in ``(0, 2/||A||]``,
      no longer covers those steps; the safeguard keeps ``f`` non-increasing over all steps.
      (The seed credits an adaptive ``alpha_bar`` to M. Lesoinne; no description of that
      strategy was found, so this is not claimed to be it.)

    Preconditioning in face (``preconditioner`` ``M^{-1}``, an approximate inverse of ``A``,
    symmetric positive (semi)definite): every iteration that passes the proportioning test
    computes ``z = D_F M^{-1} D_F phi`` (``D_F`` the 0/1 mask of the free entries; ``phi`` is
    already zero off ``F``) and uses ``z`` in place of ``phi`` in the CG direction:
    ``p = z`` after an expansion or proportioning step (restart), else
    ``p = z - (z^T A p / p^T A p) p``. The step length along ``p`` is the exact
    ``g^T p / p^T A p`` and the largest feasible step is computed along ``p`` as before, so
    this is PCG on the face with the preconditioner ``(M^{-1})_FF`` (the "approximate"
    preconditioning in face of Kruzik & Horak, arXiv:2507.00617: ``M^{-1}`` is built once,
    only masked). The proportioning test, the expansion and proportioning steps and the
    stopping test use the *un*preconditioned ``g``, ``phi``, ``beta``. Iterates stay
    feasible: ``p`` is only ever used through the feasible step length / the projection.
    ``p`` is a descent direction because ``g^T z = phi^T M^{-1} phi > 0``; where
    ``z^T phi <= 1e-12 ||z|| ||phi||`` (``M^{-1}`` singular there) that step uses ``phi``.
    One application per such iteration (``counts['precond']``); no Hessian product is added.

    Hessian multiplications: 1 for the initial gradient (0 when ``g_valid``), 1 per CG step,
    2 per expansion (``A p`` for the trial CG step, then the projected step; ``'optimal'``
    skips the second when ``phi(x_h) = 0``, a rejected ``'projcg'`` or ``'bb'`` step costs a
    third), 1 per proportioning, plus the norm estimate when neither ``alpha_bar`` nor
    ``norm_A`` is given.

    Args:
        A: Symmetric positive semidefinite operator (PETSc Mat).
        b: Linear term.
        x: Start; projected onto the box, then overwritten with the iterates (a monitor may
            read it).
        lb: Lower bound (Vec laid out like ``x``, scalar, or None for ``-inf``).
        ub: Upper bound (Vec, scalar, or None for ``+inf``).
        rtol: Default stopping test ``||g^P|| <= max(rtol * b_norm, atol)``.
        atol: See ``rtol``.
        gamma: Proportioning parameter ``Gamma > 0``.
        alpha_bar: Projected step length in ``(0, 2/||A||)``; default ``1.95 / norm_A``.
        norm_A: ``||A||``; default :func:`estimate_norm` (Lanczos, rtol 1e-4).
        expansion: ``'fixed'``, ``'optimal'`` or ``'projcg'``.
        max_it: Maximum number of iterations (steps of any kind).
        stop: Extra test ``stop(gP_norm, x, g)``, collective; a true value ends the solve as
            converged (reason ``'stop'``). Used by SMALBE.
        monitor: Called as ``monitor(it, gP_norm, kind)`` at every iterate, ``kind`` being the
            step that produced it (``'init'``, ``'cg'``, ``'expansion'``, ``'proportioning'``).
        b_norm: Reference norm of the relative test; default ``||b||``.
        g: Optional Vec for the gradient: the final gradient ``A x - b`` is left in it.
        g_valid: ``g`` already holds ``A x - b`` for the given ``x``; saves the initial
            multiplication unless the projection of ``x`` onto the box moves it.
        preconditioner: Optional ``M^{-1}`` for the CG steps: a PETSc Mat or PC, an object with
            ``mult(x, y)`` or a callable ``f(x, y)`` (see :mod:`.precond`).
        alpha: Expansion step length rule, ``'fixed'`` or ``'bb'`` (needs
            ``expansion='fixed'``).

    Returns:
        The result; ``counts`` has ``'rejected'`` for ``'projcg'`` and ``'bb'`` and
        ``'precond'`` with a preconditioner. Never raises for non-convergence: ``reason``
        ``'max_it'`` (with the last iterate), ``'unbounded'`` (non-positive curvature along a
        descent direction that no bound stops) or ``'breakdown'`` (non-finite values
        appeared).

    Raises:
        ValueError: For infeasible/invalid bounds, non-finite data, or invalid parameters.
    """
    comm = x.getComm().tompi4py()
    if expansion not in EXPANSIONS:
        raise ValueError(f"mprgp: expansion must be one of {EXPANSIONS}, got {expansion!r}")
    if not gamma > 0 or rtol < 0 or atol < 0 or max_it < 0:
        raise ValueError("mprgp: need gamma > 0 and non-negative rtol, atol, max_it")
    if alpha not in ALPHAS:
        raise ValueError(f"mprgp: alpha must be one of {ALPHAS}, got {alpha!r}")
    if alpha != "fixed" and expansion != "fixed":
        raise ValueError(f"mprgp: alpha={alpha!r} adapts the fixed-length expansion; it needs "
                         f"expansion='fixed', got {expansion!r}")
    prec = None if preconditioner is None else Preconditioner(preconditioner)
    box = Box(lb, ub, x)
    check_finite(comm, "mprgp: b", b.array_r)
    check_finite(comm, "mprgp: the start x", x.array_r)
    mult = Counter(A)
    counts = {"cg": 0, "expansion": 0, "proportioning": 0, "norm": 0}
    if expansion == "projcg" or alpha != "fixed":
        counts["rejected"] = 0
    if prec is not None:
        counts["precond"] = 0
    alpha_bar, scale_A = step_length("mprgp", mult, x, counts, alpha_bar, norm_A)
    if b_norm is None:
        b_norm = b.norm()

    g = feasible_start("mprgp", box.project, mult, x, b, g, g_valid, comm)

    phi, beta, p, Ap = x.duplicate(), x.duplicate(), x.duplicate(), x.duplicate()
    z = phi if prec is None else x.duplicate()
    saved_g = g.duplicate() if alpha == "bb" else None  # g at the half-step (long steps)
    history: list[dict] = []
    it, kind, reason = 0, "init", "max_it"
    cg_pending = False  # p holds a CG direction to be continued (else restart from phi)
    pAp = 1.0
    while True:
        phi_a, beta_a, active = box.split(x.array_r, g.array_r)
        phi.array[:] = phi_a
        beta.array[:] = beta_a
        phi2, beta2 = phi.dot(phi), beta.dot(beta)
        gP = math.sqrt(phi2 + beta2)
        history.append({"it": it, "kind": kind, "gP": gP})
        if monitor is not None:
            monitor(it, gP, kind)
        if not math.isfinite(gP):
            reason = "breakdown"
            break
        if gP <= max(rtol * b_norm, atol):
            reason = "rtol" if rtol * b_norm >= atol else "atol"
            break
        if stop is not None and stop(gP, x, g):
            reason = "stop"
            break
        if it >= max_it:
            reason = "max_it"
            break
        it += 1
        phit_a = box.reduced_free(x.array_r, phi_a, alpha_bar)
        phit_phi = comm.allreduce(float(np.dot(phit_a, phi_a)))
        if beta2 <= gamma * gamma * phit_phi:
            r = phi
            if prec is not None:
                # Preconditioning in face: z = D_F M^{-1} D_F phi (phi = D_F g already).
                prec.apply(phi, z)
                z.array[active] = 0.0
                zphi = z.dot(phi)
                if zphi > _DESCENT_RTOL * math.sqrt(phi2 * z.dot(z)):
                    r = z
            if cg_pending:
                # Continue the conjugate direction: p = r - (r^T A p / p^T A p) p.
                p.aypx(-r.dot(Ap) / pAp, r)
                if not g.dot(p) > 0.0:
                    r.copy(p)  # lost descent (face changed under rounding): restart
            else:
                r.copy(p)
            mult(p, Ap)
            pAp, gp = p.dot(Ap), g.dot(p)
            t_f = box.max_step(x.array_r, p.array_r)
            positive = pAp > _CURVATURE_RTOL * scale_A * p.dot(p)
            t_cg = gp / pAp if positive else math.inf
            if t_cg <= t_f and math.isfinite(t_cg):
                x.array[:] = box.step(x.array_r, p.array_r, t_cg)
                g.axpy(-t_cg, Ap)
                kind, cg_pending = "cg", True
                counts["cg"] += 1
                continue
            if not math.isfinite(t_f):
                reason = "unbounded"
                break
            if expansion == "projcg" and math.isfinite(t_cg):
                if _projected_cg_step(box, x, g, b, p, mult, t_cg, t_f, gp, pAp):
                    kind, cg_pending = "expansion", False
                    counts["expansion"] += 1
                    continue
                counts["rejected"] += 1
            # Expansion: go to the boundary along p, then a projected step from there.
            x.array[:] = box.step(x.array_r, p.array_r, t_f)
            g.axpy(-t_f, Ap)
            if alpha == "bb" and positive:
                # BB1 step of the secant pair (x - x_h, g - g_h) = t_f (p, A p): no product.
                step = p.dot(p) / pAp
                if step > alpha_bar:
                    saved_x = x.array_r.copy()  # the half-step
                    g.copy(saved_g)
                    if _long_step(box, x, g, b, mult, step):
                        kind, cg_pending = "expansion", False
                        counts["expansion"] += 1
                        continue
                    x.array[:] = saved_x  # the energy increased: back to the half-step
                    saved_g.copy(g)
                    counts["rejected"] += 1
            if not _expand(box, x, g, b, phi, p, Ap, mult, alpha_bar, expansion, scale_A):
                reason = "unbounded"
                break
            kind, cg_pending = "expansion", False
            counts["expansion"] += 1
        else:
            mult(beta, Ap)
            bAb = beta.dot(Ap)
            t_f = box.max_step(x.array_r, beta.array_r)
            positive = bAb > _CURVATURE_RTOL * scale_A * beta2
            t = min(beta2 / bAb if positive else math.inf, t_f)
            if not math.isfinite(t):
                reason = "unbounded"
                break
            x.array[:] = box.step(x.array_r, beta.array_r, t)
            g.axpy(-t, Ap)
            kind, cg_pending = "proportioning", False
            counts["proportioning"] += 1

    if prec is not None:
        counts["precond"] = prec.count
    active_count = comm.allreduce(int(np.count_nonzero(active)))
    objective = 0.5 * (x.dot(g) - x.dot(b))  # f = 1/2 x^T (A x - b) - 1/2 b^T x
    return QPResult(x=x, converged=reason in ("rtol", "atol", "stop"), reason=reason,
                    iterations=it, hessian_mults=mult.n, counts=counts, gP_norm=gP,
                    b_norm=b_norm, active=active, active_count=active_count, history=history,
                    objective=objective)


def _expand(box: Box, x: PETSc.Vec, g: PETSc.Vec, b: PETSc.Vec, phi: PETSc.Vec, d: PETSc.Vec,
            Ad: PETSc.Vec, mult: Counter, alpha_bar: float, expansion: str,
            scale_A: float) -> bool:
    """Projected gradient step from the half-step ``x`` (updates ``x`` and ``g``).

    ``phi``, ``d`` and ``Ad`` are scratch. Returns False if the energy is unbounded below.
    """
    xa = x.array_r
    phi_a = box.split(xa, g.array_r)[0]
    if expansion != "optimal":  # 'fixed', and the fallback of a rejected 'projcg' step
        x.array[:] = box.project(xa - alpha_bar * phi_a)
        mult(x, g)
        g.axpy(-1.0, b)
        return True
    # 'optimal': exact line search on the feasible segment along the reduced free gradient.
    d.array[:] = box.reduced_free(xa, phi_a, alpha_bar)
    phi.array[:] = phi_a
    gd = phi.dot(d)  # = g^T d: d vanishes where phi does
    if gd <= 0.0:
        return True  # phi(x_h) = 0: x_h minimizes the face, nothing to expand
    mult(d, Ad)
    dAd = d.dot(Ad)
    t_max = box.max_step(xa, d.array_r)
    positive = dAd > _CURVATURE_RTOL * scale_A * d.dot(d)
    t = min(gd / dAd if positive else math.inf, t_max)
    if not math.isfinite(t):
        return False
    x.array[:] = box.step(xa, d.array_r, t)
    g.axpy(-t, Ad)
    return True


def _projected_cg_step(box: Box, x: PETSc.Vec, g: PETSc.Vec, b: PETSc.Vec, p: PETSc.Vec,
                       mult: Counter, t_cg: float, t_f: float, gp: float, pAp: float) -> bool:
    """Try the projected full CG step ``x <- P(x - t_cg p)`` with a fresh gradient.

    It is kept if its energy is not above that of the half-step ``x - t_f p`` (known from
    scalars); otherwise ``x`` and ``g`` are restored and False is returned.
    """
    f_half = 0.5 * (x.dot(g) - x.dot(b)) - t_f * gp + 0.5 * t_f * t_f * pAp
    x_old, g_old = x.array_r.copy(), g.copy()
    x.array[:] = box.project(x_old - t_cg * p.array_r)
    mult(x, g)
    g.axpy(-1.0, b)
    if 0.5 * (x.dot(g) - x.dot(b)) <= f_half:
        return True
    x.array[:] = x_old
    g_old.copy(g)
    return False


def _long_step(box: Box, x: PETSc.Vec, g: PETSc.Vec, b: PETSc.Vec, mult: Counter,
               step: float) -> bool:
    """Try ``x <- P(x_h - step phi(x_h))`` from the half-step ``x_h`` with a fresh gradient.

    Returns whether the energy did not increase; ``x`` and ``g`` hold the trial point either
    way (the caller restores the half-step on False).
    """
    xa = x.array_r
    f_h = 0.5 * (x.dot(g) - x.dot(b))
    phi_a = box.split(xa, g.array_r)[0]
    x.array[:] = box.project(xa - step * phi_a)
    mult(x, g)
    g.axpy(-1.0, b)
    return 0.5 * (x.dot(g) - x.dot(b)) <= f_h
