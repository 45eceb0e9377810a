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
  exact line search along β cut at the opposite bound of a box (MPRGP's, :class:`.mprgp.MPRGP`).

On a flat set the expansion has variants (``expansion``, ``alpha``: see :class:`MPGP`,
:mod:`.expansion`); on a
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

from collections.abc import Callable
from typing import ClassVar

from petsc4py import PETSc

from ..validation import Choice, Flag, Integer, Option, OptionSet, Real
from .discs import Discs
from .expansion import GalerkinExpansion, ProjectedCGExpansion, expansion_of
from .mpgp_steps import MPGPSolve
from .problem import QP
from .recycle import Recycle
from .result import QPResult
from .solver import QPSolver

EXPANSIONS = ("fixed", "optimal", "projcg")
ALPHAS = ("fixed", "bb")
FACES = ("tangent", "interior")
PROPORTIONINGS = ("projection", "line")
PRECONDITIONINGS = ("face", "none")

#: MPRGP's options (also those of MPGP): ``-feti_mprgp_<name>``, ``SolverOptions.mprgp_<name>``.
OPTIONS = OptionSet(
    "mprgp", "MPRGP (bounds) and MPGP (bounds and discs), alone or as SMALBE's inner solver",
    gamma=Option(1.0, Real(gt=0), "the proportioning parameter Γ"),
    expansion=Option("fixed", Choice(*EXPANSIONS), "the expansion step: 'fixed', 'optimal' or "
                     "'projcg' (see mprgp())"),
    alpha=Option("fixed", Choice(*ALPHAS), "the expansion step length: 'fixed' (1.95/||A||) or "
                 "'bb' (Barzilai–Borwein, kept only if the energy decreases; needs expansion "
                 "'fixed')"),
    reuse=Option(80, Integer(ge=0, le=10**4), "Krylov recycling: keep the last k CG directions "
                 "and their products, and start each solve and face on the same operator by the "
                 "Galerkin step on them (0: off; see qp.recycle)"),
    deflate=Option(True, Flag(), "with reuse: keep the CG directions A-conjugate to the "
                   "recycled ones (deflated CG)"),
    project=Option(True, Flag(), "with reuse: an expansion in a face started by the Galerkin "
                   "step on the recycled directions first tries the projected Galerkin step "
                   "(qp.expansion.GalerkinExpansion)"),
    carry=Option(True, Flag(), "with reuse: a FetiSolver's row update of the same layout (a "
                 "moving curved obstacle) keeps the recycled directions as stale pairs of the "
                 "old operator if one product shows a small change (qp.recycle.Recycle.carry); "
                 "false: cleared"))


class MPGP(QPSolver):
    """MPGP for ``min 1/2 x^T A x - b^T x`` over bounds and discs, set up once (collective).

    Each iteration splits the gradient ``g = A x - b`` into the free gradient ``phi`` and the
    chopped gradient ``beta`` (``g^P = phi + beta``) and, with the reduced free gradient
    ``phi~`` (the part of ``phi`` that keeps ``x - alpha_bar phi~`` feasible):

    - if ``||beta||^2 <= gamma^2 phi~^T phi`` (proportional): a CG step along ``p`` if the full
      step is feasible; otherwise an *expansion*: the largest feasible step along ``p``, then a
      projected gradient step from that point, and ``p`` restarts from ``phi``;
    - otherwise a *proportioning* step (``proportioning``), and ``p`` restarts.

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

    Preconditioning in face (``preconditioning='face'``, with the QP's ``preconditioner``
    ``M^{-1}``, an approximate inverse of ``A``, symmetric positive (semi)definite): every
    iteration that passes the proportioning test computes ``z = D_F M^{-1} D_F phi`` (``D_F``
    the 0/1 mask of the free entries; ``phi`` is already zero off ``F``) and uses ``z`` in place
    of ``phi`` in the CG direction: ``p = z`` after an expansion or proportioning step
    (restart), else ``p = z - (z^T A p / p^T A p) p``. The step length along ``p`` is the exact
    ``g^T p / p^T A p`` and the largest feasible step is computed along ``p`` as before, so this
    is PCG on the face with the preconditioner ``(M^{-1})_FF`` (the "approximate"
    preconditioning in face of Kruzik & Horak, arXiv:2507.00617: ``M^{-1}`` is built once, only
    masked). The proportioning test, the expansion and proportioning steps and the stopping test
    use the *un*preconditioned ``g``, ``phi``, ``beta``. Iterates stay feasible: ``p`` is only
    ever used through the feasible step length / the projection. ``p`` is a descent direction
    because ``g^T z = phi^T M^{-1} phi > 0``; where ``z^T phi <= 1e-12 ||z|| ||phi||``
    (``M^{-1}`` singular there) that step uses ``phi``.
    One application per such iteration (``counts['precond']``); no Hessian product is added.

    With discs (a curved set) and ``face='tangent'`` the faces follow the circles (see the
    module docstring); ``face='interior'`` is the algorithm as published.

    Hessian multiplications: 1 for the initial gradient (0 when ``g_valid``), 1 per CG step (2
    when it turns disc pairs along their circles and the product with their pull-back onto the
    circles cannot be deferred, ``mpgp_steps.DRIFT_RTOL``; 1 more before a stopping test is
    passed with products deferred), 2 per expansion (3 when its first half turns pairs;
    ``'optimal'`` skips the second when ``phi(x_h) = 0``, a rejected ``'projcg'`` or ``'bb'``
    step or projected Galerkin step costs a third), 1 per proportioning step, 2–3 per
    rejected turning step (``counts['rejected']``) and its proportioning step, plus the norm
    estimate when neither ``alpha_bar`` nor ``norm_A`` is given.

    The variants (expansion, its length, proportioning, faces, preconditioning) are chosen
    when the solver is made; :meth:`solve` takes any QP without equality constraints
    (:class:`.problem.QP`: its ``constraints``, ``norm_A`` and ``preconditioner``).

    Args:
        rtol: Default stopping test ``||g^P|| <= max(rtol * b_norm, atol)``.
        atol: See ``rtol``.
        max_it: Maximum number of iterations (steps of any kind).
        gamma: Proportioning parameter ``Gamma > 0`` (option ``-<prefix>mprgp_gamma``).
        expansion: ``'fixed'``, ``'optimal'`` or ``'projcg'`` (the last two: bounds only;
            option ``-<prefix>mprgp_expansion``).
        alpha: Expansion step length rule, ``'fixed'`` or ``'bb'`` (needs
            ``expansion='fixed'``; bounds only; option ``-<prefix>mprgp_alpha``).
        alpha_bar: Projected step length in ``(0, 2/||A||)``; default ``1.95 / ||A||``.
        face: ``'tangent'`` or ``'interior'`` (with discs; see the module docstring).
        proportioning: ``'projection'`` (the gradient projection step, MPGP's; always on a
            curved set) or ``'line'`` (the exact line search along β, MPRGP's; bounds only).
            Default: the class's (``'projection'``; :class:`.mprgp.MPRGP`: ``'line'``).
        preconditioning: ``'face'`` (the QP's preconditioner, if it has one, in the CG steps
            of the face) or ``'none'`` (ignore it).
        monitor: Called as ``monitor(it, gP_norm, kind)`` at every iterate, ``kind`` being the
            step that produced it (``'init'``, ``'cg'``, ``'expansion'``, ``'proportioning'``).
        reuse: Krylov recycling (:mod:`.recycle`): keep the last ``reuse`` CG directions and
            their products across solves on one operator (option ``-<prefix>mprgp_reuse``;
            0: off).
        deflate: With ``reuse``: deflated CG in each face (``-<prefix>mprgp_deflate``).
        project: With ``reuse``: an expansion in a face that the Galerkin step on the
            recycled directions started first tries the projected Galerkin step over them and
            the face's CG directions (:class:`.expansion.GalerkinExpansion`;
            ``-<prefix>mprgp_project``).
        carry: With ``reuse``: whether the owner of the store keeps it across a small change
            of the operator (:meth:`.recycle.Recycle.carry`; ``-<prefix>mprgp_carry``): read
            by :class:`~dolfinx_feti.FetiSolver` at a row update; a caller of this solver
            that changes its operator calls ``recycle.carry()`` itself.
        recycle: A :class:`.recycle.Recycle` store to use (and keep) instead of a new one
            (e.g. one owned by a FETI solver across its solvers); its ``k`` and ``deflate``
            win over ``reuse`` and ``deflate``.
        options_prefix: Read the declared options (:data:`OPTIONS`) from PETSc's options
            database as ``-<options_prefix>mprgp_<name>`` (e.g. ``'feti_'``); keywords given
            here override them. None: the database is not read.

    Raises:
        ValueError: For an invalid option (an InputError naming it for the declared ones).
    """

    options: ClassVar[OptionSet] = OPTIONS
    name: ClassVar[str] = "mpgp"
    inner_capable: ClassVar[bool] = True
    #: The proportioning step unless one is given.
    default_proportioning: ClassVar[str] = "projection"

    def __init__(self, *, rtol: float = 1e-6, atol: float = 0.0, max_it: int = 10000,
                 gamma: float | None = None, expansion: str | None = None,
                 alpha: str | None = None, alpha_bar: float | None = None,
                 face: str = "tangent", proportioning: str | None = None,
                 preconditioning: str = "face",
                 monitor: Callable[[int, float, str], None] | None = None,
                 options_prefix: str | None = None, reuse: int | None = None,
                 deflate: bool | None = None, project: bool | None = None,
                 carry: bool | None = None, recycle: Recycle | None = None) -> None:
        name = self.name
        if expansion is not None and expansion not in EXPANSIONS:
            raise ValueError(f"{name}: expansion must be one of {EXPANSIONS}, got {expansion!r}")
        if rtol < 0 or atol < 0 or max_it < 0:
            raise ValueError(f"{name}: need gamma > 0 and non-negative rtol, atol, max_it")
        if alpha is not None and alpha not in ALPHAS:
            raise ValueError(f"{name}: alpha must be one of {ALPHAS}, got {alpha!r}")
        self._set_options(options_prefix, gamma=gamma, expansion=expansion, alpha=alpha,
                          reuse=reuse, deflate=deflate, project=project, carry=carry)
        #: The recycled directions (kept across solves on one operator), or None.
        self.recycle = recycle if recycle is not None else \
            Recycle(self.reuse, deflate=self.deflate) if self.reuse else None
        self.expansion_step = expansion_of(name, self.expansion, self.alpha)
        #: The expansion of a face started from the recycled directions: the projected
        #: Galerkin step first (:class:`.expansion.GalerkinExpansion`; 'projcg' tries it anyway).
        self.galerkin_expansion = GalerkinExpansion(self.expansion_step) \
            if self.recycle is not None and self.project and \
            not isinstance(self.expansion_step, ProjectedCGExpansion) else None
        if face not in FACES:
            raise ValueError(f"{name}: face must be 'tangent' or 'interior', got {face!r}")
        proportioning = proportioning or self.default_proportioning
        if proportioning not in PROPORTIONINGS:
            raise ValueError(f"{name}: proportioning must be 'projection' or 'line', got "
                             f"{proportioning!r}")
        if preconditioning not in PRECONDITIONINGS:
            raise ValueError(f"{name}: preconditioning must be one of {PRECONDITIONINGS}, got "
                             f"{preconditioning!r}")
        self.rtol, self.atol, self.max_it = rtol, atol, max_it
        self.alpha_bar, self.face, self.proportioning = alpha_bar, face, proportioning
        self.preconditioning, self.monitor = preconditioning, monitor

    def solve(self, qp: QP, x: PETSc.Vec, *,
              stop: Callable[[float, PETSc.Vec, PETSc.Vec], bool | None] | None = None,
              b_norm: float | None = None, g: PETSc.Vec | None = None, g_valid: bool = False,
              rtol: float | None = None, atol: float | None = None,
              max_it: int | None = None, test=None) -> QPResult:
        """Minimize ``qp`` from ``x`` (collective); the solver is unchanged and can solve again.

        Args:
            qp: The QP (no equality constraint: that is SMALBE's).
            x: Start; projected onto the set, then overwritten with the iterates (a monitor
                may read it).
            stop: Extra test ``stop(gP_norm, x, g)``, collective; a true value ends the solve
                as converged (reason ``'stop'``). Used by SMALBE.
            b_norm: Reference norm of the relative test; default ``||b||``.
            g: Optional Vec for the gradient: the final gradient ``A x - b`` is left in it.
            g_valid: ``g`` already holds ``A x - b`` for the given ``x``; saves the initial
                multiplication unless the projection of ``x`` onto the set moves it.
            rtol: This solve's ``rtol`` instead of the solver's (SMALBE's inner solves: 0).
            atol: Likewise ``atol``.
            max_it: Likewise ``max_it`` (SMALBE: what is left of its budget).
            test: A test of the projected gradient that replaces ``||g^P|| <= max(rtol
                b_norm, atol)`` (:class:`.stopping.MaxGradientTest`, or any collective
                ``test(gP_local, x) -> bool``); its success is reported as ``'rtol'``.

        Returns:
            The result; ``counts`` has ``'rejected'`` for ``'projcg'`` and ``'bb'`` (and after
            a rejected turning step or projected Galerkin step), ``'precond'`` with a
            preconditioner, and with recycling ``'recycle'`` (Galerkin steps) and
            ``'galerkin'`` (expansions by the projected Galerkin step).
            ``result.active`` marks the entries of the blocks on their boundary (both entries
            of a disc pair on its circle). Never raises for non-convergence: ``reason``
            ``'max_it'`` (with the last iterate), ``'unbounded'`` (non-positive curvature
            along a descent direction that no bound stops) or ``'breakdown'`` (non-finite
            values appeared); ``result.converged_reason`` is the signed code.

        Raises:
            ValueError: For an equality constraint, a variant the set does not allow,
                non-finite data or an invalid step length.
        """
        if qp.eq is not None:
            raise ValueError(f"{self.name}: the QP has an equality constraint; solve it by "
                             "SMALBE with this solver inside")
        run = MPGPSolve(self, qp, x, stop=stop, b_norm=b_norm, g=g, g_valid=g_valid,
                        rtol=self.rtol if rtol is None else rtol,
                        atol=self.atol if atol is None else atol,
                        max_it=self.max_it if max_it is None else max_it, test=test)
        return run.run()


def mpgp(A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec, *, lb=None, ub=None,
         discs: Discs | None = None, rtol: float = 1e-6, atol: float = 0.0, gamma: float = 1.0,
         alpha_bar: float | None = None, norm_A: float | None = None, expansion: str = "fixed",
         max_it: int = 10000, stop: Callable[[float, PETSc.Vec, PETSc.Vec], bool | None] | None
         = None, monitor: Callable[[int, float, str], None] | None = None,
         b_norm: float | None = None, g: PETSc.Vec | None = None, g_valid: bool = False,
         preconditioner=None, alpha: str = "fixed", face: str = "tangent",
         proportioning: str = "projection", name: str = "mpgp", reuse: int = 80,
         deflate: bool = True, project: bool = True, carry: bool = True) -> QPResult:
    """Solve ``min 1/2 x^T A x - b^T x`` s.t. ``lb <= x <= ub`` and the discs (collective).

    The function form of :class:`MPGP`: ``MPGP(...).solve(QP.create(A, b, lb=lb, ub=ub,
    discs=discs, norm_A=norm_A, preconditioner=preconditioner), x, ...)``; the arguments, the
    steps, the counts and the result are described there. ``name`` names the solver in error
    messages.
    """
    solver = MPGP(rtol=rtol, atol=atol, max_it=max_it, gamma=gamma, expansion=expansion,
                  alpha=alpha, alpha_bar=alpha_bar, face=face, proportioning=proportioning,
                  monitor=monitor, reuse=reuse, deflate=deflate, project=project,
                  carry=carry)
    solver.name = name
    qp = QP.create(A, b, lb=lb, ub=ub, discs=discs, norm_A=norm_A, preconditioner=preconditioner)
    return solver.solve(qp, x, stop=stop, b_norm=b_norm, g=g, g_valid=g_valid)


__all__ = ["ALPHAS", "EXPANSIONS", "FACES", "MPGP", "OPTIONS", "mpgp"]
