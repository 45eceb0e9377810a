"""rtol as an accuracy: stop on the KKT conditions of the original problem, in physical units.

The residuals (:func:`kkt_residuals`, also those of :meth:`.solution.Solution.check_kkt`):

- ``equality``: the largest violation of a gluing or Dirichlet row, ``max |B u − c|``, against
  ``‖u‖∞`` (lengths against the displacement scale);
- ``primal_feasibility``: the largest penetration against ``‖u‖∞``;
- ``dual_feasibility``: the largest negative contact force against the largest force;
- ``complementarity``: ``max |λ_i (B u − c)_i|`` against ``max|λ| ‖u‖∞`` (the work of the
  contact forces on the gaps, against the largest force times the displacement scale);
- ``violation_force``: the contact rows' violations in force units, ``max_i k_i |v_i|``
  against ``max(max|λ|, ‖f‖∞)`` (λ in physical rows), where ``v_i`` is ``(B u − c)_i`` on a
  contact row that carries a force and its penetration on the others, and ``k_i`` the row's
  stiffness, its sides in series (``1 / k_i = Σ_j b_ij² / K_jj``): the force that would close
  the violation at that node alone. The residuals before are relative to ``‖u‖∞``, the
  displacement of the whole body; a contact force oscillating from node to node by δ moves
  the gaps by only about δ / k (F damps such modes most), so gaps within ``rtol ‖u‖∞`` left
  force errors of 24 rtol of the largest force (2D Hertz, FETI-1). This residual bounds the
  force error of such modes by about rtol; of smooth ones it over-estimates. Gluing and
  Dirichlet rows are left to ``equality``: their smooth violations would be over-estimated
  by the number of rows (2D Hertz in 4 parts: 40 % more F-multiplications, no gain);
- ``equilibrium``: ``‖K u − f + Bᵀλ‖`` against ``max(‖f‖, ‖Bᵀλ‖, κ ‖u‖)`` (force balance of
  every subdomain, against the load).

None of them involves the dual right-hand side b of the chosen method or the gaps of contact
rows out of reach. :class:`KKTStop` makes them the stopping test: during the iterations a free
bound — the projected gradient of the dual QP is, row by row, the violation ``B u − c`` of the
primal solution its iterate implies (scaled by the row's ``scale``), so
``max_i |g^P_i| / scale_i <= θ rtol U`` (``U`` the displacement scale) bounds ``equality``,
``primal_feasibility`` and ``complementarity`` up to the term ``P F G̃ᵀG̃x`` of an iterate
off ker G̃ (SMALBE's; the QP's Hessian P F P does not see it, P G̃ᵀ = 0); on the contact rows
the same gradient in force units, ``U max_i k_i |g^P_i| / scale_i / max(max|λ|, ‖f‖∞) <=
θ rtol U`` (:class:`KKTGradientTest`, λ of the iterate), bounds ``violation_force`` (without
it 15 of 16 first checks on docs/benchmarks.md § 19's problems passed the lengths and failed
on the forces, and the bound aimed from that check over-solved the next run: history §§ 31,
33); and
``‖G̃x‖ <= min(θ_e rtol Λ, θ rtol U / (‖PFP‖ max_i 1/scale_i))`` (``Λ`` a force scale) bounds
that term and ``equilibrium``. That unit of ‖G̃x‖ is a worst case (the term's own unit
``max_i |(P F G̃ᵀ G̃x)_i| / scale_i / ‖G̃x‖`` measured 0.07–3.6 on 2D Hertz against 4–26), but
a truer one does not pay: SMALBE's multiplier update cuts ‖G̃x‖ 2–40× per outer iteration
at 0–7 F-multiplications, and the bound of ‖G̃x‖ alone takes 3.6 % of § 19's F-multiplications
(docs/benchmarks_history.md § 31, ``bench/stop_budget.py``). When the bound holds, the primal
solution is recovered (one F and one K⁺ application, counted) and the residuals above are
evaluated exactly. If one exceeds rtol, the scales and the factors θ are set from what was
measured and the QP solver continues from where it stopped (warm: the iterate and SMALBE's
multiplier kept); if a check does not improve on the one before by :data:`STALL`, the round-off
floor of the dual QP is reached and the solve stops there, with a warning.
"""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..constraints.rows import Kind
from ..parallel.reduce import max_scalar
from ..qp import MaxGradientTest

