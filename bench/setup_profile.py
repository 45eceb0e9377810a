"""From gmsh to solution on the seed's headline problem, phase by phase, against a direct solve.

B1 (Dostál's two membranes) with H/h = 128 and H = 1/8: 2 × 1024² squares, 2 130 048 primal
dofs, 128 subdomains, rtol 1e-6, the library's default solver. Phases:

- ``gmsh model``: ``meshes.membranes(n)`` (rank 0, in a gmsh session);
- ``read_gmsh``: the model into MeshData arrays, checked, broadcast;
- the solve's own phases (``report.timings``: decomposition, assembly, factorization,
  constraints, dual operators, coarse problem, preconditioner, iterations, recovery) and
  ``other`` = the wall time of ``solve`` not in a phase (the KKT check, the Solution);
- the *direct solve* of the same mesh, measured right after in the same process on rank 0:
  the undecomposed problem with the two membranes glued at the contact nodes (u_left =
  u_right there, so the matrix is SPD), assembled by DOLFINx (``tests/reference.assemble``),
  Dirichlet dofs eliminated, one sparse Cholesky (CHOLMOD) factorization and solve. Its
  "gmsh to solution" is gmsh model + read_gmsh + assembly + factor/solve.

Every phase is the maximum over the ranks. ``--repeat r`` runs the whole sequence r times and
reports each phase's median. ``--n`` and ``--H`` pick another size (n squares per membrane
side, H×H subdomains). The last line gives each rank's peak resident set size (VmHWM) after
the FETI solve and at the end (after the direct solve, which runs on rank 0).

    mpirun -n 2 python bench/setup_profile.py               # ~2 min per repeat on 2 cores
    mpirun -n 2 python bench/setup_profile.py --repeat 3 --json output/bench/setup.json
    mpirun -n 2 python bench/setup_profile.py --root-only   # the mesh on rank 0 only
    mpirun -n 2 python bench/setup_profile.py --distribute  # no rank holds the whole mesh
    mpirun -n 2 python bench/setup_profile.py --method fetidp --distribute  # FETI-DP's set-up
    PYTHONPATH=/path/to/other/export mpirun -n 2 python bench/setup_profile.py   # A/B

An export older than the test suite's current reference assembly (``tests/support/reference.py``
needs this tree's ``compat``) runs with ``--no-direct``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

ROOT = Path(__file__).resolve().parent.parent
for _p in (ROOT / "bench", ROOT / "tests" / "support"):
    sys.path.insert(0, str(_p))
import reference as ref  # noqa: E402
from memory_scaling import vm_hwm_mib  # noqa: E402

import dolfinx_feti as df  # noqa: E402
import problems as P  # noqa: E402
from dolfinx_feti.io import meshes  # noqa: E402

COMM = MPI.COMM_WORLD
BEFORE_ITERATIONS = ("problem (checks)", "decomposition", "distribution", "assembly",
                     "factorization", "constraints", "dual operators", "coarse problem",
                     "preconditioner")


def code_state() -> str:
    """The commit measured: this tree's, or that of a ``git archive`` export on PYTHONPATH."""
    pkg = Path(df.__file__).resolve().parent
    stamp = pkg.parent / "COMMIT"
    if pkg.parent != ROOT and stamp.exists():
        return f"export of {stamp.read_text().strip()} ({pkg})"
    return P.git_state()


def tmax(t0: float) -> float:
    return COMM.allreduce(time.perf_counter() - t0, op=MPI.MAX)


def build_mesh(n: int, replicate: bool = True, distribute: bool = False
               ) -> tuple[df.MeshData, dict[str, float]]:
    import gmsh

    COMM.Barrier()
    t0 = time.perf_counter()
    if COMM.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        meshes.membranes(n)
    t_model = tmax(t0)
    t0 = time.perf_counter()
    # an export of a commit older than these options takes the default input
    mode = {} if replicate and not distribute else {"replicate": replicate,
                                                    "distribute": distribute}
    mesh = df.read_gmsh(None, COMM, **mode)
    t_read = tmax(t0)
    if COMM.rank == 0:
        gmsh.finalize()
    return mesh, {"gmsh model": t_model, "read_gmsh": t_read}


