"""Friction in the solve: bounds, the Coulomb fixed point, recovery, KKT residuals, output.

With λ = μ + λ̂ (homogenization) the bounds of the tangential multipliers move with λ̂:

- 2D (one tangential row per contact node, a box): −g/s − λ̂_T <= μ_T <= g/s − λ̂_T, solved by
  MPRGP with upper bounds;
- 3D (two rows per node, a disc): ||μ_T + λ̂_T|| <= g/s, a disc centred at −λ̂_T, solved by
  MPGP (:mod:`dolfinx_feti.qp.mpgp`);

g the physical nodal slip bound and s the row scale (1/√2 for node-to-node rows, 1 for
obstacles), since the physical multiplier is s·λ. A row pinned on a symmetry plane
(:mod:`dolfinx_feti.constraints.friction`) is held at λ = 0 (the interval of bound 0), and its
node's other row gets the box −g/s <= λ_T1 <= g/s instead of a disc; the residuals, the
recovery and the output leave the pinned row out (its slip is that of the mirror image).
Coulomb friction iterates g = 𝓕 λ_N (physical normal forces) over warm-started Tresca
solves. Only built when a contact condition has friction.

On a load path (:func:`dolfinx_feti.solve_path`) a step starts warm: the QP from the last
step's multipliers (projected onto the new bounds by the QP solver), Coulomb's fixed point from
the slip bounds of the last step's normal forces instead of g = ∞.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..constraints.friction import SLIP, STICK, FrictionData
from ..parallel.reduce import any_rank, max_scalar
from ..qp import Discs, QPResult
from ..setup.share import RankRows

#: The inner accuracy of the first Coulomb steps (the KKT residuals of the Tresca solves, in
#: physical units): the bounds they feed to the next step are far from converged anyway.
#: (bench/coulomb_sliding.py with 0.1, before ETA_MAX_DISCS and SMALBE's search: 27 % fewer
#: F-multiplications over the full punch's five loads, but the half model at 0.9 𝓕N no
#: longer converged; 0.3: more steps.) Intervals (2D friction) take it: looser, the 2D
#: Coulomb path's cold solves took more steps (docs/benchmarks_history.md § 40).
ETA_MAX = 1e-2
#: The same on discs (3D friction). The first Tresca steps feed the next one their normal
#: forces only, which settle long before the floating body's tangential equilibrium (the
#: equality of the natural coarse space, SMALBE's outer loop) does; near gross sliding that
#: equilibrium is held by a few sticking nodes, and solving it to 1e-2 in the first Tresca
#: step took most of a load's F-multiplications (benchmarks.md § 24, history § 40). Up to
#: the forces' scale, not beyond: at 3 the coarse half punch's first Tresca step passed its
#: test unsolved (one F-multiplication) and the next one cost more than at 1e-2.
ETA_MAX_DISCS = 1.0
#: The last Tresca solves are solved to min(rtol, ETA_MIN_FACTOR · the fixed point's tolerance):
#: the inner error then moves the Coulomb residual by less than its tolerance.
ETA_MIN_FACTOR = 0.5
#: A Coulomb residual above STALL times the one before counts as stalled: the inner accuracy
#: is cut tenfold.
STALL = 0.7


class FrictionSolve:
    """The friction rows owned by this rank and the state of the friction solve.

    Attributes:
        data: The global :class:`~dolfinx_feti.constraints.friction.FrictionData`.
        t: Local indices (into the rank's rows) of the tangential rows.
        n: Local index of the normal row of each tangential row.
        g: Nodal slip bound (a force) per local tangential row, of the last Tresca solve.
        at_bound: Per local tangential row: its multiplier is on the bound (the node slips).
        normal_force: Per local tangential row, the physical normal force of its node after
            the solve (a warm start's Coulomb bounds).
        warm: Start the QP from the given iterate (else from λ = λ̂ where feasible).
        info: What is reported in ``report.extra['friction']``.
    """

    def __init__(self, data: FrictionData, rows: RankRows, rows_local: slice,
                 comm: MPI.Comm) -> None:
        self.data, self.rows, self.comm = data, rows, comm
        lo, hi = np.searchsorted(data.rows, [rows_local.start, rows_local.stop])
        self._global = slice(int(lo), int(hi))
        self.t = data.rows[lo:hi] - rows_local.start
        self.n = data.normal_row[lo:hi] - rows_local.start
        self.scale = rows.contact.scale[rows.contact_rows(data.rows[lo:hi])]
        self.scale_n = rows.contact.scale[rows.contact_rows(data.normal_row[lo:hi])]
        self.tresca = data.tresca[lo:hi]
        self.coef = data.coefficient[lo:hi]
        self.coulomb_rows = ~np.isnan(self.coef)
        self.nt = data.per_node
        self.pinned = np.zeros(self.t.size, dtype=bool) if data.pinned is None else \
            np.asarray(data.pinned[lo:hi], dtype=bool)
        # per local node: the disc is an interval of its first row (the other one pinned)
        self._flat = self.pinned.reshape(-1, self.nt).any(axis=1)
        self.g = np.where(self.coulomb_rows, np.inf, self.tresca)
        self.at_bound = np.zeros(self.t.size, dtype=bool)
        self.normal_force = np.zeros(self.t.size)
        self.warm = False
        self.multiplier = None
        self.info: dict = {}
        self._ub: PETSc.Vec | None = None
        self._r = math.inf  # the Coulomb residual of the last fixed-point step
        self._eta: float | None = None  # the inner accuracy of the next step (None: from _r)
        self._predicted = False  # the bounds start from a prediction: every step accurate
        self._cold = True  # neither the iterate nor the bounds start from an earlier solve

    @property
    def eta_max(self) -> float:
        """The inner accuracy of the first Coulomb steps.

        :data:`ETA_MAX_DISCS` on discs in a cold solve, else :data:`ETA_MAX`. A warm solve (a
        load path's later case, a Newton increment) starts from multipliers near its
        solution, where a loose Tresca step only postpones the work (docs/benchmarks_history.md
        § 41, item 5).
        """
        return ETA_MAX_DISCS if self.nt == 2 and self._cold else ETA_MAX

    def relabel(self, index: np.ndarray) -> None:
        """Renumber the local rows: local row ``i`` becomes ``index[i]``.

        A transform that removes rows (FETI-1, FETI-DP) solves the QP on fewer rows than the
        problem has; the friction rows are never among the removed ones.
        """
        self.t = index[self.t]
        self.n = index[self.n]

    def start_from(self, normal_force: np.ndarray | None, predicted: bool = False) -> None:
        """Start warm; Coulomb's slip bounds from the normal forces of an earlier solve.

        Args:
            normal_force: Per local tangential row, as :attr:`normal_force` of that solve;
                None: Coulomb's fixed point starts from g = ∞ (no slip).
            predicted: The normal forces are a prediction of this case's (a load path's
                secant extrapolation), not an earlier case's: every Tresca solve of the fixed
                point is then solved to its final accuracy, as the bounds are about right from
                the start (the 2D Coulomb path: the residual after the first step 5e-5 against
                1.7e-3 from the last case's forces; solved to 1e-2 and then to a tenth of the
                residual, as for a far start, the accuracy they lacked cost more steps:
                docs/benchmarks_history.md § 22).
        """
        self.warm = True
        self._cold = False
        self._predicted = predicted and normal_force is not None
        if normal_force is not None:
            self.g = np.where(self.coulomb_rows,
                              np.where(self.coulomb_rows, self.coef, 0.0)
                              * np.maximum(normal_force, 0.0), self.tresca)

    # --- the QP ----------------------------------------------------------------------------
    def bounds(self, lb: PETSc.Vec, lam_hat: PETSc.Vec):
        """Set the tangential entries of ``lb``; return ``(ub, discs, multiplier)``."""
        lh = lam_hat.array_r[self.t]
        r = np.where(self.pinned, 0.0, self.g / self.scale)  # the bound on the scaled multiplier
        box = np.repeat(self._flat, self.nt) if self.nt == 2 else np.ones(self.t.size, bool)
        lb.array[self.t] = np.where(box, -r - lh, -np.inf)
        ub = None
        if any_rank(self.comm, bool(box.any())):
            if self._ub is None:
                self._ub = lb.duplicate()
            self._ub.set(np.inf)
            self._ub.array[self.t[box]] = r[box] - lh[box]
            ub = self._ub
        if self.nt == 1:
            return ub, None, self.multiplier
        pairs = self.t.reshape(-1, 2)[~self._flat]
        discs = Discs(pairs, -lh.reshape(-1, 2)[~self._flat],
                      r.reshape(-1, 2)[~self._flat, 0])
        return ub, discs, self.multiplier

    def run(self, run_qp: Callable[..., QPResult], x: PETSc.Vec, lam_hat: PETSc.Vec,
            ineq: np.ndarray, progress, rtol: float = 1e-6,
            rescale: Callable[[QPResult], None] | None = None) -> QPResult:
        """Tresca: one QP solve. Coulomb: the fixed point over warm-started Tresca solves.

        Args:
            run_qp: Runs the QP solver from ``x``; ``run_qp(loosen=η/rtol)`` stops it at the
                accuracy η instead of ``rtol`` (the KKT test in physical units, or the dual
                test, whichever the solve uses).
            x: The iterate (a warm start when :attr:`warm`; else set here).
            lam_hat: λ̂ of the homogenization.
            ineq: Local mask of the inequality rows.
            progress: Progress output.
            rtol: The solve's tolerance.
            rescale: Called after the first Coulomb step: takes the scales of the stopping
                test from that step's solution (they define what the loosened tests mean).

        The Coulomb fixed point stops on its residual in physical units, ``r = max_i |g_i −
        𝓕 λ_N,i| / max_i λ_N,i`` over the Coulomb nodes: the iterate solves the Tresca problem
        of g to the inner accuracy, so r is what keeps it from solving Coulomb's (|λ_T| <= 𝓕λ_N
        with equality where it slips). The inner accuracy follows the outer progress (η = r/10
        between :data:`ETA_MIN_FACTOR`·tolerance and :attr:`eta_max`) and is cut tenfold when r
        stops decreasing, so the inner tolerance cannot stall the fixed point. Called again
        (the KKT check asked for more accuracy) it continues from its state.
        """
        if not self.warm:
            x.array[:] = np.where(ineq, np.maximum(0.0, -lam_hat.array_r), 0.0)
        model = "coulomb" if self.data.coulomb else "tresca"
        if not self.info:
            self.info = {"model": model, "nodes": int(self.data.rows.size // self.nt),
                         "disc": self.nt == 2, "warm": self.warm}
        self.warm = True
        if not self.data.coulomb:
            res = run_qp()
            self.normal_force = self._normal_force(x, lam_hat)
            return res
        comm = self.comm
        tol = float(self.data.rtol)
        eta_min = min(rtol, ETA_MIN_FACTOR * tol)
        steps = self.info.setdefault("steps", [])
        results = []
        fp_converged = False
        c = self.coulomb_rows
        eta = self._eta if self._eta is not None else \
            eta_min if self._predicted else max(eta_min, min(self.eta_max, 0.1 * self._r))
        for _ in range(self.data.max_steps - len(steps)):
            res = run_qp(loosen=eta / rtol)
            results.append(res)
            if rescale is not None and len(steps) == 0:
                rescale(res)
            lam_n = self.normal_force = self._normal_force(x, lam_hat)
            g_new = np.where(c, self.coef * np.maximum(lam_n, 0.0), self.tresca)
            gmax = max_scalar(comm, float(np.max(lam_n[c], initial=0.0)))
            dg = np.abs(g_new[c] - self.g[c])
            big = max_scalar(comm, float(np.max(dg, initial=0.0)))
            r = big / gmax if gmax > 0 else (0.0 if big == 0 else math.inf)
            steps.append({"step": len(steps), "change": r, "inner_rtol": eta,
                          "iterations": res.iterations,
                          "outer_iterations": res.outer_iterations,
                          "hessian_mults": res.hessian_mults, "qp_converged": res.converged})
            progress.info(f"Coulomb step {len(steps) - 1}: |g - F lam_N| / max lam_N = {r:.2e} "
                          f"(inner accuracy {eta:.0e}), {res.hessian_mults} F-multiplications")
            if not res.converged:
                break
            if r <= tol and eta <= eta_min:
                fp_converged = True
                break
            # the next inner accuracy: a tenth of the outer residual; cut tenfold when the
            # residual stalls (the inner error is then what it measures)
            stalled = math.isfinite(self._r) and r > STALL * self._r
            eta = eta_min if self._predicted else \
                max(eta_min, min(self.eta_max, 0.1 * r, 0.1 * eta if stalled else math.inf))
            self._r = min(r, self._r) if stalled else r
            self.g = g_new
            self.multiplier = res.multiplier
        self._eta = eta
        self.info.update({"fixed_point_steps": len(steps), "fixed_point_converged": fp_converged,
                          "rtol": tol, "coulomb_residual": steps[-1]["change"] if steps else None})
        out = results[-1]
        out.iterations = sum(r.iterations for r in results)
        out.outer_iterations = sum(r.outer_iterations for r in results)
        out.hessian_mults = sum(r.hessian_mults for r in results)
        counts: dict[str, int] = {}
        for r in results:
            for key, v in r.counts.items():
                counts[key] = counts.get(key, 0) + v
        out.counts = counts
        first = len(steps) - len(results)
        out.history = [dict(h, coulomb_step=first + i) for i, r in enumerate(results)
                       for h in r.history]
        if out.converged and not fp_converged:
            out.converged, out.reason = False, "coulomb_max_steps"
        return out

    def _normal_force(self, x: PETSc.Vec, lam_hat: PETSc.Vec) -> np.ndarray:
        """The physical normal force λ_N of each tangential row's node, from λ = λ̂ + x."""
        return (x.array_r[self.n] + lam_hat.array_r[self.n]) * self.scale_n

    # --- the recovery ----------------------------------------------------------------------
    def snap(self, lam: PETSc.Vec, at_bound: np.ndarray) -> None:
        """Put the tangential multipliers that are on their bound exactly on it.

        A pinned row is 0; its node slips or sticks as its other row does.
        """
        self.at_bound = at_bound[self.t].copy()
        la = lam.array
        r = self.g / self.scale
        la[self.t[self.pinned]] = 0.0
        if self.nt == 2:
            ab = self.at_bound.reshape(-1, 2)
            ab[self._flat, 1] = ab[self._flat, 0]
        if self.nt == 1 or self._flat.any():
            box = np.repeat(self._flat, self.nt) & ~self.pinned if self.nt == 2 else \
                ~self.pinned
            on = box & self.at_bound & np.isfinite(r)
            la[self.t[on]] = np.sign(la[self.t[on]]) * r[on]
            if self.nt == 1:
                return
        pairs = self.t.reshape(-1, 2)
        rr = r.reshape(-1, 2)[:, 0]
        on = self.at_bound.reshape(-1, 2)[:, 0] & np.isfinite(rr) & ~self._flat
        Y = la[pairs[on]]
        nrm = np.linalg.norm(Y, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(nrm > 0, rr[on] / nrm, 0.0)
        la[pairs[on]] = Y * s[:, None]

    def recovery_active(self, ineq: np.ndarray, at_bound: np.ndarray) -> np.ndarray:
        """Rows on which B u = c holds: equalities, pressed contact rows, sticking friction rows."""
        tang = np.zeros(ineq.size, dtype=bool)
        tang[self.t] = True
        active = (~ineq & ~tang) | ~at_bound
        active[self.t[self.pinned]] = False  # the dropped direction: no constraint on u
        return active

    # --- residuals and output --------------------------------------------------------------
    def _per_node(self, lam_phys: np.ndarray, viol: np.ndarray):
        keep = ~self.pinned  # a pinned row is no constraint: neither force nor slip counts
        lt = (lam_phys[self.t] * keep).reshape(-1, self.nt)
        r = (viol[self.t] * keep).reshape(-1, self.nt)
        g = self.g.reshape(-1, self.nt)[:, 0]
        return lt, r, g

    def kkt(self, lam_phys: np.ndarray, viol: np.ndarray, lam_max: float,
            u_max: float) -> dict[str, float]:
        """The friction KKT residuals.

        ``friction_feasibility`` = max (|λ_T| − g)⁺ / max|λ|; ``friction_complementarity`` =
        max (g |s| − λ_T·s) / (max|λ| ‖u‖∞), the Fenchel–Young gap of g|·| at the slip s: zero
        iff s = 0 where |λ_T| < g and s ∥ λ_T where |λ_T| = g; |s|/‖u‖∞ where g = ∞. With
        Coulomb friction also ``coulomb_bound`` = max |g − 𝓕 λ_N| / max|λ| over the Coulomb
        nodes: with the two above, the Coulomb conditions' residual (not part of the stopping
        test, which the fixed point's own tolerance bounds).
        """
        lt, r, g = self._per_node(lam_phys, viol)
        nl = np.linalg.norm(lt, axis=1)
        nr = np.linalg.norm(r, axis=1)
        fin = np.isfinite(g)
        over = np.where(fin, np.maximum(nl - np.where(fin, g, 0.0), 0.0), 0.0)
        gap = np.where(fin, np.abs(np.where(fin, g, 0.0) * nr - np.einsum("ij,ij->i", lt, r))
                       / max(lam_max * u_max, 1e-300), nr / max(u_max, 1e-300))

        def gmax(a):
            return max_scalar(self.comm, float(a.max(initial=0.0)))

        out = {"friction_feasibility": gmax(over) / max(lam_max, 1e-300),
               "friction_complementarity": gmax(gap)}
        if self.data.coulomb:  # how far the bound g is from 𝓕 λ_N (the fixed point's residual)
            c = self.coulomb_rows
            lam_n = np.maximum(lam_phys[self.n][c], 0.0)
            out["coulomb_bound"] = gmax(np.abs(self.g[c] - self.coef[c] * lam_n)) / \
                max(lam_max, 1e-300)
        return out

    def contact_fields(self, lam_phys: np.ndarray, viol: np.ndarray, gdim: int
                       ) -> dict[str, np.ndarray]:
        """The friction fields of :class:`~dolfinx_feti.results.solution.ContactData`.

        Per contact node in the order of the normal rows, on every rank.
        """
        comm, rows, data = self.comm, self.rows, self.data

        def gather(a):
            return np.concatenate(comm.allgather(np.asarray(a)))

        lt = gather(lam_phys[self.t] * ~self.pinned)
        s = gather(viol[self.t] * ~self.pinned)
        g = gather(self.g)
        slip_state = gather(self.at_bound)
        sel = rows.inequality_index
        pos = np.searchsorted(sel, data.normal_row)
        tang = rows.contact.normal[rows.contact_rows(data.rows)]
        nc = sel.size
        force = np.zeros((nc, gdim))
        slip = np.zeros((nc, gdim))
        np.add.at(force, pos, -lt[:, None] * tang)
        np.add.at(slip, pos, s[:, None] * tang)
        bound = np.full(nc, np.nan)
        bound[pos] = g
        state = np.zeros(nc, dtype=np.int8)
        state[pos] = np.where(slip_state, SLIP, STICK)
        return {"tangential_force": force, "slip": slip, "slip_bound": bound, "state": state}

    def destroy(self) -> None:
        """Free the PETSc objects."""
        if self._ub is not None:
            self._ub.destroy()
            self._ub = None
