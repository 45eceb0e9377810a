"""The ironing problem with a rigid die: Newton over FETI contact QPs with Coulomb friction.

After Puso & Laursen (2004) and Yang, Laursen & Meng (2005): a die pressed into a soft
neo-Hookean block and slid along its top, 𝓕 = 0.3. Here the die is rigid (a
:class:`~dolfinx_feti.Sphere`, a disc of radius R in 2D, plane strain): the block
[0, 9] × [0, 3] (E = 1, ν = 0.3) is clamped at its bottom; the die's centre goes down by
``depth`` at x = ``x0`` in ``press_steps`` steps, then along the top by ``slide`` in
``slide_steps`` steps. Friction acts on the slip increment of each step, relative to the die.

Per step: the force on the die (−the total contact force on the block), its horizontal over
its vertical component, and the ratio in the contact frame Σ|q| / Σ p (friction over normal
forces, 𝓕 exactly where every pressed node slips), Newton iterations, seconds and
F-multiplications per iteration. Then one linear contact solve (df.Elasticity, the same mesh,
decomposition, method, die and friction, at the first press step): its set-up and solve.
Writes ``output/bench/ironing.json``, ``ironing_history.json`` (solve_path's history),
``ironing.png`` (force histories); prints Markdown tables. Run:

    OMP_NUM_THREADS=1 PYTHONPATH=$PWD python bench/ironing.py [--h-top 0.15] [--parts 2]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io.meshes_rubber import ironing_block

ROOT = Path(__file__).resolve().parent.parent
LX, LY, E, NU = 9.0, 3.0, 1.0, 0.3

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--h-top", type=float, default=0.15)
parser.add_argument("--h-far", type=float, default=0.6)
parser.add_argument("--parts", type=int, default=2)
parser.add_argument("--radius", type=float, default=1.0)
parser.add_argument("--depth", type=float, default=0.5)
parser.add_argument("--x0", type=float, default=2.0)
parser.add_argument("--slide", type=float, default=2.0)
parser.add_argument("--press-steps", type=int, default=5)
parser.add_argument("--slide-steps", type=int, default=100)
parser.add_argument("--coefficient", type=float, default=0.3)
parser.add_argument("--method", default="fetidp")
parser.add_argument("--rtol", type=float, default=1e-9)
parser.add_argument("--newton-rtol", type=float, default=1e-8)
parser.add_argument("--steps", type=int, default=0, help="only the first N steps (0: all)")
parser.add_argument("--no-project", action="store_true",
                    help="mprgp_project false (expansions by MPRGP's own step only)")
args = parser.parse_args()
comm = MPI.COMM_WORLD
mesh = df.build_mesh(ironing_block, lx=LX, ly=LY, h_top=args.h_top, h_far=args.h_far,
                     comm=comm, gdim=2)
R = args.radius


def centre(t: float) -> tuple[float, float]:
    """The die's centre at pseudo-time t: pressed for t <= 1, slid for 1 < t <= 2."""
    return (args.x0 + max(t - 1.0, 0.0) * args.slide, LY + R - min(t, 1.0) * args.depth)


def problem(material, t: float) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, material, dirichlet=[df.Dirichlet("bottom")],
        contact=[df.RigidObstacle("top", df.Sphere(centre(t), R),
                                  friction=df.Coulomb(args.coefficient, rtol=1e-10,
                                                      max_steps=200))],
        decomposition=df.Parts(args.parts))


times = np.r_[np.arange(1, args.press_steps + 1) / args.press_steps,
              1.0 + np.arange(1, args.slide_steps + 1) / args.slide_steps]
if args.steps:
    times = times[:args.steps]
out = ROOT / "output/bench"
if comm.rank == 0:
    out.mkdir(parents=True, exist_ok=True)
wall = time.perf_counter()
sols = df.solve_path(lambda t: problem(df.NeoHookean(E, NU), t), times, comm=comm,
                     rtol=args.rtol, newton_rtol=args.newton_rtol, method=args.method,
                     mprgp_project=not args.no_project, history=out / "ironing_history.json")
wall = comm.allreduce(time.perf_counter() - wall, op=MPI.MAX)