def feti(mesh: df.MeshData, H: float, rtol: float, method: str | None = None
         ) -> tuple[dict[str, float], dict]:
    COMM.Barrier()
    t0 = time.perf_counter()
    problem = df.ContactProblem(
        mesh, df.Poisson(source=P.b1_source), dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")], decomposition=P.grid(H))
    t_problem = tmax(t0)
    COMM.Barrier()
    t0 = time.perf_counter()
    # an export of a commit older than the method option takes the default
    sol = df.solve(problem, rtol=rtol, **({} if method is None else {"method": method}))
    wall = tmax(t0)
    rep = sol.report
    phases = {"problem (checks)": t_problem}
    phases.update({k: v for k, v in rep.timings.items() if k != "total"})
    phases["other"] = wall - sum(phases.values()) + t_problem
    info = {"primal": rep.sizes["primal"], "dual": rep.sizes["dual"],
            "subdomains": rep.sizes["subdomains"], "converged": rep.converged,
            "outer": rep.outer_iterations, "mults": rep.hessian_mults, "wall": wall,
            "u_max": None}
    if hasattr(sol, "nodal_values_on_root"):  # collective; the whole array on rank 0 only
        nodal = sol.nodal_values_on_root()
    else:  # an export of an older commit: every rank the whole array
        nodal = sol.nodal_values()
    info["u_max"] = COMM.bcast(None if nodal is None else float(np.abs(nodal).max()), root=0)
    del nodal
    del sol
    return phases, info


def direct(mesh: df.MeshData) -> dict[str, float]:
    """The glued, undecomposed problem: DOLFINx assembly + one CHOLMOD factor and solve."""
    from petsc4py import PETSc

    t0 = time.perf_counter()
    K, f = ref.assemble(mesh, 1, ref.poisson_forms(ref.membrane_source))
    pairs = ref.match_pairs(mesh, "contact_left", "contact_right", (1,), 1, None)
    n = K.shape[0]
    target = np.arange(n)
    target[pairs.slave] = pairs.master
    fixed = ref.dirichlet_dofs(mesh, 1, [("dirichlet", None)])
    keep = np.setdiff1d(np.arange(n), pairs.slave)
    keep = keep[~fixed[keep]]
    col = np.full(n, -1)
    col[keep] = np.arange(keep.size)
    ok = col[target] >= 0
    glue = sp.csr_matrix((np.ones(ok.sum()), (np.flatnonzero(ok), col[target][ok])),
                         shape=(n, keep.size))
    A = (glue.T @ K @ glue).tocsr()
    b = glue.T @ f
    A.sort_indices()
    t_assembly = time.perf_counter() - t0
    t0 = time.perf_counter()
    M = PETSc.Mat().createAIJ(size=A.shape, csr=(A.indptr.astype(PETSc.IntType),
                                                 A.indices.astype(PETSc.IntType), A.data),
                              comm=PETSc.COMM_SELF)
    M.setOption(PETSc.Mat.Option.SPD, True)
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    ksp.setOperators(M)
    ksp.setType("preonly")
    ksp.getPC().setType("cholesky")
    ksp.getPC().setFactorSolverType("cholmod")
    bv = PETSc.Vec().createWithArray(np.ascontiguousarray(b), comm=PETSc.COMM_SELF)
    x = bv.duplicate()
    ksp.solve(bv, x)
    t_solve = time.perf_counter() - t0
    res = np.linalg.norm(A @ x.array_r - b) / np.linalg.norm(b)
    for o in (ksp, M, bv, x):
        o.destroy()
    return {"direct assembly": t_assembly, "direct factor+solve": t_solve,
            "direct residual": float(res), "direct dofs": int(keep.size)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1024, help="squares per membrane side")
    ap.add_argument("--H", type=float, default=1 / 8, help="subdomain size")
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--no-direct", action="store_true")
    ap.add_argument("--root-only", action="store_true",
                    help="read_gmsh(replicate=False): the mesh's arrays on rank 0 only")
    ap.add_argument("--distribute", action="store_true",
                    help="read_gmsh(distribute=True): every rank a block of cells (the direct "
                         "solve then reads its own copy on rank 0, after FETI)")
    ap.add_argument("--method", default=None,
                    help="the FETI method (dual_qp's method; default: the solver's default)")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()
    runs = []
    for _ in range(args.repeat):
        mesh, times = build_mesh(args.n, not args.root_only, args.distribute)
        phases, info = feti(mesh, args.H, args.rtol, args.method)
        times.update(phases)
        info["peak MiB after FETI"] = COMM.allgather(vm_hwm_mib())
        if not args.no_direct:
            if args.distribute:  # the direct solve needs the whole mesh on rank 0
                del mesh
                mesh, _ = build_mesh(args.n, replicate=False)
            d = direct(mesh) if COMM.rank == 0 else None
            d = COMM.bcast(d, root=0)
            info.update({k: d.pop(k) for k in ("direct residual", "direct dofs")})
            times.update(d)
        info["peak MiB at end"] = COMM.allgather(vm_hwm_mib())
        runs.append((times, info))
        del mesh
        if COMM.rank == 0:
            print(json.dumps({"times": times, "info": info}), flush=True)
    med = {k: float(np.median([t[k] for t, _ in runs])) for k in runs[0][0]}
    info = runs[0][1]
    setup = sum(med.get(k, 0.0) for k in BEFORE_ITERATIONS)
    mesh_t = med["gmsh model"] + med["read_gmsh"]
    solve_total = sum(v for k, v in med.items() if not k.startswith("direct")
                      and k not in ("gmsh model", "read_gmsh"))
    g2s = mesh_t + solve_total
    lines = [f"{COMM.size} rank(s), {args.repeat} repeat(s) (medians), {P.machine()}",
             f"code: {code_state()}",
             f"B1 n={args.n}, H={args.H:g}: {info['primal']} primal dofs, {info['dual']} dual, "
             f"{info['subdomains']} subdomains; converged {info['converged']}, "
             f"{info['outer']} outer, {info['mults']} F-mults", "",
             "| phase | s |", "|---|---:|"]
    lines += [f"| {k} | {v:.2f} |" for k, v in med.items()]
    lines += [f"| **set-up before the iterations** ({' + '.join(BEFORE_ITERATIONS)}) | "
              f"{setup:.2f} |", f"| **iterations** | {med.get('iterations', 0.0):.2f} |",
              f"| **FETI gmsh to solution** | {g2s:.2f} |"]
    if not args.no_direct:
        d2s = mesh_t + med["direct assembly"] + med["direct factor+solve"]
        lines += [f"| **direct gmsh to solution** ({info['direct dofs']} dofs, residual "
                  f"{info['direct residual']:.1e}) | {d2s:.2f} |",
                  f"| **ratio FETI / direct** | {g2s / d2s:.2f} |"]
    last = runs[-1][1]
    lines += ["", "peak RSS per rank (VmHWM, MiB): after FETI "
              + ", ".join(f"{v:.0f}" for v in last["peak MiB after FETI"])
              + "; at end " + ", ".join(f"{v:.0f}" for v in last["peak MiB at end"])]
    text = "\n".join(lines)
    if COMM.rank == 0:
        print(text)
        if args.json:
            args.json.write_text(json.dumps({"runs": runs, "median": med, "text": text},
                                            indent=1))


if __name__ == "__main__":
    main()
