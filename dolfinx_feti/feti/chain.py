"""The FETI chain of one problem as a plain dual QP, and its way back.

:func:`chain_qp` factors the last system of a chain of primal transforms (eliminate Dirichlet,
eliminate corners), dualizes, homogenizes and projects; :class:`DualQP` is the result: the QP

    min 1/2 xᵀ A x − bᵀ x   s.t.   x ≥ lb on the inequality rows,   G̃ x = 0,

with ``A = P F P``, ``b = P (d − F λ̂)``, ``lb = −λ̂`` on the inequality rows, and the chain
that maps its solution back (:meth:`DualQP.map_back`) and applies itself to a new load case
(:meth:`DualQP.for_load`). Algebra only: the set-up that produces the first system from a
mesh is :mod:`dolfinx_feti.setup.stages`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import InputError
from ..qp import Projector, RowBlockConstraint, orthonormalize
from ..timing import Timer
from .dualize import Dualization
from .homogenize import Homogenize, Project
from .system import INEQUALITY, BlockSystem

#: A load component along a free rigid motion above this, relative to the size of the load
#: (:func:`_unbalanced`), means the load cannot be balanced (e ∉ Im G).
BALANCE_TOL = 1e-8
#: The secant predictor (:meth:`DualQP.secant_step`) needs the last step of d above this,
#: relative to d (else the same load twice) ...
SECANT_SEPARATION = 1e-10
#: ... and the new d within this of the line through the last two, relative to its step along
#: it (else the load changed its shape, and the scaled start is used).
SECANT_FIT = 0.1


@dataclass
class DualQP:
    """The homogenized, projected dual QP of one problem and the chain of transforms behind it.

    The chain is ``steps`` (the primal transforms: eliminate Dirichlet, eliminate corners),
    ``feti`` (dualize), ``hom`` (homogenize) and ``proj`` (project); each maps a solution of its
    child back (:meth:`map_back`). The QP itself: ``A``, ``b``, ``lb``, ``constraint``.

    Attributes:
        feti: The dual operators (``F``, ``B``, ``d``, ``e``, kernels, primal recovery) of the
            last primal problem of the chain.
        system: The Total FETI system of the problem (all rows; what the solution is checked
            against).
        steps: The primal transforms (eliminate Dirichlet, eliminate corners), in order.
        method: ``"tfeti"``, ``"feti1"`` or ``"fetidp"``.
        row_index: Local indices, into the rows of ``system`` owned by this rank, of the rows
            of this QP.
        hom: The homogenization (:class:`.feti.homogenize.Homogenize`: λ̂, the bounds).
        proj: The projection (:class:`.feti.homogenize.Project`: P, P F P, b, ‖P F P‖).
        ineq: Local mask of the inequality rows.
        warnings: Notes for the report (e.g. an unloaded rigid motion nothing fixes).
        info: Sizes of the method (e.g. FETI-DP's corners).
        dec: This rank's part of the decomposition (:class:`.share.LocalDecomposition`).
        rows: This rank's rows and the contact rows (:class:`.share.RankRows`).
        mortar: What the contact search found for each mortar condition
            (:class:`.constraints.mortar_rows.MortarInfo`).
        copy_weight: Per local entry of ``system``'s primal vector, 1 / the number of subdomain
            copies of its node (None: all ones).
        friction: The friction rows (:class:`.constraints.friction.FrictionData`) or None.
        share: What this rank holds of the problem (:class:`.share.RankShare`).
        surface: On a distributed mesh with contact, the cells along the contact surfaces
            gathered on rank 0 (:class:`.share_distributed.Surface`; None elsewhere).
    """

    feti: Dualization
    system: BlockSystem
    steps: list
    method: str
    row_index: np.ndarray
    hom: Homogenize
    proj: Project
    ineq: np.ndarray
    warnings: list[str]
    info: dict = field(default_factory=dict)
    dec: object = None
    rows: object = None
    mortar: list = field(default_factory=list)
    copy_weight: np.ndarray | None = None
    friction: object = None
    share: object = None
    surface: object = None

    # --- the QP --------------------------------------------------------------------------
    @property
    def constraint(self):
        """G̃ with orthonormal rows (:class:`.qp.equality.OrthonormalConstraint`)."""
        return self.hom.constraint

    @property
    def projector(self) -> Projector:
        """P = I − G̃ᵀG̃."""
        return self.proj.projector

    @property
    def A(self) -> PETSc.Mat:  # noqa: N802  (the QP's Hessian)
        """P F P."""
        return self.proj.A

    @property
    def b(self) -> PETSc.Vec:
        """P (d − F λ̂)."""
        return self.proj.b

    @property
    def lb(self) -> PETSc.Vec:
        """Lower bound of x: −λ̂ on the inequality rows, −inf elsewhere."""
        return self.hom.lb

    @property
    def lam_hat(self) -> PETSc.Vec:
        """The particular solution λ̂ of G λ = e."""
        return self.hom.lam_hat

    @property
    def norm_A(self) -> float:  # noqa: N802
        """The Lanczos estimate of ‖P F P‖."""
        return self.proj.norm_A

    @property
    def b_noise(self) -> float:
        """Round-off level of b (a floor for absolute tolerances)."""
        return self.hom.b_noise

    @property
    def primal(self):
        """The primal problem that was dualized (the last of the chain)."""
        return self.feti.primal

    def start(self, out: PETSc.Vec | None = None) -> PETSc.Vec:
        """A feasible start ``x = max(0, lb)`` (λ = λ̂ where that is feasible).

        Written into ``out`` if given, else into a new Vec.
        """
        x = self.b.duplicate() if out is None else out
        x.array[:] = np.maximum(0.0, self.lb.array_r)
        return x

    def warm_start(self, lam: PETSc.Vec, out: PETSc.Vec,
                   earlier: tuple[PETSc.Vec, PETSc.Vec, PETSc.Vec] | None = None,
                   gradient: PETSc.Vec | None = None) -> tuple[float, float | None, bool]:
        """A start near the multipliers ``lam`` of an earlier load case, feasible for the bounds.

        x = max(s·w, lb), w = P lam: the earlier homogenized solution scaled by s, where

        - s = (G lam)ᵀe / ‖G lam‖², the load factor along the coarse space (G lam is the old
          e), when the load acts on floating subdomains: for a proportional load with the
          same contact set the start is the new solution itself (λ = λ̂ + s·P lam = s·lam);
        - else (e = 0, so λ̂ = 0 and x = λ) the best multiple of lam for the new cost,
          s = bᵀw / wᵀAw (one multiplication by A).

        With the load case before ``lam``'s, ``earlier = (lam_before, d_before, d_last)`` (its
        multipliers, the ``d`` of both cases; the same rows), the start is the secant predictor
        x = max(P(lam + ω (lam − lam_before)), lb) instead (:meth:`secant_step`).

        ``gradient``: a Vec for the start's gradient A x − b, asked for by a QP solved without
        a coarse space (MPRGP alone, whose first product is that gradient). The product s
        needs is then that of the start: the scaled start's gradient is s·Aw − b (no product
        more), and a secant start multiplies the start itself instead of w, whose s only a
        coarse space's multiplier or friction's normal forces would use (s is then 1 + ω, the
        load factor of the secant step, reported only). Without a coarse space e = 0, so s
        is otherwise always the product's.

        Returns:
            The factor s, the secant's step ω (None: not used), for SMALBE's multiplier,
            which follows the load the same way, and whether ``gradient`` holds A x − b at the
            returned start.
        """
        omega = None if earlier is None else self.secant_step(earlier[1], earlier[2])
        have = False
        if omega is None or gradient is None:
            s, have = self._scaled(lam, out, gradient)
            have = have and omega is None
        else:
            s = 1.0 + omega
        if omega is not None:
            pred = lam.copy()
            pred.scale(1.0 + omega)
            pred.axpy(-omega, earlier[0])
            self.projector.apply(pred, out)
            pred.destroy()
        xa = out.array_r
        xp = np.maximum(xa, self.lb.array_r)
        moved = self.proj.b.getComm().tompi4py().allreduce(bool(np.any(xp != xa)), op=MPI.LOR)
        if moved:
            out.array[:] = xp
        if gradient is not None and (moved or not have):
            self.A.mult(out, gradient)  # the start's gradient: the product s did not need
            gradient.axpy(-1.0, self.b)
            have = True
        return s, omega, have

    def secant_step(self, d_before: PETSc.Vec, d_last: PETSc.Vec) -> float | None:
        """The step ω of the load along the last step, by the data: d ≈ d_last + ω Δd.

        ω = Δdᵀ(d − d_last) / ‖Δd‖², Δd = d_last − d_before: the step of the load measured by
        the right-hand side d = B K⁺ f − c of the three cases, so no parameter of the path is
        needed (ω = 1 for equal steps, 1.1 for steps growing by 10 %). The predictor
        λ_last + ω (λ_last − λ_before) is exact when λ is affine in the load on an unchanged
        contact set — the scaled start only for a proportional load — and from a growing
        contact set is off by the second difference (Hertz, 10 % steps: the A-norm error
        5e-3 to 1.5e-2 of the solution's against 3.5e-2 scaled). None when Δd is round-off
        (the same load twice) or the fit is poor (a load that changes its shape).
        """
        dd = d_last.copy()
        dd.axpy(-1.0, d_before)
        step = self.feti.d.copy()
        step.axpy(-1.0, d_last)
        dd2, proj = dd.dot(dd), dd.dot(step)
        fit = step.dot(step) - (proj * proj / dd2 if dd2 > 0 else 0.0)
        size = max(d_last.norm(), self.feti.d.norm())
        for v in (dd, step):
            v.destroy()
        if dd2 <= (SECANT_SEPARATION * size) ** 2 or fit > SECANT_FIT ** 2 * (proj * proj / dd2):
            return None
        return float(proj / dd2)

    def _scaled(self, lam: PETSc.Vec, out: PETSc.Vec, gradient: PETSc.Vec | None = None
                ) -> tuple[float, bool]:
        """``out`` ← s·P lam with the load factor s of :meth:`warm_start`.

        Returns s and whether ``gradient`` (if given) now holds A out − b: where s took a
        product (e = 0); else it is untouched.
        """
        have = False
        Glam = self.constraint.base.mult(lam)
        e = self.feti.e
        g2, e2 = float(Glam @ Glam), float(e @ e)
        self.projector.apply(lam, out)
        if e2 > 0 and g2 > 1e-24 * e2:
            s = max(float(Glam @ e) / g2, 0.0)
        else:
            Aw = out.duplicate()
            self.A.mult(out, Aw)
            curvature = float(Aw.dot(out))
            s = max(float(self.b.dot(out)) / curvature if curvature > 0 else 1.0, 0.0)
            if gradient is not None:
                Aw.copy(gradient)
                gradient.scale(s)
                gradient.axpy(-1.0, self.b)
                have = True
            Aw.destroy()
        out.scale(s)
        return s, have

    def multiplier_estimate(self, x: PETSc.Vec) -> np.ndarray:
        """The least-squares multiplier μ of G̃ x = 0 at ``x`` (one multiplication by ``A``).

        At a solution the gradient g = A x − b is balanced on the rows off the bound by the
        equality alone, g_F + (G̃ᵀμ)_F = 0 (the bound's multiplier lives on the rows at it), so
        μ = G̃ Gᵀa with (G_F G_Fᵀ) a = −G_F g_F over the rows F off the bound: the first-order
        estimate of augmented Lagrangian methods (Fletcher 1970; Bertsekas 1982). Exact at the
        solution; at a warm start it is the multiplier that start implies, so that SMALBE's
        first inner solve does not move x off G̃ x = 0 to undo a stale μ (Hertz, one 10 % load
        step: 0.8 % off against 14 % for the last μ scaled). Rigid motions all of whose rows
        are at the bound are left to the minimum-norm choice.
        """
        g = x.duplicate()
        self.A.mult(x, g)
        g.axpy(-1.0, self.b)
        lb = self.lb.array_r
        free = ~(np.isfinite(lb) & (x.array_r <= lb))
        base = self.constraint.base
        DF = RowBlockConstraint(base.Dt_local[np.flatnonzero(free)], base.comm)
        r = -base.comm.allreduce(DF.Dt_local.T @ g.array_r[free], op=MPI.SUM)
        a = orthonormalize(DF, rtol=1e-12).gram_solve(r)
        base.mult_transpose(a, g)  # Gᵀa: the G̃ᵀμ sought
        mu = self.constraint.mult(g)
        g.destroy()
        return mu

    def objective(self, x: PETSc.Vec) -> float:
        """``1/2 xᵀ A x − bᵀ x`` (one multiplication by ``A``; collective)."""
        y = x.duplicate()
        self.A.mult(x, y)
        value = 0.5 * y.dot(x) - self.b.dot(x)
        y.destroy()
        return float(value)

    def multipliers(self, x: PETSc.Vec) -> PETSc.Vec:
        """λ = λ̂ + x."""
        return self.hom.map_back(x, None)

    # --- the way back --------------------------------------------------------------------
    def free_motions(self, N: np.ndarray) -> np.ndarray:
        """The motions R n_k (columns of ``N``: coarse vectors) in the layout of ``system``."""
        Z = self.feti.R @ N
        for step in reversed(self.steps):
            Z = step.map_primal(Z)
        return Z

    def map_back(self, lam: PETSc.Vec, alpha: np.ndarray) -> tuple[PETSc.Vec, PETSc.Vec]:
        """(u, λ) of the original problem from the multipliers λ of this QP and α (collective).

        ``u`` is the primal solution subdomain by subdomain (Dirichlet values included), ``λ``
        the multipliers of all rows of ``system`` (those a transform removed recovered from
        equilibrium).
        """
        u = self.feti.primal_solution(lam, alpha)
        lam = lam.copy()
        for step in reversed(self.steps):
            u_new, lam_new = step.map_back(u, lam)
            u.destroy()
            lam.destroy()
            u, lam = u_new, lam_new
        return u, lam

    # --- a new load case -----------------------------------------------------------------
    def for_load(self, system: BlockSystem) -> DualQP:
        """The dual QP of ``system``, a new load case of this one's (same K and B).

        Each transform of the chain is applied to the new right-hand sides and shares its
        operators: the factorizations, F, G, the coarse factor, P F P and ‖P F P‖ are kept;
        d, e, λ̂, b and the bounds are new (one K⁺ application and one F application).

        Raises:
            InputError: When the new load cannot be balanced (``e ∉ Im G``).
        """
        steps, parent = [], system
        for step in self.steps:
            steps.append(step.for_load(parent))
            parent = steps[-1].child
        feti = self.feti.for_load(parent)
        warnings = check_balance(self.constraint, feti)
        hom = self.hom.for_load(feti)
        return replace(self, feti=feti, system=system, steps=steps, hom=hom,
                       proj=self.proj.for_load(hom), warnings=warnings)

    def destroy_load(self) -> None:
        """Free the vectors of this load case (not the shared operators)."""
        self.hom.destroy()
        self.proj.b.destroy()

    def destroy(self) -> None:
        """Free the chain's PETSc objects: the vectors, P F P, F, the factorizations.

        The Total FETI system's B, c and f stay (a Solution reads them); so does every
        operator of an earlier load case it shares with this one (they are the same objects).
        A shell Mat holds its Python context — and through it the whole chain — until it is
        destroyed: without this, a chain outlives its last reference.
        """
        self.destroy_load()
        self.proj.A.destroy()
        if self.proj.top is not None:
            self.proj.top.destroy()
        self.feti.destroy(operators=True)
        last = self.steps[-1].child if self.steps else self.system
        last.destroy_factors()
        for step in self.steps:
            step.child.destroy_rows()


def chain_qp(total: BlockSystem, steps: list, *, method: str = "tfeti",
             factor: str | None = None, norm_rtol: float = 1e-4, timer: Timer | None = None,
             dec=None, rows=None, info: dict | None = None,
             dual_operator: str = "implicit", norm_guess: PETSc.Vec | None = None,
             same_load: Dualization | None = None) -> DualQP:
    """Factor the last system of a chain of primal transforms, dualize, homogenize, project.

    Args:
        total: The first system of the chain (Total FETI form: every row).
        steps: The primal transforms applied to it, in order (each ``steps[i].parent`` is the
            previous one's ``child``); may be empty.
        method: The name of the method (for the report).
        factor: Sparse Cholesky package.
        norm_rtol: Relative tolerance of the Lanczos estimate of ``||P F P||``.
        timer: Phase timers (a new one if None).
        dec: The decomposition behind ``total``, if any.
        rows: The constraint rows behind ``total``, if any.
        info: Sizes of the method for the report.
        dual_operator: How F is applied (:class:`.dualize.Dualization`).
        norm_guess: Where the estimate of ``||P F P||`` starts (:class:`.homogenize.Project`).
        same_load: The dualization of a chain of the same factors (other rows) whose K⁺f this
            one takes where f is the same (:class:`.dualize.Dualization`).
    """
    timer = Timer() if timer is None else timer
    comm = total.comm
    system = steps[-1].child if steps else total
    row_index = np.arange(total.dual_size[0])
    for step in steps:
        row_index = row_index[step.kept]
    if not system.factored:
        with timer.phase("factorization"):
            system.factorize(factor, site="factorization")  # guarded inside (collective)
    with timer.phase("dual operators"):
        feti = Dualization(system, dual_operator, same_load=same_load)
    ineq = system.types == INEQUALITY
    with timer.phase("coarse problem"):
        ocon = orthonormalize(RowBlockConstraint(feti.Gt_local, comm))
        warnings = check_balance(ocon, feti)
        hom = Homogenize(feti, ocon, ineq)
        proj = Project(hom, norm_rtol, norm_guess)
    return DualQP(feti=feti, system=total, steps=steps, method=method, dec=dec, rows=rows,
                  row_index=row_index, hom=hom, proj=proj, ineq=ineq, warnings=warnings,
                  info=info or {})


def check_balance(ocon, feti: Dualization) -> list[str]:
    """Refuse a load that the constraints cannot balance; note undetermined motions."""
    N = ocon.null_space
    if N.shape[1] == 0:
        return []
    weight = np.abs(N).max(axis=1)
    cols = np.flatnonzero(weight > 1e-6 * weight.max())
    bodies = sorted({feti.kernel_bodies[i] for i in cols})
    ratio = _unbalanced(N, feti)
    if ratio > BALANCE_TOL:
        raise InputError(
            f"the load cannot be balanced: bodies {bodies} can move rigidly without meeting any "
            "Dirichlet or contact condition, and the load has a component along that motion "
            f"(relative size {ratio:.2e}), so the problem has no solution (e is "
            "not in Im G). Add a Dirichlet condition or a contact surface that stops it, or "
            "remove that load component")
    return [f"{N.shape[1]} rigid motion(s) of bodies {bodies} are not fixed by any condition "
            "(and not loaded); of the solutions, which differ by these motions, the one "
            "returned is orthogonal to them (zero nodal mean along each, in the nodal l2 inner "
            "product): the same for every decomposition and number of ranks"]


def _unbalanced(N: np.ndarray, feti: Dualization) -> float:
    """The largest load component along a free rigid motion, relative to the load's size.

    ``|n_kᵀ e|`` against ``|n_k|ᵀ ẽ + ||e||`` with ``ẽ = |R|ᵀ |f|`` (the size of the terms
    summed in e = Rᵀf; ``||e||`` for the round-off of n_k itself): a self-equilibrated load
    has ``n_kᵀ e`` at round-off of ẽ, not of ``||e||``, which is itself round-off then.
    """
    e_abs = feti.comm.allreduce(abs(feti.R).T @ np.abs(feti.f.array_r), op=MPI.SUM)
    scale = np.abs(N).T @ e_abs + np.linalg.norm(feti.e)
    along = np.abs(N.T @ feti.e)
    return float(np.max(along / np.maximum(scale, 1e-300), initial=0.0))


__all__ = ["BALANCE_TOL", "DualQP", "chain_qp", "check_balance"]
