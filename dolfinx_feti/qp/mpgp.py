"""MPGP: one loop for MPRGP (bounds) and MPGP (bounds and discs), over a constraint set.

Minimizes ``f(x) = 1/2 x^T A x - b^T x`` over a product of simple convex sets: every entry of
``x`` lies in an interval ``l_i <= x_i <= u_i`` (infinite bounds allowed), except the entries
grouped in pairs by :class:`.discs.Discs`, each pair in a disc ``||(x_i, x_j) - c|| <= r`` (the
dual of 3D contact with Tresca friction). The set is an object (:class:`.box.Box` for bounds
alone, :class:`.discs.SeparableSet` with discs) with the operations the loop needs, as in
PERMON's QPC constraint sets. Sources: Dostál, *Optimal Quadratic Programming Algorithms*
(2009), chapter 5 (MPRGP); Dostál, Kozubek, Sadowská, Vondrák, *Scalable Algorithms for
Contact Problems* (2016), MPGP for separable convex constraints.

- a block (an entry, or a disc pair) is *active* when it lies on the boundary of its set, with
  outward unit normal n (for an entry at its lower bound n = -1, at its upper bound n = +1,
  for a disc pair n = (x - c)/||x - c||);
- free gradient φ = g on the blocks that are not active, 0 on the active ones;
- chopped gradient β = g - min(nᵀg, 0) n on the active blocks, 0 on the others; the projected
  gradient is gᴾ = φ + β and vanishes exactly at the solution;
- reduced free gradient φ̃ = (x - P(x - ᾱ φ))/ᾱ;
- proportional iterate (‖β‖² <= Γ² φ̃ᵀφ): a CG step in the face if it stays feasible, else an
  expansion: the largest feasible step along the CG direction, then a projected step;
- otherwise a proportioning step: the gradient projection ``x <- P(x - ᾱ g(x))`` (MPGP's; a
  line search along β leaves a curved boundary at once), or on a flat set (bounds only) the
  exact line search along β cut at the opposite bound of a box (MPRGP's, :func:`.mprgp.mprgp`).

On a flat set the expansion has variants (``expansion``, ``alpha``: see :func:`mpgp`); on a
curved set only the fixed-length one.

Curved faces (``face='tangent'``, the default; ``face='interior'`` is the algorithm above as
published). A disc pair on its circle whose gradient pushes it outwards (nᵀg <= 0) is at a
minimum in the normal direction and can only turn along the circle; with the plain definition
its tangential gradient counts in β, and only gradient projection steps of length ᾱ move it,
which converges slowly when many contact nodes slip (measured: 5–40× the frictionless number of
F-multiplications on the 3D blocks of ``demos/demo_tresca3d.py``). With ``'tangent'`` such a
pair belongs to the face: its tangential gradient counts in φ, the CG direction is kept
tangent to its circle, the step length is that of the model with the Hessian of the Lagrangian
on the circle, ``A + (ξ/r) I`` (ξ = −nᵀg the normal force; the exact second-order model of the
energy along the projected step), and the step ``x <- P(x - t p)`` goes along the circle (the
projection maps the tangent back to the circle). Such a step takes a fresh gradient (a second
multiplication) and is kept unless the energy increased beyond round-off, else a gradient
projection step follows. The expansion and proportioning steps and the stopping test are
unchanged (gᴾ = φ + β is the same vector). Measured: 3–6× fewer multiplications on the 3D
blocks (see docs/friction.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .box import Box, check_finite
from .discs import Discs, SeparableSet
from .precond import Preconditioner
from .result import QPResult
from .start import Counter, feasible_start, step_length

EXPANSIONS = ("fixed", "optimal", "projcg")
ALPHAS = ("fixed", "bb")
FACES = ("tangent", "interior")
# z^T phi below this fraction of ||z|| ||phi|| means that the preconditioned free gradient is
# no descent direction (M^{-1} singular or not positive there): the step falls back to phi.
_DESCENT_RTOL = 1e-12
# p^T A p below this fraction of ||A|| p^T p is treated as zero curvature: rounding makes the
# curvature of a PSD operator along a null direction tiny but positive, not zero.
_CURVATURE_RTOL = 1e-14
# A step along the circles is rejected when it raises the energy by more than this times
# Σ|x||g| (the round-off level of the energy differences).
_ENERGY_NOISE = 64 * np.finfo(float).eps


def mpgp(A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, *, lb=None, ub=None,
         discs: Discs | None = None, rtol: float = 1e-6, atol: float = 0.0, gamma: float = 1.0,
         alpha_bar: float | None = None, norm_A: float | None = None, expansion: str = "fixed",
         max_it: int = 10000, stop: Callable[[float, PETSc.Vec, PETSc.Vec], bool | None] | None
         = None, monitor: Callable[[int, float, str], None] | None = None,
         b_norm: float | None = None, g: PETSc.Vec | None = None, g_valid: bool = False,
         preconditioner=None, alpha: str = "fixed", face: str = "tangent",
         proportioning: str = "projection", name: str = "mpgp") -> QPResult:
    """Solve ``min 1/2 x^T A x - b^T x`` s.t. ``lb <= x <= ub`` and the discs (collective).

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

    With discs (a curved set) and ``face='tangent'`` the faces follow the circles (see the
    module docstring); ``face='interior'`` is the algorithm as published.

    Hessian multiplications: 1 for the initial gradient (0 when ``g_valid``), 1 per CG step (2
    when it turns disc pairs along their circles), 2 per expansion (3 when its first half turns
    pairs; ``'optimal'`` skips the second when ``phi(x_h) = 0``, a rejected ``'projcg'`` or
    ``'bb'`` step costs a third), 1 per proportioning step, 3 per rejected turning step
    (``counts['rejected']``) and its proportioning step, plus the norm estimate when neither
    ``alpha_bar`` nor ``norm_A`` is given.

    Args:
        A: Symmetric positive semidefinite operator (PETSc Mat).
        b: Linear term.
        x: Start; projected onto the set, then overwritten with the iterates (a monitor may
            read it).
        lb: Lower bound (Vec laid out like ``x``, scalar, or None for ``-inf``).
        ub: Upper bound (Vec, scalar, or None for ``+inf``); both infinite on disc entries.
        discs: :class:`.discs.Discs` on pairs of local entries, or None.
        rtol: Default stopping test ``||g^P|| <= max(rtol * b_norm, atol)``.
        atol: See ``rtol``.
        gamma: Proportioning parameter ``Gamma > 0``.
        alpha_bar: Projected step length in ``(0, 2/||A||)``; default ``1.95 / norm_A``.
        norm_A: ``||A||``; default :func:`.norm.estimate_norm` (Lanczos, rtol 1e-4).
        expansion: ``'fixed'``, ``'optimal'`` or ``'projcg'`` (the last two: bounds only).
        max_it: Maximum number of iterations (steps of any kind).
        stop: Extra test ``stop(gP_norm, x, g)``, collective; a true value ends the solve as
            converged (reason ``'stop'``). Used by SMALBE.
        monitor: Called as ``monitor(it, gP_norm, kind)`` at every iterate, ``kind`` being the
            step that produced it (``'init'``, ``'cg'``, ``'expansion'``, ``'proportioning'``).
        b_norm: Reference norm of the relative test; default ``||b||``.
        g: Optional Vec for the gradient: the final gradient ``A x - b`` is left in it.
        g_valid: ``g`` already holds ``A x - b`` for the given ``x``; saves the initial
            multiplication unless the projection of ``x`` onto the set moves it.
        preconditioner: Optional ``M^{-1}`` for the CG steps: a PETSc Mat or PC, an object with
            ``mult(x, y)`` or a callable ``f(x, y)`` (see :mod:`.precond`).
        alpha: Expansion step length rule, ``'fixed'`` or ``'bb'`` (needs
            ``expansion='fixed'``; bounds only).
        face: ``'tangent'`` or ``'interior'`` (with discs; see the module docstring).
        proportioning: ``'projection'`` (the gradient projection step, MPGP's; always on a
            curved set) or ``'line'`` (the exact line search along β, MPRGP's; bounds only).
        name: The solver's name in error messages.

    Returns:
        The result; ``counts`` has ``'rejected'`` for ``'projcg'`` and ``'bb'`` (and after a
        rejected turning step) and ``'precond'`` with a preconditioner. ``result.active`` marks
        the entries of the blocks on their boundary (both entries of a disc pair on its
        circle). Never raises for non-convergence: ``reason`` ``'max_it'`` (with the last
        iterate), ``'unbounded'`` (non-positive curvature along a descent direction that no
        bound stops) or ``'breakdown'`` (non-finite values appeared).

    Raises:
        ValueError: For infeasible/invalid bounds or discs, non-finite data, or invalid
            parameters.
    """
    comm = x.getComm().tompi4py()
    if expansion not in EXPANSIONS:
        raise ValueError(f"{name}: expansion must be one of {EXPANSIONS}, got {expansion!r}")
    if not gamma > 0 or rtol < 0 or atol < 0 or max_it < 0:
        raise ValueError(f"{name}: need gamma > 0 and non-negative rtol, atol, max_it")
    if alpha not in ALPHAS:
        raise ValueError(f"{name}: alpha must be one of {ALPHAS}, got {alpha!r}")
    if alpha != "fixed" and expansion != "fixed":
        raise ValueError(f"{name}: alpha={alpha!r} adapts the fixed-length expansion; it needs "
                         f"expansion='fixed', got {expansion!r}")
    if face not in FACES:
        raise ValueError(f"{name}: face must be 'tangent' or 'interior', got {face!r}")
    S = Box(lb, ub, x) if discs is None else SeparableSet(lb, ub, discs, x)
    curved = S.curved
    if curved and (expansion != "fixed" or alpha != "fixed"):
        raise ValueError(f"{name}: with discs only the fixed expansion is implemented, got "
                         f"expansion={expansion!r}, alpha={alpha!r}")
    if proportioning not in ("projection", "line"):
        raise ValueError(f"{name}: proportioning must be 'projection' or 'line', got "
                         f"{proportioning!r}")
    line_search = proportioning == "line" and not curved
    tangent = curved and face == "tangent"
    prec = None if preconditioner is None else Preconditioner(preconditioner)
    check_finite(comm, f"{name}: b", b.array_r)
    check_finite(comm, f"{name}: the start x", x.array_r)
    mult = Counter(A)
    counts = {"cg": 0, "expansion": 0, "proportioning": 0, "norm": 0}
    if expansion == "projcg" or alpha != "fixed":
        counts["rejected"] = 0
    if prec is not None:
        counts["precond"] = 0
    alpha_bar, scale_A = step_length(name, mult, x, counts, alpha_bar, norm_A)
    if b_norm is None:
        b_norm = b.norm()

    g = feasible_start(name, S.project, mult, x, b, g, g_valid, comm)

    phi, beta, p, Ap = x.duplicate(), x.duplicate(), x.duplicate(), x.duplicate()
    Hp = x.duplicate() if tangent else Ap  # (A + curvature) p on the circles
    z = phi if prec is None else x.duplicate()
    saved_g = g.duplicate() if alpha == "bb" else None  # g at the half-step (long steps)
    history: list[dict] = []
    it, kind, reason = 0, "init", "max_it"
    cg_pending = False  # p holds a CG direction to be continued (else restart from phi)
    pHp = 1.0
    n = x.getLocalSize()
    rot = np.zeros(n, dtype=bool)
    curv = np.zeros(n)
    while True:
        phi_a, beta_a, active = S.split(x.array_r, g.array_r)
        if tangent:  # pairs on their circle pushed outwards: their tangential part is free
            rot, curv = S.rotating(x.array_r, g.array_r)
            phi_a[rot] = beta_a[rot]
            beta_a[rot] = 0.0
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
        phit_a = S.reduced_free(x.array_r, phi_a, alpha_bar)
        phit_phi = comm.allreduce(float(np.dot(phit_a, phi_a)))
        proportional = beta2 <= gamma * gamma * phit_phi
        if proportional:
            fixed = active & ~rot  # entries that do not move in this face
            r = phi
            if prec is not None:
                # Preconditioning in face: z = D_F M^{-1} D_F phi (phi = D_F g already).
                prec.apply(phi, z)
                z.array[fixed] = 0.0
                if tangent:
                    z.array[:] = S.tangential(x.array_r, z.array_r, rot)
                if z.dot(phi) > _DESCENT_RTOL * math.sqrt(phi2 * z.dot(z)):
                    r = z
            if cg_pending:
                # Continue the conjugate direction: p = r - (r^T H p / p^T H p) p.
                p.aypx(-r.dot(Hp) / pHp, r)
                if tangent:  # the face: interior blocks and the tangents of rotating pairs
                    pa = S.tangential(x.array_r, p.array_r, rot)
                    pa[fixed] = 0.0
                    p.array[:] = pa
                if not g.dot(p) > 0.0:
                    r.copy(p)  # lost descent (face changed under rounding): restart
            else:
                r.copy(p)
            mult(p, Ap)
            if tangent:
                Hp.array[:] = Ap.array_r + curv * p.array_r
                moves = comm.allreduce(bool(np.any(p.array_r[rot] != 0.0)), op=MPI.LOR)
                pf = p.array_r.copy()
                pf[rot] = 0.0  # rotating pairs follow their circle: no limit on the step
            else:
                moves, pf = False, p.array_r
            pHp, gp = p.dot(Hp), g.dot(p)
            t_f = S.max_step(x.array_r, pf)
            positive = pHp > _CURVATURE_RTOL * scale_A * p.dot(p)
            t_cg = gp / pHp if positive else math.inf
            if t_cg <= t_f and math.isfinite(t_cg):
                if not moves:
                    x.array[:] = S.step(x.array_r, p.array_r, t_cg)
                    g.axpy(-t_cg, Ap)
                    kind, cg_pending = "cg", True
                    counts["cg"] += 1
                    continue
                if _turn(S, x, g, b, p, mult, t_cg, comm):
                    kind, cg_pending = "cg", True
                    counts["cg"] += 1
                    continue
                counts["rejected"] = counts.get("rejected", 0) + 1
                proportional = False  # fall back to a gradient projection step
            else:
                if not math.isfinite(t_f):
                    reason = "unbounded"
                    break
                if moves:
                    # Expansion: to the boundary along p (turning pairs), then a projected
                    # free-gradient step.
                    x.array[:] = S.step(x.array_r, p.array_r, t_f)
                    mult(x, g)
                    g.axpy(-1.0, b)
                    _expand(S, x, g, b, phi, p, Ap, mult, alpha_bar, "fixed", scale_A)
                    kind, cg_pending = "expansion", False
                    counts["expansion"] += 1
                    continue
                if expansion == "projcg" and math.isfinite(t_cg):
                    if _projected_cg_step(S, x, g, b, p, mult, t_cg, t_f, gp, pHp):
                        kind, cg_pending = "expansion", False
                        counts["expansion"] += 1
                        continue
                    counts["rejected"] += 1
                # Expansion: go to the boundary along p, then a projected step from there.
                x.array[:] = S.step(x.array_r, p.array_r, t_f)
                g.axpy(-t_f, Ap)
                if alpha == "bb" and positive:
                    # BB1 step of the secant pair (x - x_h, g - g_h) = t_f (p, A p): no product.
                    step = p.dot(p) / pHp
                    if step > alpha_bar:
                        saved_x = x.array_r.copy()  # the half-step
                        g.copy(saved_g)
                        if _long_step(S, x, g, b, mult, step):
                            kind, cg_pending = "expansion", False
                            counts["expansion"] += 1
                            continue
                        x.array[:] = saved_x  # the energy increased: back to the half-step
                        saved_g.copy(g)
                        counts["rejected"] += 1
                if not _expand(S, x, g, b, phi, p, Ap, mult, alpha_bar, expansion, scale_A):
                    reason = "unbounded"
                    break
                kind, cg_pending = "expansion", False
                counts["expansion"] += 1
                continue
        if not proportional:
            if not line_search:
                # Proportioning: the gradient projection step with the full g.
                x.array[:] = S.project(x.array_r - alpha_bar * g.array_r)
                mult(x, g)
                g.axpy(-1.0, b)
            else:
                # Proportioning: the exact line search along beta, cut at the opposite bound.
                mult(beta, Ap)
                bAb = beta.dot(Ap)
                t_f = S.max_step(x.array_r, beta.array_r)
                positive = bAb > _CURVATURE_RTOL * scale_A * beta2
                t = min(beta2 / bAb if positive else math.inf, t_f)
                if not math.isfinite(t):
                    reason = "unbounded"
                    break
                x.array[:] = S.step(x.array_r, beta.array_r, t)
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


def _turn(S, x: PETSc.Vec, g: PETSc.Vec, b: PETSc.Vec, p: PETSc.Vec, mult: Counter,
          t: float, comm) -> bool:
    """A CG step that turns disc pairs along their circles: x <- P(x - t p), fresh gradient.

    Kept unless the energy increased: f(x1) - f(x0) = ½ (x1 - x0)ᵀ(g0 + g1) for a quadratic,
    without the cancellation of f(x1) - f(x0); the rounding of x on the circles, where g is
    large, moves f by ~ eps Σ|x||g|: tolerated. On rejection x and g are restored.
    """
    x0, g0 = x.array_r.copy(), g.copy()
    x.array[:] = S.step(x.array_r, p.array_r, t)
    mult(x, g)
    g.axpy(-1.0, b)
    xa, ga = x.array_r, g.array_r
    df, noise = comm.allreduce(np.array([
        0.5 * float(np.dot(xa - x0, g0.array_r + ga)),
        float(np.abs(x0) @ np.abs(g0.array_r) + np.abs(xa) @ np.abs(ga))]))
    if df <= _ENERGY_NOISE * noise:
        g0.destroy()
        return True
    x.array[:] = x0
    g0.copy(g)
    g0.destroy()
    return False


def _expand(S, x: PETSc.Vec, g: PETSc.Vec, b: PETSc.Vec, phi: PETSc.Vec, d: PETSc.Vec,
            Ad: PETSc.Vec, mult: Counter, alpha_bar: float, expansion: str,
            scale_A: float) -> bool:
    """Projected gradient step from the half-step ``x`` (updates ``x`` and ``g``).

    ``phi``, ``d`` and ``Ad`` are scratch. Returns False if the energy is unbounded below.
    """
    xa = x.array_r
    phi_a = S.split(xa, g.array_r)[0]
    if expansion != "optimal":  # 'fixed', and the fallback of a rejected 'projcg' step
        x.array[:] = S.project(xa - alpha_bar * phi_a)
        mult(x, g)
        g.axpy(-1.0, b)
        return True
    # 'optimal': exact line search on the feasible segment along the reduced free gradient.
    d.array[:] = S.reduced_free(xa, phi_a, alpha_bar)
    phi.array[:] = phi_a
    gd = phi.dot(d)  # = g^T d: d vanishes where phi does
    if gd <= 0.0:
        return True  # phi(x_h) = 0: x_h minimizes the face, nothing to expand
    mult(d, Ad)
    dAd = d.dot(Ad)
    t_max = S.max_step(xa, d.array_r)
    positive = dAd > _CURVATURE_RTOL * scale_A * d.dot(d)
    t = min(gd / dAd if positive else math.inf, t_max)
    if not math.isfinite(t):
        return False
    x.array[:] = S.step(xa, d.array_r, t)
    g.axpy(-t, Ad)
    return True


def _projected_cg_step(S, x: PETSc.Vec, g: PETSc.Vec, b: PETSc.Vec, p: PETSc.Vec,
                       mult: Counter, t_cg: float, t_f: float, gp: float, pAp: float) -> bool:
    """Try the projected full CG step ``x <- P(x - t_cg p)`` with a fresh gradient.

    It is kept if its energy is not above that of the half-step ``x - t_f p`` (known from
    scalars); otherwise ``x`` and ``g`` are restored and False is returned.
    """
    f_half = 0.5 * (x.dot(g) - x.dot(b)) - t_f * gp + 0.5 * t_f * t_f * pAp
    x_old, g_old = x.array_r.copy(), g.copy()
    x.array[:] = S.project(x_old - t_cg * p.array_r)
    mult(x, g)
    g.axpy(-1.0, b)
    if 0.5 * (x.dot(g) - x.dot(b)) <= f_half:
        return True
    x.array[:] = x_old
    g_old.copy(g)
    return False


def _long_step(S, x: PETSc.Vec, g: PETSc.Vec, b: PETSc.Vec, mult: Counter,
               step: float) -> bool:
    """Try ``x <- P(x_h - step phi(x_h))`` from the half-step ``x_h`` with a fresh gradient.

    Returns whether the energy did not increase; ``x`` and ``g`` hold the trial point either
    way (the caller restores the half-step on False).
    """
    xa = x.array_r
    f_h = 0.5 * (x.dot(g) - x.dot(b))
    phi_a = S.split(xa, g.array_r)[0]
    x.array[:] = S.project(xa - step * phi_a)
    mult(x, g)
    g.axpy(-1.0, b)
    return 0.5 * (x.dot(g) - x.dot(b)) <= f_h
