# # A soft hemisphere pressed onto a rigid plane (3D): Newton over FETI against PETSc SNES VI
#
# A compressible neo-Hookean ball of radius $R = 1$ ($E = 1$, $\nu = 0.3$), its lower half,
# pressed onto the frictionless rigid plane $z = -R$ by moving its flat top $z = 0$ down by
# $\delta$, up to $\delta = 0.15R$ in four load steps. By symmetry a quarter is modelled (the
# planes $x = 0$ and $y = 0$ keep $u_x = 0$ and $u_y = 0$).
#
# `df.solve_path` runs Newton at every load step on one FETI set-up (`Parts(4)`, FETI-DP): each
# iteration is an exact-constraint contact QP for the increment, with the plane's gap taken at
# the nodes' current positions. As an independent reference the same energy on the same mesh
# is minimized by PETSc's reduced-space active-set Newton for variational inequalities
# (`vinewtonrsls`) with the plane as a bound on every node's vertical displacement
# (tests/support/snes_vi.py, on rank 0 over the whole mesh): the two must agree to the solvers'
# tolerances.
#
# Run: `python demos/demo_rubber_hemisphere.py` (or under `mpirun -n 2`); `--help` lists
# options.

# +
import argparse
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io.meshes_rubber import quarter_hemisphere

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "support"))
from rubber_cases import hemisphere_bounds  # noqa: E402
from snes_vi import match, neo_hookean, snes_vi  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=float, default=0.05, help="element size at the contact")
parser.add_argument("--delta", type=float, default=0.15, help="travel of the top / R")
parser.add_argument("--steps", type=int, default=4, help="load steps")
parser.add_argument("--parts", type=int, default=4, help="subdomains")
parser.add_argument("--rtol", type=float, default=1e-11, help="Newton's KKT tolerance")
parser.add_argument("--out", type=Path, default=Path("output/rubber_hemisphere"),
                    help="output folder")
parser.add_argument("--json", type=Path, default=None, help="write the last step's report here")
args, _ = parser.parse_known_args()  # -feti_* options: read by solve_path(options=sys.argv)
comm = MPI.COMM_WORLD
R, E, nu = 1.0, 1.0, 0.3
mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
# -

# ## The load path by Newton over FETI

# +
mesh = df.build_mesh(quarter_hemisphere, R=R, h_contact=args.h, h_far=0.2, comm=comm)
loads = args.delta * R * np.arange(1, args.steps + 1) / args.steps


def problem_at(t: float) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, df.NeoHookean(E, nu),
        dirichlet=[df.Dirichlet("top", -t, components=[2]),
                   df.Dirichlet("x0", 0.0, components=[0]),
                   df.Dirichlet("y0", 0.0, components=[1])],
        contact=[df.RigidObstacle("sphere", df.Plane((0.0, 0.0, -R), (0.0, 0.0, 1.0)))],
        decomposition=df.Parts(args.parts))


wall = time.perf_counter()
sols = df.solve_path(problem_at, loads, comm=comm, options=sys.argv, rtol=1e-12,
                     newton_rtol=args.rtol)
wall = comm.allreduce(time.perf_counter() - wall, op=MPI.MAX)
nodal = [s.nodal_values_on_root() for s in sols]
force = np.array([s.total_contact_force[2] for s in sols])
newton = [[h["residual"] for h in s.report.extra["newton"]] for s in sols]
radius = []  # of the contact zone: the farthest node carrying force, deformed
for s, u in zip(sols, nodal, strict=True):
    c = s.contact
    on = c.force > 0
    radius.append(float(np.hypot(*(c.x[on, :2] + u[c.node[on], :2]).T).max())
                  if comm.rank == 0 else 0.0)
# -

# ## The reference: SNES VI on the same energy and mesh (rank 0)
#
# The same load steps; the Dirichlet values are equal bounds, the plane a lower bound on
# $u_z$ (`hemisphere_bounds`, shared with the tests); the plane's force is the residual
# $\partial\Pi/\partial u$ at the nodes that touch it. Compared at the last step.

# +
summary = None
if comm.rank == 0:
    Xr, Ur, Rr, its = snes_vi(mesh, neo_hookean(mu, lmbda), hemisphere_bounds, -R, loads)
    touching = Xr[:, 2] + Ur[:, 2] + R < 1e-9
    ref_force = float(Rr[touching, 2].sum())
    ref_u = Ur[match(Xr, mesh.x)]
    du = float(np.abs(nodal[-1] - ref_u).max() / np.abs(ref_u).max())
    summary = (ref_force, du, abs(force[-1] - ref_force) / ref_force, its)
ref_force, du, df_rel, snes_its = comm.bcast(summary, root=0)
# -

# ## Output: plots, XDMF of the last step, JSON

# +
if comm.rank == 0:
    args.out.mkdir(parents=True, exist_ok=True)
comm.barrier()
sols[-1].write_xdmf(args.out / "rubber_hemisphere.xdmf")
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(14, 4.2))
    x = mesh.x + nodal[-1]
    plane = np.abs(mesh.x[:, 1]) < 1e-12  # the section y = 0
    ax1.plot(mesh.x[plane, 0], mesh.x[plane, 2], ".", ms=2, color="0.6", label="reference")
    ax1.plot(x[plane, 0], x[plane, 2], ".", ms=3, label=f"deformed, δ = {loads[-1]:.2f} R")
    ax1.axhline(-R, color="k", lw=2)
    ax1.set_aspect("equal")
    ax1.set_title("section y = 0")
    ax1.legend(fontsize=7)
    ax2.plot(np.r_[0, loads], np.r_[0, 4 * force], "o-", label="Newton over FETI")
    ax2.plot(loads[-1:], [4 * ref_force], "x", ms=9, label="SNES VI")
    ax2.set_xlabel("travel δ / R")
    ax2.set_ylabel("force on the plane (whole hemisphere)")
    ax2.legend()
    ax2b = ax2.twinx()
    ax2b.plot(loads, radius, "s--", color="C2")
    ax2b.set_ylabel("contact radius / R", color="C2")
    for k, r in enumerate(newton):
        ax3.semilogy(r, "o-", label=f"step {k + 1}")
    ax3.set_xlabel("Newton iteration")
    ax3.set_ylabel("relative equilibrium residual")
    ax3.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out / "rubber_hemisphere.png", dpi=120)
agree = du < 1e-6 and df_rel < 1e-6
report = sols[-1].report
report.converged = all(s.report.converged for s in sols) and agree
report.extra["snes_vi"] = {"displacement_rel": du, "force_rel": df_rel,
                           "contact_radius": radius}
if args.json:
    report.save_json(args.json)
# -

# ## Summary

# +
if comm.rank == 0:
    print(f"{len(sols)} load steps on {comm.size} rank(s), {wall:.2f} s; all converged: "
          f"{all(s.report.converged for s in sols)}")
    print("Newton iterations per step:", [len(r) for r in newton])
    print("force on the plane (whole hemisphere):", " ".join(f"{4 * f:.6f}" for f in force))
    print("contact radius / R:", " ".join(f"{r:.3f}" for r in radius))
    print(f"against SNES VI ({sum(snes_its)} SNES iterations): max |u − u_ref| / max |u_ref| "
          f"{du:.1e}, force {df_rel:.1e}")
    print("last step's residual history:", " ".join(f"{r:.1e}" for r in newton[-1]))
    print(f"agree to 1e-6: {agree}; output in {args.out}/")
# -
