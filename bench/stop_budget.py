"""Where the F-multiplications of a KKT-stopped solve go: runs, outer iterations, which bound.

Each SMALBE outer iteration records the stop's two bounds (``qp/smalbe.py``: ``test_gP`` the
weighted projected gradient ``max_i |gᴾ_i| / scale_i`` against ``test_tol``, ‖G̃x‖ against
``eq_tol``; ``drivers/kkt_stop.py``). Per solve of B1, 2D Hertz (mortar, ``Parts(4)``) and the
rigid sphere S1 (``Parts(4)``) — the problems of ``bench/rtol_accuracy.py`` — this prints the
F-multiplications (those of the checks before the last included), the KKT checks, each run's
F-multiplications, those spent in outer iterations that followed one whose gradient already
met its bound (only ‖G̃x‖ was left: what the bound of ‖G̃x‖ costs), and each check's largest
residual against rtol (the last one: the accepted solution; far below 1: over-solved).

``--variant`` swaps the bound of ‖G̃x‖ (a measuring aid that replaces methods of
``drivers/kkt_stop.KKTStop`` and, for ``keep_m``, of SMALBE's private solve state; the library
is unchanged):

- ``current``: the library's, ``min(rtol Λ, tol_g / unit)`` with the unit ``‖PFP‖ max_i
  1/scale_i`` until a check, then measured from the check;
- ``force``: ``rtol Λ`` only (no length unit: the loosest bound the equilibrium allows);
- ``none``: ‖G̃x‖ not tested (the exact check alone guards it);
- ``exact``: after a failed check the unit of the stop's own G̃x in the lengths,
  ``max_i |(P F G̃ᵀ G̃x)_i| / scale_i / ‖G̃x‖`` (one more F-multiplication per failed check,
  counted), instead of the measured one;
- ``safety1``: the current bound, but a failed check aims the next bound at what would just
  pass (``kkt_stop.SAFETY`` 1 instead of 0.5);
- ``keep_m``: the current bound, and a run after a failed check starts SMALBE from the inner
  precision factor M the run before ended with (not from the option's M);
- ``lengths``: the gradient bound in lengths only (the library before history § 33: no force
  part on the contact rows, ``kkt_stop.KKTStop.forces`` None; the before of § 33).

Run: ``python bench/stop_budget.py`` (seconds; ``--problems hertz --methods fetidp --rtols
1e-6 --trace`` prints every outer iteration, ``--units`` with it the unit of each iterate's
G̃x against the stop's); ``python bench/stop_budget.py --variant force
--run bench/reuse.py --case hertz2d --method auto --cases 0`` runs another bench script with
the variant installed.
"""

from __future__ import annotations

import argparse
import importlib
import math
import runpy
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx_feti as df

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import rtol_accuracy as RA  # noqa: E402  (its problems)

KS = importlib.import_module("dolfinx_feti.drivers.kkt_stop")
VARIANTS = ("current", "force", "none", "exact", "safety1", "keep_m", "lengths")
SM = importlib.import_module("dolfinx_feti.qp.smalbe")
QS = importlib.import_module("dolfinx_feti.drivers.qp_solve")


def install(variant: str) -> None:
    """Replace the bound of ‖G̃x‖ of :class:`KKTStop` by ``variant`` (module docstring)."""
    stop = KS.KKTStop
    if variant == "safety1":
        KS.SAFETY = 1.0
    if variant in ("force", "none"):
        make_test = stop.make_test

        def loose(self, loosen: float = 1.0):
            test = make_test(self, loosen)
            test.eq_tol = math.inf if variant == "none" else self.rtol * self.Lam * loosen
            return test
        stop.make_test = loose
    if variant == "keep_m":
        last = {"M": None}
        solve_init, result, runs_init = (SM._SMALBESolve.__init__, SM._SMALBESolve._result,
                                         QS._KKTRuns.__init__)

        def start_m(self, *args, **kwargs):
            solve_init(self, *args, **kwargs)
            if last["M"] is not None and self.test is not None:
                self.M = last["M"]

        def end_m(self, reason, res):
            last["M"] = self.M
            return result(self, reason, res)

        def new_solve(self, *args, **kwargs):
            last["M"] = None
            runs_init(self, *args, **kwargs)
        SM._SMALBESolve.__init__, SM._SMALBESolve._result = start_m, end_m
        QS._KKTRuns.__init__ = new_solve
    if variant == "lengths":
        init = stop.__init__

        def lengths_only(self, qp, *args, **kwargs):
            init(self, qp, *args, **kwargs)
            self.forces = None
        stop.__init__ = lengths_only
    if variant == "exact":
        init, accept = stop.__init__, stop.accept

        def keep_qp(self, qp, *args, **kwargs):
            init(self, qp, *args, **kwargs)
            self.qp = qp

        def exact_unit(self, kkt, u, lam_qp, Dx_norm):
            done = accept(self, kkt, u, lam_qp, Dx_norm)
            if done or self.stalled or not Dx_norm:
                return done
            qp = self.qp
            con = qp.constraint
            v = con.mult(lam_qp) - con.mult(qp.lam_hat)  # G̃x (λ = λ̂ + x)
            t, s, ps = lam_qp.duplicate(), lam_qp.duplicate(), lam_qp.duplicate()
            con.mult_transpose(v, t)
            qp.feti.F.mult(t, s)  # counted among the F-multiplications
            qp.projector.apply(s, ps)
            term = self.comm.allreduce(float(np.max(np.abs(ps.array_r) * self.weight,
                                                    initial=0.0)), op=MPI.MAX)
            for w in (t, s, ps):
                w.destroy()
            self.eq_unit = max(term / max(float(np.linalg.norm(v)), 1e-300), 1e-300)
            self.tol_e = min(self.rtol * self.Lam, self.tol_g / self.eq_unit)
            return done
        stop.__init__, stop.accept = keep_qp, exact_unit


