"""The coarse problem alone: set-up and one projection, dense against sparse.

The FETI natural coarse space G = Rᵀ Bᵀ of a Cartesian lattice of subdomains
(``tests/support/coarse_lattice.py``: the library's gluing and Dirichlet rows and rigid modes, one
face
clamped, 2 cells per subdomain and direction) at about 10², 10³ and 10⁴ subdomains, with the 2D
(k = 3) and 3D (k = 6) elasticity kernels; scalar kernels (k = 1) with ``--kernels 2s,3s``.

- set-up: ``orthonormalize`` (forming G Gᵀ, replicated, and factoring it);
- projection: one ``Projector.apply`` (local Gx, one Allreduce of m numbers, T, Tᵀ, local Gᵀy);
  median of ``--repeat`` applications.

"dense" is the route used before (G Gᵀ dense, LAPACK Cholesky, explicit L⁻¹ up to 1024 rows,
triangular solves above); "sparse" the sparse Cholesky. Dense runs whose matrices would not fit
in ``--dense-mem`` GB (three m × m arrays) are not run; the table then shows the O(m³) / O(m²)
extrapolation from the largest measured dense run of the same kernel, marked "~".

    python bench/coarse_problem.py                        # the table (a few minutes)
    python bench/coarse_problem.py --crossover            # dense vs sparse over m (DENSE_MAX)
    mpirun -n 2 python bench/coarse_problem.py --sizes 2  # the same with the rows on 2 ranks
    # the inputs of docs/benchmarks_history.md § 11.6 (1 000 ranks on paper):
    python bench/coarse_problem.py --kernels 3 --ns 10 20 --methods sparse
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "support"))
from coarse_lattice import lattice_gt  # noqa: E402

from dolfinx_feti.qp import Projector, RowBlockConstraint, orthonormalize  # noqa: E402

COMM = MPI.COMM_WORLD
#: kernel → (dim, value size, subdomains per direction for ~10², 10³, 10⁴ subdomains)
KERNELS = {"2": (2, 2, (10, 32, 100)), "3": (3, 3, (5, 10, 22)),
           "2s": (2, 1, (10, 32, 100)), "3s": (3, 1, (5, 10, 22))}
K_OF = {"2": 3, "3": 6, "2s": 1, "3s": 1}


def constraint(Gt) -> tuple[RowBlockConstraint, PETSc.Vec]:
    n = Gt.shape[0]
    x = PETSc.Vec().createMPI((PETSc.DECIDE, n), comm=COMM)
    lo, hi = x.getOwnershipRange()
    x.array[:] = np.random.default_rng(0).standard_normal(n)[lo:hi]
    return RowBlockConstraint(Gt[lo:hi], COMM), x


def vm_hwm_mib() -> float:
    """Peak resident set size of this process so far (MiB)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def measure(Gt, method: str, repeat: int) -> dict:
    con, x = constraint(Gt)
    COMM.Barrier()
    hwm = vm_hwm_mib()
    t0 = time.perf_counter()
    ocon = orthonormalize(con, method=method)
    setup = COMM.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    growth = COMM.allreduce(vm_hwm_mib() - hwm, op=MPI.MAX)
    proj, out = Projector(ocon), x.duplicate()
    times = []
    for _ in range(repeat):
        COMM.Barrier()
        t0 = time.perf_counter()
        proj.apply(x, out)
        times.append(COMM.allreduce(time.perf_counter() - t0, op=MPI.MAX))
    return {"setup": setup, "projection": float(np.median(times)), "peak_growth_MiB": growth,
            "Px": out.copy(), "method": ocon.method}


def run(kernel: str, ns: int, methods, repeat: int, dense_mem: float) -> dict:
    dim, bs, _ = KERNELS[kernel]
    t0 = time.perf_counter()
    Gt = lattice_gt(ns, dim, value_size=bs)
    m = Gt.shape[1]
    row = {"kernel": kernel, "subdomains": ns**dim, "m": m, "dual": Gt.shape[0],
           "gram_nnz": int((Gt.T @ Gt).nnz), "build": time.perf_counter() - t0}
    results = {}
    for method in methods:
        if method == "dense" and 3 * 8 * m * m > dense_mem * 1e9:
            continue
        results[method] = measure(Gt, method, repeat)
        row[method] = {k: v for k, v in results[method].items()
                       if k in ("setup", "projection", "peak_growth_MiB")}
    if len(results) == 2:
        a, b = results["dense"]["Px"], results["sparse"]["Px"]
        d = a.copy()
        d.axpy(-1.0, b)
        row["rel_diff"] = d.norm() / a.norm()
    return row


