"""Hessian-multiplication counts of MPRGP / SMALBE variants (not a test; run it by hand).

    .venv/bin/python tests/qp/bench_qp_variants.py [--quick]

Prints one markdown table per problem: the step-length rule of the expansion (``alpha``), the
expansion variant and the preconditioner against multiplications by the Hessian, iterations,
step counts and the error against a reference solution.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from petsc4py import PETSc

sys.path.insert(0, str(Path(__file__).parent))
from qp_helpers import (  # noqa: E402
    Diagonal,
    gather,
    make_mat,
    make_vec,
    obstacle,
    random_spd,
    ref_box,
    scaled,
)

from dolfinx_feti.qp import mprgp  # noqa: E402


def pc_of(A: PETSc.Mat, kind: str) -> PETSc.PC:
    pc = PETSc.PC().create(comm=A.getComm())
    pc.setOperators(A)
    if A.getComm().getSize() > 1 and kind in ("icc", "cholesky"):
        pc.setType("bjacobi")
        pc.setUp()
        for sub in pc.getBJacobiSubKSP():
            sub.getPC().setType(kind)
    else:
        pc.setType(kind)
    pc.setUp()
    return pc


def dense_box(n: int = 300, seed: int = 0, cond: float = 1e3, kind: str = "box"):
    rng = np.random.default_rng(seed)
    A = random_spd(n, rng, cond=cond)
    b = 3.0 * rng.standard_normal(n)
    l, u = np.full(n, -0.3), np.full(n, 0.4)
    if kind == "mixed":
        which = rng.integers(0, 4, n)
        l[which == 0], u[which == 0] = -np.inf, np.inf
        u[which == 1] = np.inf
        l[which == 2] = -np.inf
    return A, b, l, u


def run(A, b, l, u, ref, *, rtol, expansion="fixed", alpha="fixed", precond=None, norm_A=None):
    Am = make_mat(A)
    x = make_vec(np.clip(np.zeros_like(b), l, u))
    M = None
    if precond == "jacobi":
        M = Diagonal(1.0 / np.asarray(A.diagonal()), x)
    elif precond in ("icc", "cholesky"):
        M = pc_of(Am, precond)
    t0 = time.perf_counter()
    res = mprgp(Am, make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=rtol,
                expansion=expansion, alpha=alpha, preconditioner=M, norm_A=norm_A)
    dt = time.perf_counter() - t0
    xs = gather(x)
    err = np.linalg.norm(xs - ref) / np.linalg.norm(ref)
    return res, err, dt


VARIANTS = [
    ("fixed", "fixed", None), ("fixed", "bb", None), ("optimal", "fixed", None),
    ("projcg", "fixed", None),
]


def table(name, A, b, l, u, ref, rtols, variants, norm_A):
    print(f"\n### {name}\n")
    print("| rtol | expansion | alpha | precond | mults | its | cg/exp/prop | rejected | "
          "precond | rel. error | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for rtol in rtols:
        for expansion, alpha, precond in variants:
            res, err, dt = run(A, b, l, u, ref, rtol=rtol, expansion=expansion, alpha=alpha,
                               precond=precond, norm_A=norm_A)
            c = res.counts
            flag = "" if res.converged else f" ({res.reason})"
            print(f"| {rtol:g} | {expansion} | {alpha} | {precond or '-'} | "
                  f"{res.hessian_mults}{flag} | {res.iterations} | "
                  f"{c['cg']}/{c['expansion']}/{c['proportioning']} | {c.get('rejected', '-')} | "
                  f"{c.get('precond', '-')} | {err:.1e} | {dt:.2f} |")


def main(quick: bool = False) -> None:
    rtols = [1e-6, 1e-10]
    pre = [("fixed", "fixed", "jacobi"), ("fixed", "bb", "jacobi")]
    # Test problems of tests/qp (n = 60, cond 50) and the larger ones.
    from test_qp_mprgp import box_problem  # noqa: PLC0415

    for kind in ("lower", "box", "mixed"):
        A, b, l, u = box_problem(kind, seed=1)
        lam = float(np.linalg.eigvalsh(A).max())
        table(f"box_problem('{kind}'), n = 60", A, b, l, u, ref_box(A, b, l, u), rtols,
              VARIANTS, lam)
    A, b, l, u = dense_box(300)
    lam = float(np.linalg.eigvalsh(A).max())
    table("dense n = 300, cond 1e3, box", A, b, l, u, ref_box(A, b, l, u), rtols,
          VARIANTS + pre, lam)
    rng = np.random.default_rng(5)
    As = scaled(A, rng)
    lam = float(np.linalg.eigvalsh(As).max())
    table("dense n = 300, scaled S A S (S over 2 decades), box", As, b, l, u,
          ref_box(As, b, l, u), rtols, VARIANTS + pre, lam)
    smalbe_tables(rtols)
    if quick:
        return
    A, b, l, u = obstacle(80)
    lam = float(sp.linalg.eigsh(A, k=1, which="LA", return_eigenvectors=False)[0])
    ref = gather(make_vec(np.zeros_like(b)))
    x = make_vec(np.maximum(0.0, l))
    mprgp(make_mat(A), make_vec(b), x, lb=make_vec(l), rtol=1e-13, norm_A=lam)
    ref = gather(x)
    print(f"\nobstacle: active at the solution {int(np.sum(ref <= l))} of {len(b)}")
    table("obstacle 80 x 80", A, b, l, u, ref, rtols,
          VARIANTS + pre + [("fixed", "fixed", "icc"), ("fixed", "bb", "icc"),
                            ("fixed", "fixed", "cholesky"), ("fixed", "bb", "cholesky")], lam)


def smalbe_table(name, F, G, e, d, lower, feasible, rtols) -> None:
    from qp_helpers import ref_active_set  # noqa: PLC0415
    from test_qp_smalbe import solve_feti_like  # noqa: PLC0415

    ref = ref_active_set(F, d, lower, np.full(len(d), np.inf), G, e, x0=feasible)
    print(f"\n### SMALBE, {name}\n")
    print("| rtol | alpha | precond (form) | F-mults | outer | inner its | precond | rel. error |")
    print("|---|---|---|---|---|---|---|---|")
    for rtol in rtols:
        for alpha in ("fixed", "bb"):
            for pc in (None, "projected", "plain"):
                kw = {}
                if pc is not None:
                    kw = {"preconditioner": Diagonal(1.0 / np.diag(F), make_vec(d)),
                          "preconditioner_form": pc}
                lam, res, ctx, _ = solve_feti_like(F, G, e, d, lower, rtol=rtol,
                                                   inner_options={"alpha": alpha}, **kw)
                err = np.linalg.norm(lam - ref) / np.linalg.norm(ref)
                flag = "" if res.converged else f" ({res.reason})"
                print(f"| {rtol:g} | {alpha} | {'-' if pc is None else 'jacobi, ' + pc} | "
                      f"{res.hessian_mults}{flag} | {res.outer_iterations} | {res.iterations} | "
                      f"{res.counts.get('precond', '-')} | {err:.1e} |")


def smalbe_tables(rtols) -> None:
    from test_qp_smalbe import feti_like  # noqa: PLC0415

    smalbe_table("FETI-like n = 80, m = 8 (tests)", *feti_like(seed=0), rtols)
    F, G, e, d, lower, feasible = feti_like(seed=0, n=300, m=20)
    smalbe_table("FETI-like n = 300, m = 20", F, G, e, d, lower, feasible, rtols)
    Fs = scaled(F, np.random.default_rng(11), decades=1.5)
    smalbe_table("FETI-like n = 300, m = 20, scaled S F S (1.5 decades)", Fs, G, e, d, lower,
                 feasible, rtols)


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