def probe_units() -> None:
    """Record in each SMALBE outer record the unit of its own G̃x in the lengths.

    ``unit`` = ``max_i |(P F G̃ᵀ G̃x)_i| / scale_i / ‖G̃x‖``, beside the one the stop uses
    (``eq_unit``): one more F-multiplication per outer iteration, counted (the counts of the
    solve are then not the library's).
    """
    current = {}
    stop_init, outer_update = KS.KKTStop.__init__, SM._SMALBESolve._outer_update

    def keep(self, qp, *args, **kwargs):
        stop_init(self, qp, *args, **kwargs)
        current["stop"], current["qp"] = self, qp

    def measure(self, k, M_k, res):
        reason = outer_update(self, k, M_k, res)
        rec, stop, qp = self.history[-1], current.get("stop"), current.get("qp")
        if stop is None or self.test is None or rec["Dx"] <= 0:
            return reason
        t, s, ps = qp.b.duplicate(), qp.b.duplicate(), qp.b.duplicate()
        self.D.mult_transpose(self.D.mult(self.x), t)
        qp.feti.F.mult(t, s)
        qp.projector.apply(s, ps)
        term = stop.comm.allreduce(float(np.max(np.abs(ps.array_r) * stop.weight,
                                                initial=0.0)), op=MPI.MAX)
        for w in (t, s, ps):
            w.destroy()
        rec.update(unit=term / rec["Dx"], eq_unit=stop.eq_unit, rows=self.D.m)
        return reason
    KS.KKTStop.__init__, SM._SMALBESolve._outer_update = keep, measure


def runs_of(history: list[dict]) -> list[list[dict]]:
    """The SMALBE outer records split into runs (``k`` restarts at 0 after a check)."""
    runs: list[list[dict]] = []
    for rec in history:
        if rec.get("k", 0) == 0 or not runs:
            runs.append([])
        runs[-1].append(rec)
    return runs


def equality_only(run: list[dict]) -> int:
    """F-multiplications of outer iterations after one whose gradient met its bound."""
    return sum(run[i]["hessian_mults"] for i in range(1, len(run))
               if run[i - 1].get("test_gP", math.inf) <= run[i - 1].get("test_tol", 0.0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", default="b1,hertz,sphere")
    ap.add_argument("--methods", default=",".join(RA.METHODS))
    ap.add_argument("--rtols", default="1e-4,1e-6,1e-8")
    ap.add_argument("--variant", default="current", choices=VARIANTS)
    ap.add_argument("--trace", action="store_true", help="every outer iteration")
    ap.add_argument("--units", action="store_true",
                    help="with --trace: the unit of each iterate's G̃x (one more F each)")
    ap.add_argument("--run", nargs=argparse.REMAINDER,
                    help="another bench script and its arguments, run with the variant")
    args = ap.parse_args()
    install(args.variant)
    if args.units:
        probe_units()
    if args.run:
        sys.argv = args.run
        runpy.run_path(args.run[0], run_name="__main__")
        return
    comm = MPI.COMM_WORLD
    make = {"b1": lambda: RA.b1(16), "hertz": lambda: RA.hertz(4),
            "sphere": lambda: RA.sphere("S1", 4)}
    say = print if comm.rank == 0 else (lambda *a, **k: None)
    say(f"variant {args.variant}, {comm.size} rank(s)")
    say("| problem | method | rtol | F | checks | F per run | F for ‖G̃x‖ alone | "
        "checks' largest residual / rtol |\n|---|---|---|---|---|---|---|---|")
    total = {"F": 0, "eq": 0}
    for name in args.problems.split(","):
        problem = make[name]()
        for method in args.methods.split(","):
            for rtol in (float(r) for r in args.rtols.split(",")):
                sol = df.solve(problem, comm=comm, method=method, rtol=rtol)
                rep = sol.report
                history = comm.bcast(rep.extra.get("history", []), root=0)
                if len(history) >= 50:
                    say("  (the report keeps the last 50 outer iterations only)")
                runs = [r for r in runs_of(history) if "test_gP" in r[0]]
                eq = sum(equality_only(r) for r in runs)
                total["F"] += rep.hessian_mults
                total["eq"] += eq
                checks = ", ".join(f"{h['primal'] / rtol:.2g}"
                                   for h in rep.stopping.get("history", []))
                per_run = " + ".join(str(sum(rec["hessian_mults"] for rec in r))
                                     for r in runs) or "–"
                say(f"| {name} | {method} | {rtol:.0e} | {rep.hessian_mults} | "
                    f"{rep.stopping.get('checks', 0)} | {per_run} | {eq} | {checks} |",
                    flush=True)
                if args.trace:
                    for rec in history:
                        say(f"    outer {rec['k']:2d}: F {rec['hessian_mults']:3d}  gradient "
                            f"{rec.get('test_gP', math.nan) / rec.get('test_tol', 1.0):9.3g} "
                            f"x bound  ‖G̃x‖ {rec['Dx'] / rec.get('eq_tol', 1.0):9.3g} x bound"
                            f"  ({rec['inner_reason']})" + (
                                f"  unit {rec['unit']:.3g} (the stop's {rec['eq_unit']:.3g},"
                                f" {rec['rows']} rows)" if "unit" in rec else ""))
    say(f"total: {total['F']} F-multiplications, {total['eq']} of them "
        f"({100 * total['eq'] / max(total['F'], 1):.1f} %) for ‖G̃x‖ alone")
    PETSc.garbage_cleanup()


if __name__ == "__main__":
    main()