def fmt_time(t: float) -> str:
    return f"{t * 1e3:.3g} ms" if t < 1 else f"{t:.3g} s"


def table(rows: list[dict]) -> str:
    lines = ["| kernel | subdomains | m | nnz(GGᵀ) | dense set-up | dense projection | "
             "sparse set-up | sparse projection | ‖P_d x − P_s x‖/‖P_d x‖ |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for kernel in dict.fromkeys(r["kernel"] for r in rows):
        ks = [r for r in rows if r["kernel"] == kernel]
        ref = max((r for r in ks if "dense" in r), key=lambda r: r["m"], default=None)
        for r in ks:
            if "dense" in r:
                ds, dp = fmt_time(r["dense"]["setup"]), fmt_time(r["dense"]["projection"])
            elif ref is not None:  # extrapolated, O(m³) and O(m²)
                q = r["m"] / ref["m"]
                ds = "~" + fmt_time(ref["dense"]["setup"] * q**3)
                dp = "~" + fmt_time(ref["dense"]["projection"] * q**2)
                ds += f" ({8 * r['m'] ** 2 / 1e9:.0f} GB/matrix)"
            else:
                ds = dp = "—"
            sp_ = r.get("sparse", {})
            lines.append(
                f"| {'2D' if kernel[0] == '2' else '3D'} k={K_OF[kernel]} | {r['subdomains']} | "
                f"{r['m']} | {r['gram_nnz']} | {ds} | {dp} | "
                f"{fmt_time(sp_['setup']) if sp_ else '—'} | "
                f"{fmt_time(sp_['projection']) if sp_ else '—'} | "
                f"{r['rel_diff']:.1e} |" if "rel_diff" in r else
                f"| {'2D' if kernel[0] == '2' else '3D'} k={K_OF[kernel]} | {r['subdomains']} | "
                f"{r['m']} | {r['gram_nnz']} | {ds} | {dp} | "
                f"{fmt_time(sp_['setup']) if sp_ else '—'} | "
                f"{fmt_time(sp_['projection']) if sp_ else '—'} | — |")
    return "\n".join(lines)


def crossover(repeat: int, projections: int) -> str:
    """Dense vs sparse around DENSE_MAX: set-up, projection, set-up + n projections."""
    lines = [f"| kernel | subdomains | m | dense set-up | sparse set-up | dense proj. | "
             f"sparse proj. | dense + {projections} proj. | sparse + {projections} proj. |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for kernel, sizes in (("2", (4, 6, 8, 12, 16, 20, 26)), ("3", (2, 3, 4, 5, 6, 7, 8)),
                          ("2s", (8, 16, 24, 32, 45))):
        for ns in sizes:
            r = run(kernel, ns, ("dense", "sparse"), repeat, 1e9)
            d, s = r["dense"], r["sparse"]
            lines.append(
                f"| {kernel} | {r['subdomains']} | {r['m']} | {fmt_time(d['setup'])} | "
                f"{fmt_time(s['setup'])} | {fmt_time(d['projection'])} | "
                f"{fmt_time(s['projection'])} | "
                f"{fmt_time(d['setup'] + projections * d['projection'])} | "
                f"{fmt_time(s['setup'] + projections * s['projection'])} |")
            if COMM.rank == 0:
                print(lines[-1], flush=True)
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kernels", default="2,3", help="comma-separated: 2, 3, 2s, 3s")
    ap.add_argument("--sizes", default="0,1,2", help="indices into 10², 10³, 10⁴ subdomains")
    ap.add_argument("--ns", nargs="*", type=int, default=None,
                    help="subdomains per direction (instead of --sizes)")
    ap.add_argument("--methods", default="dense,sparse")
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--dense-mem", type=float, default=6.0,
                    help="GB: skip dense runs needing more (three m×m arrays)")
    ap.add_argument("--crossover", action="store_true")
    ap.add_argument("--projections", type=int, default=500,
                    help="projections per solve in the crossover table")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    if args.crossover:
        text = crossover(args.repeat, args.projections)
    else:
        rows = []
        for kernel in args.kernels.split(","):
            sizes = args.ns or [KERNELS[kernel][2][int(i)] for i in args.sizes.split(",")]
            for ns in sizes:
                r = run(kernel, ns, args.methods.split(","), args.repeat, args.dense_mem)
                rows.append(r)
                if COMM.rank == 0:
                    print(json.dumps(r), flush=True)
        text = table(rows)
        if args.json and COMM.rank == 0:
            args.json.write_text(json.dumps(rows, indent=1))
    if COMM.rank == 0:
        print(f"\n{COMM.size} rank(s)\n\n{text}")


if __name__ == "__main__":
    main()