rows = []
for t, s in zip(times, sols, strict=False):
    c = s.contact
    force = -s.total_contact_force  # on the die
    pressed = c.force > 0
    h = s.report.extra["newton"]
    rows.append({
        "time": float(t), "die_x": centre(t)[0], "die_depth": min(t, 1.0) * args.depth,
        "converged": bool(s.report.converged), "Fx": float(force[0]), "Fy": float(force[1]),
        "ratio_xy": float(abs(force[0]) / abs(force[1])),
        "ratio_contact": float(np.linalg.norm(c.tangential_force[pressed], axis=1).sum()
                               / c.force[pressed].sum()),
        "pressed": int(pressed.sum()), "slip": int(np.count_nonzero(c.state[pressed] == 2)),
        "newton_iterations": len(h), "seconds_per_iteration": float(np.mean(
            [x["seconds"] for x in h])),
        "fmults_per_iteration": float(np.mean([x["hessian_mults"] for x in h])),
        "fmults": int(sum(x["hessian_mults"] for x in h)),
        "residuals": [x["residual"] for x in h],
        "coulomb_bound": float(s.report.kkt.get("coulomb_bound", np.nan)),
        "friction_complementarity": float(s.report.kkt["friction_complementarity"])})

t0 = time.perf_counter()
solver = df.FetiSolver(problem(df.Elasticity(E, NU), times[0]), comm=comm, rtol=args.rtol,
                       method=args.method)
t1 = time.perf_counter()
lin = solver.solve()
t2 = time.perf_counter()
solver.destroy()
linear = {"setup": comm.allreduce(t1 - t0, op=MPI.MAX),
          "solve": comm.allreduce(t2 - t1, op=MPI.MAX),
          "fmults": int(lin.report.hessian_mults), "converged": bool(lin.report.converged)}

if comm.rank == 0:
    summary = {"args": vars(args), "nodes": mesh.num_nodes,
               "primal": lin.report.sizes["primal"], "ranks": comm.size, "wall": wall,
               "steps": rows, "linear": linear}
    (out / "ironing.json").write_text(json.dumps(summary, indent=1))
    print(f"mesh: {mesh.num_nodes} nodes, {lin.report.sizes['primal']} primal dofs, "
          f"Parts({args.parts}), {args.method}, {comm.size} rank(s); {times.size} steps in "
          f"{wall:.1f} s, {sum(r['fmults'] for r in rows)} F-multiplications, "
          f"{sum(r['newton_iterations'] for r in rows)} Newton iterations; all converged: "
          f"{all(r['converged'] for r in rows)}")
    print("| step | die x | depth | F_x | F_y | F_x/F_y | Σ|q|/Σp | pressed | slipping "
          "| Newton its | s/it | F-mults/it |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for k, r in enumerate(rows):
        print(f"| {k + 1} | {r['die_x']:.2f} | {r['die_depth']:.2f} | {r['Fx']:.4f} | "
              f"{r['Fy']:.4f} | {r['ratio_xy']:.4f} | {r['ratio_contact']:.6f} | "
              f"{r['pressed']} | {r['slip']} | {r['newton_iterations']} | "
              f"{r['seconds_per_iteration']:.3f} | {r['fmults_per_iteration']:.0f} |")
    print(f"linear contact solve (Elasticity, Coulomb, the first press step): set-up "
          f"{linear['setup']:.3f} s, solve {linear['solve']:.3f} s, {linear['fmults']} F-mults")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    travel = [r["die_x"] - args.x0 + r["die_depth"] for r in rows]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8))
    a1.plot(travel, [r["Fy"] for r in rows], "o-", label="$F_y$ (normal)")
    a1.plot(travel, [r["Fx"] for r in rows], "s-", label="$F_x$ (tangential)")
    a1.axvline(args.depth, color="0.6", lw=0.8)
    a1.set_xlabel("die travel (down, then along)")
    a1.set_ylabel("force on the die")
    a1.legend()
    a2.plot(travel, [r["ratio_xy"] for r in rows], "o-", label="$|F_x|/F_y$")
    a2.plot(travel, [r["ratio_contact"] for r in rows], "s-", label=r"$\Sigma|q|/\Sigma p$")
    a2.axhline(args.coefficient, color="k", lw=0.8, ls="--", label=r"$\mathcal{F}$")
    a2.set_xlabel("die travel (down, then along)")
    a2.legend()
    fig.tight_layout()
    fig.savefig(out / "ironing.png", dpi=120)
