# # Tresca friction in 3D: a block pressed on another and sheared
#
# A block $[0,1]^2 \times [0.5, 1]$ stands on a block $[0,1]^2 \times [0, 0.5]$ (both $E = 1$,
# $\nu = 0.3$); the lower one is clamped at the bottom, the top of the upper one is displaced by
# $(0.02, 0.01, -0.02)$: pressed and sheared obliquely. Given (Tresca) friction with slip bound
# $g$ acts on the contact: in 3D the tangential force of a node is a vector, bounded by a disc,
# $\|\lambda_T\| \le g$ (times the node's lumped area). The dual problem then has one disc per
# contact node on its two tangential multipliers; SMALBE-M solves it with MPGP (modified
# proportioning with gradient projections for separable convex constraints) as inner solver.
#
# Run: `python demos/demo_tresca3d.py` (or under `mpirun -n 2`); `--help` lists options.

# +
import argparse
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--n", type=int, default=8, help="elements per unit length")
parser.add_argument("--parts", type=int, default=2, help="subdomains per block")
parser.add_argument("--g", type=float, default=0.0075, help="Tresca slip bound (a traction)")
parser.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance")
parser.add_argument("--out", type=Path, default=Path("output/tresca3d"), help="output folder")
parser.add_argument("--json", type=Path, default=None, help="write the solve report here")
args, _ = parser.parse_known_args()
comm = MPI.COMM_WORLD
shift = (0.02, 0.01, -0.02)
# -

# ## The problem and the solve

# +
mesh = df.build_mesh(meshes.blocks3d, n=args.n, comm=comm)


def problem(friction):
    return df.ContactProblem(
        mesh, df.Elasticity(1.0, 0.3),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=shift)],
        contact=[df.NodeToNode("contact_upper", "contact_lower", friction=friction)],
        decomposition=df.Parts(args.parts))


solution = df.solve(problem(df.Tresca(args.g)), comm=comm, options=sys.argv,
                    rtol=args.rtol)
frictionless = df.solve(problem(None), comm=comm, options=sys.argv, rtol=args.rtol)
report = solution.report
# -

# ## Stick and slip on the contact face
#
# Where a node slips, its slip (the relative tangential displacement of the upper block) points
# against the friction force, and the force is on the circle $\|\lambda_T\| = g$; where it
# sticks, the slip vanishes.

# +
c = solution.contact
ft = np.linalg.norm(c.tangential_force, axis=1)
stick = c.state == df.ContactData.STICK
slip = ~stick
s = np.linalg.norm(c.slip, axis=1)
u_max = np.abs(solution.nodal_values()).max()
moving = slip & (s > 1e-8 * u_max)
cos = np.einsum("ij,ij->i", c.slip[moving], c.tangential_force[moving]) / (s * ft)[moving]
checks = {"max |lambda_T| / g": float((ft / c.slip_bound).max()),
          "max |slip| at stick nodes / max|u|": float(s[stick].max(initial=0) / u_max),
          "max cos(slip, friction force) at slipping nodes": float(cos.max(initial=-1))}
# -

# ## Output

# +
if comm.rank == 0:
    args.out.mkdir(parents=True, exist_ok=True)
solution.write_xdmf(args.out / "tresca3d.xdmf")
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 5))
    sc = ax.scatter(c.x[:, 0], c.x[:, 1], c=ft / c.slip_bound, cmap="viridis", vmin=0, vmax=1,
                    s=40, marker="o", edgecolors=np.where(stick, "k", "r"))
    ax.quiver(c.x[slip, 0], c.x[slip, 1], c.slip[slip, 0], c.slip[slip, 1], color="r",
              angles="xy", width=0.004)
    fig.colorbar(sc, ax=ax, label=r"$\|\lambda_T\| / g$")
    ax.set_title(f"Tresca g = {args.g}: stick (black rim), slip (red rim, arrows: slip)",
                 fontsize=9)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(args.out / "tresca3d_stick_slip.png", dpi=120)
if args.json:
    report.save_json(args.json)
# -

# ## Summary

if comm.rank == 0:
    print(report.summary())
    print(f"frictionless: {frictionless.report.hessian_mults} F-multiplications; Tresca (MPGP): "
          f"{report.hessian_mults}")
    print(f"{int(stick.sum())} of {stick.size} contact nodes stick")
    for k, v in checks.items():
        print(f"{k}: {v}")
    print(f"output in {args.out}/")
