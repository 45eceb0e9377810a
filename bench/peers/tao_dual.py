"""PETSc TAO (BQPIP, GPCG, BLMVM) against MPRGP on the same bound-constrained dual QP.

The QP is FETI's dual penalty problem (``qp="penalty"``, FETI-NCG_ρ) of
:func:`dolfinx_feti.dual_qp`: ``min 1/2 xᵀ A_ρ x − bᵀ x  s.t.  x ≥ lb`` with
``A_ρ = P F P + ρ Q`` (``Q = G̃ᵀG̃``, ρ = penalty_rho·‖PFP‖), ``lb = −λ̂`` on the inequality
rows and −inf elsewhere. Every solver gets the same ``A_ρ`` (a PETSc shell Mat), the same
``b``, bounds and start ``max(0, lb)``, and the same stopping test, implemented here and
installed as TAO's convergence test (TAO's own gatol/grtol/gttol are not used):

    ‖g^P(x)‖ ≤ rtol · ‖b‖,   g = A_ρ x − b,   g^P_i = g_i (x_i > lb_i), min(g_i, 0) (x_i = lb_i).

The test computes ``g`` itself with one multiplication that is *not* counted and whose time is
subtracted from the wall time (TAO's stored gradient is not always the one at the current
iterate, e.g. BQPIP's). F-multiplications are the calls of ``F`` through ``A_ρ`` made by the
solver (objective/gradient evaluations, Hessian products in its KSP); after each solve
``‖g^P‖/‖b‖`` is recomputed from the returned ``x``. Error = ‖x − x*‖∞/‖x*‖∞ with ``x*``
MPRGP's solution of the same QP at rtol 1e-12 (the penalty problem's own solution, not the
exact-constraint one).

BQPIP is an interior-point method: its iterates stay strictly inside the bounds, so at an
active bound ``g^P_i = g_i > 0`` stays large until ``x_i − lb_i`` is tiny, and the test above
is not met even when ``x`` is accurate. "TAO bqpip + oracle" therefore also stops as soon as
``‖x − x*‖∞/‖x*‖∞`` is at most the error MPRGP reached at the same rtol (an oracle that knows
``x*``: it favours BQPIP). A method that misses the test at one rtol (time limit, iteration
limit, error) is not run at the tighter ones.

    OMP_NUM_THREADS=1 .venv/bin/python bench/peers/tao_dual.py            # ~10 min
    OMP_NUM_THREADS=1 .venv/bin/python bench/peers/tao_dual.py --quick    # smallest sizes

Writes output/bench/tao_dual.md, output/bench/tao_dual.json and output/bench/tao_dual.png.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as C  # noqa: E402

import dolfinx_feti as df  # noqa: E402
from dolfinx_feti.qp import mprgp, projected_operator  # noqa: E402

OUT = C.ROOT / "output" / "bench"
RTOLS = (1e-4, 1e-6, 1e-8)
TAO_TYPES = ("bqpip", "gpcg", "blmvm")
#: name -> (builder, label); B1 on H = 1/4 (32 subdomains), 2D Hertz with 4 parts.
CASES = {
    "B1 n=32": (lambda: C.P.b1(32, 1 / 4), "B1, n = 32, H = 1/4"),
    "B1 n=64": (lambda: C.P.b1(64, 1 / 4), "B1, n = 64, H = 1/4"),
    "B1 n=128": (lambda: C.P.b1(128, 1 / 4), "B1, n = 128, H = 1/4"),
    "Hertz h=0.05": (lambda: C.P.hertz2d(parts=4, h_contact=0.05), "2D Hertz, h = 0.05, 4 parts"),
    "Hertz H1": (lambda: C.hertz_problem("H1", 4), "2D Hertz H1, h = 0.02, 4 parts"),
}
QUICK = ("B1 n=32", "Hertz h=0.05")


class Counted:
    """``A_ρ`` with the F-multiplications split into the solver's and the stopping test's."""

    def __init__(self, A: PETSc.Mat) -> None:
        self.A = A
        self.ctx = A.getPythonContext()
        self.test_mults = 0
        self.test_time = 0.0

    @property
    def solver_mults(self) -> int:
        return self.ctx.mults - self.test_mults

    def reset(self) -> None:
        self.ctx.mults = 0
        self.test_mults = 0
        self.test_time = 0.0


class _PlusDiagonal:
    """Python shell ``A_ρ + D`` with ``D`` a diagonal that ``MatDiagonalSet(ADD_VALUES)`` edits.

    BQPIP adds its barrier diagonal to the Hessian in place and removes it after its KSP solve;
    a plain shell of ``A_ρ`` has no diagonal to add to. Each product is one product of ``A_ρ``
    (so one F-multiplication, counted by ``A_ρ``).
    """

    def __init__(self, A: PETSc.Mat) -> None:
        self.A = A
        self.d = A.createVecRight()
        self.d.set(0.0)

    def mult(self, mat, x, y) -> None:
        self.A.mult(x, y)
        y.array[:] += self.d.array_r * x.array_r

    def setDiagonal(self, mat, D, addv) -> None:  # noqa: N802 (petsc4py's name)
        if not (addv is True or addv == PETSc.InsertMode.ADD_VALUES):  # petsc4py passes a bool
            raise NotImplementedError(f"only ADD_VALUES (got {addv}): diag(A_ρ) is not known")
        self.d.axpy(1.0, D)

    multTranspose = mult  # noqa: N815


def plus_diagonal(A: PETSc.Mat) -> PETSc.Mat:
    M = PETSc.Mat().createPython(A.getSizes(), _PlusDiagonal(A), comm=A.getComm())
    M.setUp()
    return M


def projected_gradient(x: np.ndarray, g: np.ndarray, lb: np.ndarray) -> float:
    at_l = x <= lb
    return float(np.linalg.norm(np.where(at_l, np.minimum(g, 0.0), g)))


def gradient(A: PETSc.Mat, b: PETSc.Vec, x: PETSc.Vec) -> PETSc.Vec:
    g = b.duplicate()
    A.mult(x, g)
    g.axpy(-1.0, b)
    return g


def run_mprgp(qp, op: Counted, lb: PETSc.Vec, rho: float, rtol: float, expansion: str) -> dict:
    x = qp.start()
    op.reset()
    t0 = time.perf_counter()
    res = mprgp(op.A, qp.b, x, lb=lb, rtol=rtol, norm_A=max(qp.norm_A, rho), expansion=expansion,
                max_it=200000)
    elapsed = time.perf_counter() - t0
    return {"x": x, "t": elapsed, "mults": op.solver_mults, "its": res.iterations,
            "status": res.reason, "mults_reported": res.hessian_mults}


def run_tao(qp, op: Counted, lb: PETSc.Vec, rtol: float, kind: str, time_limit: float,
            max_it: int, oracle: tuple[np.ndarray, float] | None = None) -> dict:
    A, b = op.A, qp.b
    lb_np = lb.array_r.copy()
    target = rtol * b.norm()
    x = qp.start()
    xl = lb.copy()
    xl.array[:] = np.where(np.isfinite(lb_np), lb_np, PETSc.NINFINITY)
    xu = lb.duplicate()
    xu.set(PETSc.INFINITY)
    work = b.duplicate()
    gvec = b.duplicate()
    state = {"gP": math.inf, "t0": 0.0, "timeout": False, "oracle": False}

    def objgrad(tao, X, G):
        A.mult(X, work)
        value = 0.5 * work.dot(X) - b.dot(X)
        work.copy(G)
        G.axpy(-1.0, b)
        return value

    def hessian(tao, X, H, P):
        pass  # A_ρ is constant

    def converged(tao):
        t = time.perf_counter()
        X = tao.getSolution()
        A.mult(X, work)
        work.axpy(-1.0, b)
        op.test_mults += 1
        gP = projected_gradient(X.array_r, work.array_r, lb_np)
        state["gP"] = gP
        hit = False
        if oracle is not None:
            x_ref, err_target = oracle
            hit = np.abs(X.array_r - x_ref).max() / np.abs(x_ref).max() <= err_target
        op.test_time += time.perf_counter() - t
        if gP <= target or hit:
            state["oracle"] = hit and gP > target
            tao.setConvergedReason(PETSc.TAO.Reason.CONVERGED_USER)
        elif tao.getIterationNumber() >= max_it:
            tao.setConvergedReason(PETSc.TAO.Reason.DIVERGED_MAXITS)
        elif time.perf_counter() - state["t0"] - op.test_time > time_limit:
            state["timeout"] = True
            tao.setConvergedReason(PETSc.TAO.Reason.DIVERGED_USER)
        else:
            tao.setConvergedReason(PETSc.TAO.Reason.CONTINUE_ITERATING)

    tao = PETSc.TAO().create(PETSc.COMM_SELF)
    tao.setType(kind)
    tao.setObjectiveGradient(objgrad, gvec)
    H = plus_diagonal(A) if kind == "bqpip" else A
    tao.setHessian(hessian, H, H)
    tao.setVariableBounds(xl, xu)
    tao.setMaximumIterations(max_it)
    tao.setMaximumFunctionEvaluations(10 * max_it)
    tao.setConvergenceTest(converged)
    if kind in ("gpcg", "bqpip"):
        tao.getKSP().getPC().setType("none")  # A_ρ is a shell: no diagonal, no factors
    tao.setFromOptions()
    op.reset()
    reason, error = None, None
    state["t0"] = time.perf_counter()
    try:
        tao.solve(x)
        reason = str(tao.getConvergedReason())
    except PETSc.Error as exc:
        error = f"PETSc error {exc.ierr}"
    elapsed = time.perf_counter() - state["t0"] - op.test_time
    names = {v: k for k, v in vars(PETSc.TAO.Reason).items() if not k.startswith("_")}
    status = error or names.get(int(reason), reason)
    if state["timeout"]:
        status = f"time limit {time_limit:g} s"
    elif state["oracle"]:
        status = "error oracle"
    out = {"x": x, "t": elapsed, "mults": op.solver_mults, "its": tao.getIterationNumber(),
           "status": status, "test_mults": op.test_mults}
    for o in (tao, xl, xu, work, gvec) + ((H,) if H is not A else ()):
        o.destroy()
    return out


def run_case(name: str, penalty_rho: float, rtols, time_limit: float, max_it: int) -> list[dict]:
    build, label = CASES[name]
    problem = build()
    t0 = time.perf_counter()
    qp = df.dual_qp(problem, MPI.COMM_SELF)
    t_setup = time.perf_counter() - t0
    rho = penalty_rho * qp.norm_A
    op = Counted(projected_operator(qp.feti.F, qp.constraint, rho=rho))
    lb = qp.lb
    lb_np = lb.array_r.copy()
    b_norm = qp.b.norm()
    ref = run_mprgp(qp, op, lb, rho, 1e-12, "fixed")
    x_ref = ref["x"].array_r.copy()
    scale = np.abs(x_ref).max()
    n_ineq = int(np.count_nonzero(qp.ineq))
    info = {"case": name, "label": label, "dual": int(qp.b.getSize()), "ineq": n_ineq,
            "eq": int(qp.constraint.m), "norm_A": qp.norm_A, "rho": rho,
            "t_setup": t_setup, "ref_mults": ref["mults"], "ref_status": ref["status"]}
    print(f"== {label}: dual {info['dual']} ({n_ineq} inequalities, {qp.constraint.m} "
          f"equalities), ||PFP|| {qp.norm_A:.3g}, rho {rho:.3g}, setup {t_setup:.1f} s; "
          f"reference MPRGP rtol 1e-12: {ref['mults']} F-mults ({ref['status']})", flush=True)
    rows = []
    failed = {}  # method -> the rtol it did not reach: tighter ones are not tried
    methods = ["MPRGP", "MPRGP optimal", "TAO bqpip", "TAO bqpip + oracle", "TAO gpcg",
               "TAO blmvm"]
    mprgp_err = 0.0
    for rtol in sorted(rtols, reverse=True):
        for method in methods:
            if method in failed:
                print(f"{name} rtol {rtol:.0e} {method}: not run (did not reach rtol "
                      f"{failed[method]:.0e})", flush=True)
                continue
            if method.startswith("MPRGP"):
                expansion = "optimal" if method.endswith("optimal") else "fixed"
                r = run_mprgp(qp, op, lb, rho, rtol, expansion)
            else:
                oracle = (x_ref, mprgp_err) if method.endswith("oracle") else None
                r = run_tao(qp, op, lb, rtol, method.split()[1], time_limit, max_it, oracle)
            x = r.pop("x")
            g = gradient(op.A, qp.b, x)
            gP = projected_gradient(x.array_r, g.array_r, lb_np) / b_norm
            err = float(np.abs(x.array_r - x_ref).max() / scale)
            row = {**info, "method": method, "rtol": rtol, "gP_rel": gP, "met": gP <= rtol,
                   "err": err, **r}
            rows.append(row)
            if method == "MPRGP":
                mprgp_err = err
            if not row["met"] and r["status"] != "error oracle":
                failed[method] = rtol
            print(f"{name} rtol {rtol:.0e} {method:18s}: {r['mults']:6d} F-mults, "
                  f"{r['its']:6d} its, {r['t']:7.2f} s, gP/b {gP:.1e} "
                  f"({'met' if gP <= rtol else 'NOT met'}), err {err:.1e}, {r['status']}",
                  flush=True)
            for v in (x, g):
                v.destroy()
    op.A.destroy()
    del qp
    return rows


def table(rows: list[dict]) -> str:
    out = ["| problem | dual (ineq.) | rtol | method | F-mults | iterations | time (s) | "
           "‖g^P‖/‖b‖ reached | error vs x* | returned |", "|" + "---|" * 10]
    for r in rows:
        out.append(f"| {r['label']} | {r['dual']} ({r['ineq']}) | {r['rtol']:.0e} | "
                   f"{r['method']} | {r['mults']} | {r['its']} | {r['t']:.2f} | "
                   f"{r['gP_rel']:.1e}{'' if r['met'] else ' (not met)'} | {r['err']:.1e} | "
                   f"{r['status']} |")
    return "\n".join(out)


def summary(rows: list[dict]) -> str:
    """One line per problem and rtol: F-mults (time) per method; "–" where the test was missed."""
    methods = list(dict.fromkeys(r["method"] for r in rows))
    out = ["| problem | dual (ineq.) | rtol | " + " | ".join(methods) + " |",
           "|" + "---|" * (3 + len(methods))]
    keys = list(dict.fromkeys((r["case"], r["rtol"]) for r in rows))
    for case, rtol in keys:
        rs = {r["method"]: r for r in rows if r["case"] == case and r["rtol"] == rtol}
        r0 = next(iter(rs.values()))
        cells = []
        for m in methods:
            r = rs.get(m)
            if r is None:
                cells.append("not run")
            elif r["met"] or r["status"] == "error oracle":
                cells.append(f"{r['mults']} ({r['t']:.2f} s)")
            else:
                cells.append(f"missed: {r['status']}, {r['mults']} ({r['t']:.0f} s)")
        out.append(f"| {r0['label']} | {r0['dual']} ({r0['ineq']}) | {rtol:.0e} | "
                   + " | ".join(cells) + " |")
    return "\n".join(out)


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = list(dict.fromkeys(r["case"] for r in rows))
    fig, axes = plt.subplots(1, len(cases), figsize=(4 * len(cases), 4), squeeze=False)
    colours = {"MPRGP": "C0", "MPRGP optimal": "C9", "TAO bqpip": "C1",
               "TAO bqpip + oracle": "C5", "TAO gpcg": "C2",
               "TAO blmvm": "C3"}
    for ax, case in zip(axes[0], cases, strict=True):
        rs = [r for r in rows if r["case"] == case]
        for method in colours:
            pts = sorted((r["mults"], max(r["gP_rel"], 1e-16)) for r in rs if r["method"] == method)
            if pts:
                ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-", color=colours[method],
                          label=method)
        ax.set_title(rs[0]["label"], fontsize=8)
        ax.set_xlabel("F-multiplications")
        ax.set_ylabel("‖g^P‖ / ‖b‖ reached")
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=list(CASES), choices=list(CASES))
    parser.add_argument("--quick", action="store_true", help=f"only {QUICK}")
    parser.add_argument("--rtol", nargs="*", type=float, default=list(RTOLS))
    parser.add_argument("--penalty-rho", type=float, default=1e3,
                        help="ρ relative to ||PFP|| (the library's default penalty_rho)")
    parser.add_argument("--time-limit", type=float, default=30.0, help="per TAO solve (s)")
    parser.add_argument("--max-it", type=int, default=20000, help="TAO iterations")
    parser.add_argument("--tag", default="", help="suffix of the output file names")
    parser.add_argument("--report", action="store_true",
                        help="only rewrite the tables and the plot from the JSON")
    args = parser.parse_args()
    cases = list(QUICK) if args.quick else args.cases
    name = "tao_dual" + (f"_{args.tag}" if args.tag else "")
    OUT.mkdir(parents=True, exist_ok=True)
    if args.report:
        data = json.loads((OUT / f"{name}.json").read_text())
        head, rows = data["head"], data["rows"]
    else:
        t0 = time.perf_counter()
        rows = []
        for case in cases:
            rows += run_case(case, args.penalty_rho, args.rtol, args.time_limit, args.max_it)
        head = [f"Machine: {C.P.machine()}. Code: {C.P.git_state()}. Run time "
                f"{(time.perf_counter() - t0) / 60:.1f} min. penalty_rho = "
                f"{args.penalty_rho:g}, TAO time limit {args.time_limit:g} s per solve.",
                f"Command: `OMP_NUM_THREADS=1 python {' '.join(sys.argv)}`"]
        (OUT / f"{name}.json").write_text(json.dumps({"head": head, "rows": rows}, indent=1,
                                                     default=float))
    md = ["# TAO against MPRGP on the dual penalty QP", "", *head, "",
          "F-multiplications (time) to ‖g^P‖ ≤ rtol‖b‖:", "", summary(rows), "",
          "All runs:", "", table(rows)]
    (OUT / f"{name}.md").write_text("\n".join(md) + "\n")
    plot(rows, OUT / f"{name}.png")
    print("\n".join(md))
    print(f"wrote {OUT}/{name}.md, .json, .png")


if __name__ == "__main__":
    main()
