# # A rubber cylinder squeezed between two rigid plates: large deformation by Newton
#
# A compressible neo-Hookean cylinder (radius $R = 1$, $E = 1$, $\nu = 0.3$, plane strain)
# between two frictionless rigid plates that approach each other by $2\delta$, up to
# $\delta = 0.3R$. By symmetry a quarter is modelled: the centre line $y = 0$ keeps
# $u_y = 0$, the axis $x = 0$ keeps $u_x = 0$, and the lower plate $y = -R + t$ rises with
# the pseudo-time $t$.
#
# The material is `df.NeoHookean(E, nu)`: a stored energy density
# $\psi = \frac{\mu}{2}(\operatorname{tr} C - 2) - \mu\ln J + \frac{\lambda}{2}(\ln J)^2$, from
# which the library derives the residual and the tangent (`ufl.derivative`, total Lagrangian).
# `df.solve_path` runs Newton at every load step on one FETI set-up: each Newton iteration is a
# FETI-DP contact QP for the increment, with the plate's gap taken in the current
# configuration, solved by MPRGP exactly (no penalty), warm-started; a step Newton cannot take
# is cut back automatically.
#
# Run: `python demos/demo_rubber_cylinder.py` (or under `mpirun -n 2`); `--help` lists options.

# +
import argparse
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io.meshes_rubber import quarter_disk

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=float, default=0.03, help="element size at the contact")
parser.add_argument("--delta", type=float, default=0.3, help="plate travel / R")
parser.add_argument("--steps", type=int, default=6, help="load steps")
parser.add_argument("--parts", type=int, default=2, help="subdomains")
parser.add_argument("--rtol", type=float, default=1e-10, help="Newton's KKT tolerance")
parser.add_argument("--out", type=Path, default=Path("output/rubber_cylinder"),
                    help="output folder")
parser.add_argument("--json", type=Path, default=None, help="write the last step's report here")
args, _ = parser.parse_known_args()  # -feti_* options: read by solve_path(options=sys.argv)
comm = MPI.COMM_WORLD
R, E, nu = 1.0, 1.0, 0.3
# -

# ## The load path

# +
mesh = df.build_mesh(quarter_disk, R=R, h_contact=args.h, h_far=0.2, comm=comm, gdim=2)
times = args.delta * R * np.arange(1, args.steps + 1) / args.steps


def problem_at(t: float) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, df.NeoHookean(E, nu),
        dirichlet=[df.Dirichlet("top", 0.0, components=[1]),
                   df.Dirichlet("axis", 0.0, components=[0])],
        contact=[df.RigidObstacle("arc", df.Plane((0.0, -R + t), (0.0, 1.0)))],
        decomposition=df.Parts(args.parts))


wall = time.perf_counter()
sols = df.solve_path(problem_at, times, comm=comm, options=sys.argv, rtol=1e-12,
                     newton_rtol=args.rtol)
wall = comm.allreduce(time.perf_counter() - wall, op=MPI.MAX)
# -

# ## Results: force, contact half-width, Newton's convergence
#
# The plate force per unit length (the quarter's, times 2 for the half cylinder), the
# deformed contact half-width, and the Newton residual history of every step: quadratic
# convergence shows as the exponent of the residual doubling from one iteration to the next.

# +
force = np.array([s.total_contact_force[1] for s in sols])
widths, converged = [], all(s.report.converged for s in sols)
nodal = [s.nodal_values_on_root() for s in sols]
for s, u in zip(sols, nodal, strict=True):
    c = s.contact
    on = c.force > 0
    widths.append(float((c.x[on, 0] + u[c.node[on], 0]).max()) if comm.rank == 0 else 0.0)
newton = [[h["residual"] for h in s.report.extra["newton"]] for s in sols]
kkt = sols[-1].report.kkt
# -

# ## Output: plots, XDMF of the last step, JSON

# +
args.out.mkdir(parents=True, exist_ok=True) if comm.rank == 0 else None
comm.barrier()
sols[-1].write_xdmf(args.out / "rubber_cylinder.xdmf")
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(14, 4.2))
    x = mesh.x[:, :2] + nodal[-1][:, :2]
    cells = mesh.cells
    ax1.triplot(x[:, 0], x[:, 1], cells, lw=0.4)
    ax1.triplot(-x[:, 0], x[:, 1], cells, lw=0.4, color="C0")
    ax1.axhline(-R + times[-1], color="k", lw=2)
    ax1.set_aspect("equal")
    ax1.set_title(f"deformed, plate travel δ = {times[-1]:.2f} R")
    ax2.plot(np.r_[0, times], np.r_[0, 2 * force], "o-")
    ax2.set_xlabel("plate travel δ / R")
    ax2.set_ylabel("plate force per unit length (half cylinder)")
    ax2b = ax2.twinx()
    ax2b.plot(times, widths, "s--", color="C1")
    ax2b.set_ylabel("contact half-width / R", color="C1")
    for k, r in enumerate(newton):
        ax3.semilogy(r, "o-", label=f"step {k + 1}")
    ax3.set_xlabel("Newton iteration")
    ax3.set_ylabel("relative equilibrium residual")
    ax3.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out / "rubber_cylinder.png", dpi=120)
report = sols[-1].report
report.converged = converged
if args.json:
    report.save_json(args.json)
# -

# ## Summary

# +
if comm.rank == 0:
    print(f"{len(sols)} load steps on {comm.size} rank(s), all converged: {converged}; "
          f"{wall:.2f} s")
    print("Newton iterations per step:", [len(r) for r in newton])
    print("F-multiplications per step:", [s.report.hessian_mults for s in sols])
    print("plate force per unit length:", " ".join(f"{2 * f:.4f}" for f in force))
    print("contact half-width / R:", " ".join(f"{w:.3f}" for w in widths))
    print("last step's residual history:", " ".join(f"{r:.1e}" for r in newton[-1]))
    print("KKT residuals at the end (physical units, relative):",
          ", ".join(f"{k} {v:.1e}" for k, v in kkt.items()))
    print(f"output in {args.out}/")
# -
