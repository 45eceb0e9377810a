"""A deformable slider on a deformable block: Newton with Coulomb friction on node-to-node pairs.

The deformable-die counterpart of bench/ironing.py within what node-to-node pairs can do (a
slave node stays paired with one master node: the slide must stay within an element, so the
die is a flat block, not a disc slid over many elements). Two neo-Hookean blocks
[0, 2] × [0, 1] and [0, 2] × [1, 2] meshed apart with matching nodes (``stacked_blocks`` of
tests/support, ``n`` cells per unit), E = 10, ν = 0.3, plane strain; the lower one clamped at
its bottom, free to deform under the pair (its surface's normals turn); the upper one ("the
die") moved at its top: down by 0.1 in ``press_steps`` steps, then along x by ``slide`` in
``slide_steps`` steps; 𝓕 = 0.3 (Coulomb, fixed point to 1e-10), friction on the slip of each
pair in each step. ``ByTags`` (one subdomain per body) or ``Parts(k)``, FETI-DP.

Per step: the force on the die's top (−the contact force on the upper block: they balance),
its horizontal over vertical component, Σ|q| / Σp in the contact frame (𝓕 exactly where every
pressed pair slips), the largest relative slip of a pair over the element size, Newton
iterations, seconds and F-multiplications per iteration. Then one linear contact solve
(df.Elasticity, the same mesh, decomposition, method and friction, at the first press step).
Writes ``output/bench/pair_sliding.json``; prints a Markdown table. Run:

    OMP_NUM_THREADS=1 PYTHONPATH=$PWD python bench/pair_sliding.py [--n 8] [--parts 1]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))

from element_models import stacked_blocks  # noqa: E402

import dolfinx_feti as df  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
E, NU, LX = 10.0, 0.3, 2.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--parts", type=int, default=1)
    ap.add_argument("--press", type=float, default=0.1)
    ap.add_argument("--slide", type=float, default=0.18)
    ap.add_argument("--press-steps", type=int, default=2)
    ap.add_argument("--slide-steps", type=int, default=6)
    ap.add_argument("--coefficient", type=float, default=0.3)
    ap.add_argument("--rtol", type=float, default=1e-10)
    ap.add_argument("--newton-rtol", type=float, default=1e-9)
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    mesh = df.build_mesh(stacked_blocks, n=args.n, lx=LX, gdim=2, comm=comm)
    h = LX / (2 * args.n)
    dec = df.ByTags() if args.parts == 1 else df.Parts(args.parts)

    def problem(material, t: float) -> df.ContactProblem:
        shift = max(t - 1.0, 0.0) * args.slide
        return df.ContactProblem(
            mesh, material,
            dirichlet=[df.Dirichlet("bottom"),
                       df.Dirichlet("top", (shift, -min(t, 1.0) * args.press))],
            contact=[df.NodeToNode("upper_bottom", "lower_top", friction=df.Coulomb(
                args.coefficient, rtol=1e-10, max_steps=200))],
            decomposition=dec)

    times = np.r_[np.arange(1, args.press_steps + 1) / args.press_steps,
                  1.0 + np.arange(1, args.slide_steps + 1) / args.slide_steps]
    wall = time.perf_counter()
    sols = df.solve_path(lambda t: problem(df.NeoHookean(E, NU), t), times, comm=comm,
                         rtol=args.rtol, newton_rtol=args.newton_rtol, method="fetidp",
                         progress=False)
    wall = comm.allreduce(time.perf_counter() - wall, op=MPI.MAX)
    rows = []
    for t, s in zip(times, sols, strict=True):
        c = s.contact
        force = -s.total_contact_force  # on the die's top (the upper block is in balance)
        pressed = c.force > 0
        hist = s.report.extra["newton"]
        U = s.nodal_values()
        rows.append({
            "time": float(t), "shift": max(t - 1.0, 0.0) * args.slide,
            "converged": bool(s.report.converged), "Fx": float(force[0]),
            "Fy": float(force[1]), "ratio_xy": float(abs(force[0]) / abs(force[1])),
            "ratio_contact": float(np.linalg.norm(c.tangential_force[pressed], axis=1).sum()
                                   / c.force[pressed].sum()),
            "pressed": int(pressed.sum()), "slip": int(np.count_nonzero(c.state[pressed] == 2)),
            "slip_over_h": float(np.abs(U[c.node, 0] - U[c.partner, 0]).max() / h),
            "newton_iterations": len(hist),
            "seconds_per_iteration": float(np.mean([x["seconds"] for x in hist])),
            "fmults_per_iteration": float(np.mean([x["hessian_mults"] for x in hist])),
            "residuals": [x["residual"] for x in hist]})
    t0 = time.perf_counter()
    solver = df.FetiSolver(problem(df.Elasticity(E, NU), times[0]), comm=comm, rtol=args.rtol,
                           method="fetidp")
    t1 = time.perf_counter()
    lin = solver.solve()
    t2 = time.perf_counter()
    solver.destroy()
    linear = {"setup": comm.allreduce(t1 - t0, op=MPI.MAX),
              "solve": comm.allreduce(t2 - t1, op=MPI.MAX),
              "fmults": int(lin.report.hessian_mults), "converged": bool(lin.report.converged)}
    if comm.rank != 0:
        return
    out = ROOT / "output/bench"
    out.mkdir(parents=True, exist_ok=True)
    summary = {"args": vars(args), "nodes": mesh.num_nodes,
               "primal": lin.report.sizes["primal"], "ranks": comm.size, "wall": wall,
               "steps": rows, "linear": linear}
    (out / "pair_sliding.json").write_text(json.dumps(summary, indent=1))
    print(f"mesh: {mesh.num_nodes} nodes, {lin.report.sizes['primal']} primal dofs, h = {h:.4g}, "
          f"parts {args.parts}, fetidp, {comm.size} rank(s); {times.size} steps in {wall:.1f} s; "
          f"all converged: {all(r['converged'] for r in rows)}")
    print("| step | shift | F_x | F_y | F_x/F_y | Σ|q|/Σp | pressed | slipping | max slip / h "
          "| Newton its | s/it | F-mults/it |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for k, r in enumerate(rows):
        print(f"| {k + 1} | {r['shift']:.3f} | {r['Fx']:.4f} | {r['Fy']:.4f} | "
              f"{r['ratio_xy']:.6f} | {r['ratio_contact']:.10f} | {r['pressed']} | {r['slip']} "
              f"| {r['slip_over_h']:.3f} | {r['newton_iterations']} | "
              f"{r['seconds_per_iteration']:.3f} | {r['fmults_per_iteration']:.0f} |")
    print(f"linear contact solve (Elasticity, Coulomb, the first press step): set-up "
          f"{linear['setup']:.3f} s, solve {linear['solve']:.3f} s, {linear['fmults']} F-mults")


if __name__ == "__main__":
    main()