#: The residuals the stopping test bounds by rtol (friction adds its own two).
KEYS = ("dual_feasibility", "primal_feasibility", "equality", "complementarity",
        "violation_force", "equilibrium")
#: At most this many exact checks in one solve (each a recovery of u); then the QP solver's
#: stop is accepted as it is, with a warning naming the residual above rtol.
MAX_CHECKS = 8
#: A bound of the weighted gradient below this many ε ‖A‖ max_i w_i ‖λ‖ (the round-off of
#: the gradient F λ − d) is not asked of the QP solver: a run cannot reach it and would go
#: to its budget (a Newton increment near the solution, whose U is small). 1, not 10: the
#: P2 contact patch tests at rtol 1e-12 reach bounds just above ε ‖A‖ w ‖λ‖.
ROUND_OFF = 1.0
#: A failed check aims the next bound at this fraction of what would just pass.
SAFETY = 0.5
#: The largest ratio of all rows' largest force to the QP rows' that a warm solve's bound
#: takes from the last solve (:class:`KKTStop`'s ``force_ratio``).
FORCE_RATIO_MAX = 1e3
#: A check whose largest residual is above this fraction of the best before, after the bound
#: was tightened, has met the round-off floor of the dual QP (e.g. eps ‖b‖ of far gaps): the
#: solve stops there, with a warning.
STALL = 0.5


def kkt_residuals(system, scale: np.ndarray, kind: np.ndarray, ineq: np.ndarray,
                  u: PETSc.Vec, lam: PETSc.Vec, Bu: PETSc.Vec | None = None,
                  friction=None, u_floor: float = 0.0) -> tuple[dict[str, float], float]:
    """The KKT residuals of ``(u, λ)`` for the Total FETI ``system`` (collective).

    Args:
        system: The Total FETI system (``B``, ``c``, ``comm``, ``residuals``).
        scale: Per local row, its scale (a row is the physical condition times its scale).
        kind: Per local row, its :class:`.constraints.rows.Kind`.
        ineq: Local mask of the inequality rows.
        u: The primal solution, subdomain by subdomain.
        lam: The multipliers of all rows.
        Bu: ``B u`` if known (else computed).
        friction: The solve's FrictionSolve, or None.
        u_floor: A lower bound of the displacement scale ‖u‖∞ the lengths are measured
            against (a Newton increment's: the total displacement, see :class:`KKTStop`).

    Returns:
        The residuals by name (module docstring) and the largest penetration (a length).
    """
    comm = system.comm
    own_Bu = Bu is None
    if own_Bu:
        Bu = system.B.createVecLeft()
        system.B.mult(u, Bu)
    viol = (Bu.array_r - system.c.array_r) / scale  # B u − c, physical units
    lam_phys = lam.array_r * scale

    def gmax(a, default=0.0):
        return max_scalar(comm, float(a.max()) if a.size else default)

    lam_max = gmax(np.abs(lam_phys))
    u_max = max(u.norm(PETSc.NormType.INFINITY), u_floor, 1e-300)
    pen = gmax(viol[ineq], -np.inf)
    kkt = {
        "dual_feasibility": gmax(np.maximum(-lam_phys[ineq], 0.0)) / max(lam_max, 1e-300),
        "primal_feasibility": max(pen, 0.0) / u_max,
        "equality": gmax(np.abs(viol[~ineq & (kind != Kind.TANGENT)])) / u_max,
        "complementarity": gmax(np.abs(lam_phys[ineq] * viol[ineq]))
        / max(lam_max * u_max, 1e-300),
    }
    if getattr(system, "K", None) is not None:  # Newton's nonlinear residual has no K
        kkt["violation_force"] = _violation_force(system, scale, kind, ineq, viol, lam_phys,
                                                  lam_max)
    if friction is not None:
        kkt.update(friction.kkt(lam_phys, viol, lam_max, u_max))
    kkt.update(system.residuals(u, lam))
    if own_Bu:
        Bu.destroy()
    return kkt, (max(pen, 0.0) if np.isfinite(pen) else 0.0)


def _violation_force(system, scale: np.ndarray, kind: np.ndarray, ineq: np.ndarray,
                     viol: np.ndarray, lam_phys: np.ndarray, lam_max: float) -> float:
    """``max_i k_i |v_i| / max(max|λ|, ‖f‖∞)`` (module docstring; collective).

    ``k_i`` is the stiffness of row i, its sides in series: ``1 / k_i = Σ_j b_ij² / K_jj``
    over the row's entries (b the physical row). In series, not summed: at a coefficient jump
    the soft side decides how much force a violation hides (``b K bᵀ`` of the stiff side
    over-estimates it by the jump). One multiplication by B squared entrywise: no solve.
    """
    # contact rows only: a gluing violation of a smooth mode hides little force, which
    # k_i |v_i| over-estimates by the number of rows (50× on 2D Hertz in 4 parts, 40 % more
    # F-multiplications for no gain in the contact forces); ``equality`` bounds it in lengths
    v = np.where(lam_phys > 0.0, viol, np.maximum(viol, 0.0))
    v[~_contact_rows(kind, ineq)] = 0.0  # friction has residuals of its own
    k = row_stiffness(system, scale)
    force = max_scalar(system.comm, float(np.max(k * np.abs(v), initial=0.0)))
    ref = max(lam_max, system.f.norm(PETSc.NormType.INFINITY), 1e-300)
    return force / ref


def _contact_rows(kind: np.ndarray, ineq: np.ndarray) -> np.ndarray:
    """The rows ``violation_force`` measures: the inequalities, friction's tangents not."""
    return ineq & (kind != Kind.TANGENT)


def row_stiffness(system, scale: np.ndarray) -> np.ndarray:
    """Per local row, its stiffness with its sides in series, ``1 / Σ_j b_ij² / K_jj``.

    ``b`` the physical row (the row of B over its ``scale``); 0 for a row without entries.
    One multiplication by B squared entrywise: no solve (collective).
    """
    B = system.B
    kdiag = system.K.diagonal()
    inv = B.createVecRight()
    inv.array[:] = np.divide(1.0, kdiag, out=np.zeros_like(kdiag), where=kdiag > 0)
    ai, aj, av = B.getValuesCSR()
    B2 = PETSc.Mat().createAIJ(B.getSizes(), csr=(ai, aj, av * av), comm=B.comm)
    comp = B.createVecLeft()
    B2.mult(inv, comp)
    c = comp.array_r / (scale * scale)  # the row's compliance, physical units
    for obj in (inv, B2, comp):
        obj.destroy()
    return np.divide(1.0, c, out=np.zeros_like(c), where=c > 0)


def row_data(qp) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per local row of ``qp.system``: scale, kind and the inequality mask."""
    rows = qp.rows
    n = qp.system.dual_size[0]
    if rows is None:  # a hand-made system: unit scales, the kinds from the row types
        ineq = np.asarray(qp.system.types == 1)
        kind = np.where(ineq, Kind.OBSTACLE, Kind.GLUE)
        return np.ones(n), kind, ineq
    own = rows.own
    return own.scale, own.kind, own.inequality


def _force_bound(qp, scale: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """What :class:`KKTGradientTest` needs beyond the lengths (collective).

    ``k_i / scale_i`` on the QP's contact rows (0 elsewhere), the rows' scales, λ̂ and ``‖f‖∞``.
    """
    _, kind, ineq = row_data(qp)
    rows = qp.row_index
    k = row_stiffness(qp.system, scale)[rows]
    contact = _contact_rows(kind, ineq)[rows]
    sc = scale[rows]
    return (np.where(contact, k / sc, 0.0), sc, qp.lam_hat.array_r.copy(),
            qp.system.f.norm(PETSc.NormType.INFINITY))


#: The residuals measured in lengths against U (what the weighted gradient bounds).
LENGTHS = ("primal_feasibility", "equality", "complementarity")


def _lengths(kkt: dict[str, float]) -> float:
    """The largest residual of :data:`LENGTHS` (relative to U)."""
    return max(kkt.get(k, 0.0) for k in LENGTHS)


class KKTGradientTest(MaxGradientTest):
    """The bound of :class:`KKTStop`: lengths and, on the contact rows, forces (collective).

    ``max(max_i w_i |g^P_i|, U / R max_i k_i w_i |g^P_i|) <= tol`` and ``‖G̃x‖ <= eq_tol``,
    ``w_i = 1 / scale_i``. Row i's projected gradient is its violation ``v_i = w_i g^P_i`` (up
    to the term of ‖G̃x‖), so the first part bounds the length residuals and the second
    ``violation_force``, ``max_i k_i |v_i| / R`` with ``R = max(max_i |λ_i| scale_i, ‖f‖∞)`` of
    the iterate (``λ = λ̂ + x``), brought to lengths by U (``tol`` is θ rtol U).

    Args:
        weight: ``w`` on the QP's rows.
        force_weight: ``k_i w_i`` on the contact rows, 0 on the others.
        scale: The QP's rows' scales.
        lam_hat: Local array of λ̂ (the iterate is ``x = λ − λ̂``).
        f_inf: ``‖f‖∞``.
        U: The displacement scale.
        tol: Tolerance of the weighted gradient (a length).
        comm: The communicator of the rows.
        eq_tol: Tolerance of ``‖G̃x‖``.
        force_ratio: ``R`` is taken as ``max(force_ratio max_i |λ_i| scale_i, ‖f‖∞)``: the
            exact ``violation_force`` is relative to the largest force of *all* rows, which
            FETI-1 and FETI-DP partly eliminate from the QP (Dirichlet rows, corners), so a
            ratio measured on an earlier solution (:attr:`KKTStop.force_ratio`) makes the
            bound that much less conservative (the exact check still decides).

    Attributes:
        length, force: The two parts of :attr:`last` (lengths, and forces brought to lengths).
    """

    def __init__(self, weight: np.ndarray, force_weight: np.ndarray, scale: np.ndarray,
                 lam_hat: np.ndarray, f_inf: float, U: float, tol: float, comm: MPI.Comm,
                 eq_tol: float = math.inf, force_ratio: float = 1.0) -> None:
        super().__init__(weight, tol, comm, eq_tol)
        self.force_weight, self.scale, self.lam_hat = force_weight, scale, lam_hat
        self.f_inf, self.U, self.force_ratio = f_inf, U, force_ratio
        self.length = self.force = math.inf

    def __call__(self, gP: np.ndarray, x: PETSc.Vec | None = None) -> bool:
        """Whether the bound holds for the local projected gradient ``gP`` at ``x``."""
        g = np.abs(gP)
        lam = 0.0 if x is None else float(
            np.max(np.abs((self.lam_hat + x.array_r) * self.scale), initial=0.0))
        local = np.array([np.max(self.weight * g, initial=0.0),
                          np.max(self.force_weight * g, initial=0.0), lam])
        both = np.empty(3)
        self.comm.Allreduce(local, both, op=MPI.MAX)  # one reduction for the three
        length, force, lam = (float(v) for v in both)
        ref = max(lam * self.force_ratio, self.f_inf)
        # no force yet (λ = 0, no load: a problem driven by its Dirichlet values): the force
        # part cannot pass (a floor like 1e-300 instead made the value depend on the load's
        # scale, and the QP solver's path with it)
        self.force = force * self.U / ref if ref > 0 else (math.inf if force > 0 else 0.0)
        self.length = length
        self.last = max(self.length, self.force)
        return self.last <= self.tol


class KKTStop:
    """The stopping test of one solve: a bound during the iterations, the exact check after.

    Args:
        qp: The dual QP (:class:`.feti.chain.DualQP`).
        rtol: The tolerance of every residual of :data:`KEYS`.
        u_floor: A lower bound of the displacement scale U. A Newton increment Δu tends to 0
            while the multipliers stay the total forces: measured against ‖Δu‖∞ the bound
            falls below the round-off of F λ and the QP solver runs to its budget (the 3D
            friction runs under Newton that did not finish); the increment only needs to be
            accurate against the total displacement.
        force_ratio: The ratio of the largest force of all rows to the largest of the QP's
            rows, measured on an earlier solution of the same set-up (:attr:`force_ratio` of
            its stop; a warm solve's): the force part of the bound is measured against that
            many times the QP's largest force (:class:`KKTGradientTest`). 1: the QP's rows
            alone (a lower bound of the exact reference: a conservative bound).

    Attributes:
        checks: Exact checks made (recoveries of u), the last one included.
        stalled: Whether the last check failed to improve on the best one before by the
            factor :data:`STALL`: the round-off floor, where more iterations do not help.
        U: The displacement scale of the bound (``‖u‖∞`` of the last check; before the first,
            ``max_i |b_i| / scale_i``, the violation of λ = λ̂).
        Lam: The force scale of the equality bound (``‖λ‖`` of the QP's rows at the last
            check; before the first, ``‖b‖ / ‖A‖``).
        force_ratio: The ratio the bound's force part uses.
        measured: The ratio the last check measured (:meth:`measure`), for the next solve.
    """

    def __init__(self, qp, rtol: float, u_floor: float = 0.0,
                 force_ratio: float = 1.0) -> None:
        self.rtol, self.comm, self.u_floor = rtol, qp.system.comm, u_floor
        self.force_ratio = min(max(float(force_ratio), 1.0), FORCE_RATIO_MAX) \
            if math.isfinite(force_ratio) else 1.0
        scale, _, _ = row_data(qp)
        self.rows = qp.row_index
        self.weight = 1.0 / scale[qp.row_index]
        self.measured = 1.0
        b = qp.b.array_r
        self.U = max(u_floor, self.comm.allreduce(
            float(np.max(np.abs(b) * self.weight, initial=0.0)), op=MPI.MAX))
        self.Lam = qp.b.norm() / max(qp.norm_A, 1e-300)
        # ‖G̃x‖ ≠ 0 moves B u − c by up to ‖PFP‖ ‖G̃x‖ (SMALBE's iterates leave ker G̃): in
        # lengths, times the largest weight
        w_max = self.comm.allreduce(float(self.weight.max(initial=0.0)), op=MPI.MAX)
        self.eq_unit = self.eq_unit_max = max(qp.norm_A * w_max, 1e-300)
        self.tol_g = rtol * self.U
        self.tol_e = min(rtol * self.Lam, self.tol_g / self.eq_unit)
        self.forces = _force_bound(qp, scale) if getattr(qp.system, "K", None) is not None \
            else None  # a system without K has no violation_force to bound
        self.checks = 0
        self.stalled, self.flat = False, 0
        self.worst = math.inf
        self.test: MaxGradientTest | None = None
        self.history: list[dict] = []

    def make_test(self, loosen: float = 1.0) -> MaxGradientTest:
        """The bound for the next run of the QP solver, ``loosen`` times the current one.

        ``loosen > 1`` asks for less accuracy (Coulomb's early fixed-point steps).
        """
        floor = ROUND_OFF * np.finfo(float).eps * self.eq_unit_max * self.Lam
        tol, eq_tol = max(self.tol_g * loosen, floor), self.tol_e * loosen
        self.test = MaxGradientTest(self.weight, tol, self.comm, eq_tol) \
            if self.forces is None else KKTGradientTest(
                self.weight, *self.forces, self.U, tol, self.comm, eq_tol, self.force_ratio)
        return self.test

    def measure(self, lam_all: PETSc.Vec, scale: np.ndarray) -> float:
        """The ratio of the largest force of all rows to the QP rows' at a check (collective).

        ``lam_all``: the multipliers of all rows, ``scale`` their scales (physical λ =
        λ scale). Kept as :attr:`measured` (1 without a force on the QP's rows). With
        ``scale`` per local row of the problem, of which the QP's rows are ``qp.row_index``.
        """
        lam = np.abs(lam_all.array_r * scale)
        local = np.array([np.max(lam, initial=0.0), np.max(lam[self.rows], initial=0.0)])
        both = np.empty(2)
        self.comm.Allreduce(local, both, op=MPI.MAX)  # elementwise (the buffer reduction)
        all_max, qp_max = (float(v) for v in both)
        self.measured = float(all_max / qp_max) if qp_max > 0 else 1.0
        return self.measured

    def rescale(self, u: PETSc.Vec, lam_qp: PETSc.Vec) -> None:
        """Take the scales U and Λ of an intermediate solution (collective).

        Before the first check U is ``max_i |b_i| / scale_i``, which the gaps of rows far out
        of reach can make much larger than the displacements; a loosened bound (Coulomb's
        early steps) would then be no bound at all.
        """
        self.take_scales(u.norm(PETSc.NormType.INFINITY), lam_qp.norm())

    def take_scales(self, U: float, Lam: float) -> None:
        """Take the displacement scale U and the force scale Λ (see :meth:`rescale`)."""
        U = max(U, self.u_floor)
        if U > 0:
            self.U, self.Lam = U, Lam
            self.tol_g = min(self.tol_g, self.rtol * U)
            self.tol_e = min(self.tol_e, self.rtol * self.Lam, self.tol_g / self.eq_unit)

    def accept(self, kkt: dict[str, float], u: PETSc.Vec, lam_qp: PETSc.Vec,
               Dx_norm: float | None) -> bool:
        """Whether the exact residuals pass; if not, the bound of the next run (collective).

        Args:
            kkt: The exact residuals of the recovered solution.
            u: The recovered primal solution.
            lam_qp: λ = λ̂ + x on the QP's rows.
            Dx_norm: ``‖G̃x‖`` at the stop (None: no equality in the QP).
        """
        self.checks += 1
        rtol = self.rtol
        primal = max([kkt.get(k, 0.0) for k in KEYS if k != "equilibrium"] +
                     [v for k, v in kkt.items() if k.startswith("friction")])
        equil = kkt.get("equilibrium", 0.0)
        g_last = self.test.last if self.test is not None else math.inf
        self.history.append({"check": self.checks, "bound": g_last, "tol_g": self.tol_g,
                             "Dx": Dx_norm, "tol_e": self.tol_e, "primal": primal,
                             "equilibrium": equil})
        if primal <= rtol and equil <= rtol:
            return True
        worst = max(primal, equil)
        self.flat = self.flat + 1 if worst > STALL * self.worst else 0
        # two flat checks in a row end it: past the floor a QP run chases an unreachable
        # bound, but each run after a failed check is bounded by the runs before it
        # (qp_solve.CONTINUE_BUDGET); one flat check ended FETI-1 on the coarse 2D Hertz mesh
        # at 1.2·rtol where the next run reached 0.01·rtol
        self.stalled, self.worst = self.flat >= 2, min(worst, self.worst)
        if self.stalled:
            return False
        U = max(u.norm(PETSc.NormType.INFINITY), self.u_floor)
        Lam = lam_qp.norm()
        tightened = False
        if primal > rtol:
            # the bound at this stop, scaled to what would have passed, and the scale U now
            target = SAFETY * g_last * rtol / primal if math.isfinite(g_last) else math.inf
            new = min(rtol * U, target) if U > 0 else target
            tightened = new < self.tol_g
            self.tol_g = min(self.tol_g, new) if math.isfinite(new) else 0.1 * self.tol_g
        if equil > rtol:
            if Dx_norm is not None and Dx_norm > 0:
                new = min(SAFETY * Dx_norm * rtol / equil, rtol * Lam)
                tightened = tightened or new < self.tol_e
                self.tol_e = min(self.tol_e, new)
            else:  # no coarse equality to tighten: the gradient decides the balance
                self.tol_g *= 0.1
                tightened = True
        if Dx_norm and math.isfinite(g_last):
            # what ‖G̃x‖ moved B u − c by at most, measured: the excess of the exact violation
            # over the gradient bound (the worst case ‖PFP‖ max 1/scale over-solves 5–50×)
            # (lengths only: violation_force is a force, and read as a length it made the
            # unit 100x too large and the next run over-solve ‖G̃x‖, FETI-DP on 2D Hertz)
            measured = max(_lengths(kkt) * U, g_last) / Dx_norm
            self.eq_unit = min(self.eq_unit_max, max(measured, 1e-3 * self.eq_unit_max))
        if not tightened:  # the measured scales say the bound held: tighten it anyway
            self.tol_g *= 0.1
            self.tol_e *= 0.1
        self.tol_e = min(self.tol_e, self.tol_g / self.eq_unit)
        self.U, self.Lam = U, Lam
        return False


__all__ = ["FORCE_RATIO_MAX", "KEYS", "MAX_CHECKS", "STALL", "KKTGradientTest", "KKTStop",
           "kkt_residuals", "row_data", "row_stiffness"]
