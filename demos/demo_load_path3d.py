# # A block pressed, sheared back and forth and released, with Coulomb friction (3D)
#
# Two stacked unit blocks (E = 1, ν = 0.3), the lower one clamped at the bottom, node-to-node
# contact with Coulomb friction $\mathcal{F} = 0.3$ (a disc of slip bounds per node, MPGP inside
# SMALBE). The top of the upper block is first pressed down by $0.02$, then moved sideways along
# x to $+0.02$, back through 0 to $-0.02$ and to $+0.02$ again, and finally back to 0: a
# displacement-controlled load path.
#
# `df.solve_path` solves the steps on one set-up, each warm-started from the last; the friction
# acts on the slip increment of each step (a node that sticks keeps its tangential
# displacement). Two blocks of one footprint press hardest at the edges of their contact face,
# so the nodes slip first in its middle, where the normal force is lowest; after a turn of the
# shift everything sticks again until the friction force has reversed there. The friction
# force against the shift is a hysteresis loop, and after the release tangential tractions
# stay locked in. The same path from the
# command line: `dolfinx-feti problems/load_path3d.toml` (the `[loading]` table).
#
# Run: `python demos/demo_load_path3d.py` (or under `mpirun -n 2`); `--help` lists options.

# +
import argparse
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--n", type=int, default=8, help="cells per unit length")
parser.add_argument("--coefficient", type=float, default=0.3, help="Coulomb coefficient")
parser.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance")
parser.add_argument("--out", type=Path, default=Path("output/load_path3d"),
                    help="output folder")
parser.add_argument("--json", type=Path, default=None, help="write the last step's report here")
args, _ = parser.parse_known_args()  # -feti_* options: read by solve_path(options=sys.argv)
comm = MPI.COMM_WORLD
# -

# ## The path
#
# Step k prescribes the top's displacement $(s_k, 0, -0.02)$.

# +
mesh = df.build_mesh(meshes.blocks3d, n=args.n, comm=comm)
shift = np.array([0.0, 0.005, 0.01, 0.015, 0.02, 0.01, 0.0, -0.01, -0.02, -0.01, 0.0, 0.01, 0.02,
                  0.01, 0.0])


def problem_at(t: float) -> df.ContactProblem:
    return df.ContactProblem(
        mesh, df.Elasticity(1.0, 0.3),
        dirichlet=[df.Dirichlet("bottom"),
                   df.Dirichlet("top", value=(float(shift[int(t)]), 0.0, -0.02))],
        contact=[df.NodeToNode("contact_upper", "contact_lower",
                               friction=df.Coulomb(args.coefficient))],
        decomposition=df.Parts(4))


if comm.rank == 0:
    args.out.mkdir(parents=True, exist_ok=True)
sols = df.solve_path(problem_at, range(shift.size), comm=comm, options=sys.argv,
                     rtol=args.rtol, xdmf=args.out / "load_path3d.xdmf",
                     history=args.out / "history.json")
# -

# ## Checks at every step
#
# The forces on the upper block balance: the contact forces (normal and friction) equal the
# reaction at its top. Every tangential force is within its disc, |λ_T| ≤ 𝓕 λ_N; where a node
# slips its slip increment points against its friction force.

# +
coef = args.coefficient
rows = []
for k, sol in enumerate(sols):
    c = sol.contact
    ft = np.linalg.norm(c.tangential_force, axis=1)
    slipping = c.state == df.ContactData.SLIP
    pressed = c.force > 0
    against = np.einsum("ij,ij->i", c.slip, c.tangential_force)[slipping & pressed]
    rows.append({"step": k, "shift": float(shift[k]), "Q": float(-sol.total_contact_force[0]),
                 "P": float(sol.total_contact_force[2]),
                 "stick": int(np.count_nonzero(~slipping & pressed)),
                 "slip": int(np.count_nonzero(slipping & pressed)),
                 "disc": float((ft - coef * c.force).max()),
                 "against": bool(np.all(against <= 1e-12 * max(ft.max(), 1e-300)))})
# -

# ## Output: the stick/slip zones over time, the hysteresis loop; XDMF over time; JSON

# +
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    show = [2, 4, 6, 8, 10, 14]
    fig, axes = plt.subplots(2, 4, figsize=(15, 7.5))
    loop = axes[0, 0]
    Q = np.array([r["Q"] for r in rows])
    # the loop is slim next to the elastic response: Q less its secant through the turns
    secant = (Q[4] - Q[8]) / (shift[4] - shift[8])
    loop.plot(shift, Q - secant * shift, "o-", ms=3)
    loop.set_xlabel("shift s of the top along x")
    loop.set_ylabel("friction force Q on the upper block, less the secant's Q*·s/s*")
    loop.set_title("hysteresis loop")
    axes[1, 0].axis("off")
    colours = {df.ContactData.STICK: "0.7", df.ContactData.SLIP: "C3"}
    for ax, k in zip([*axes[0, 1:], *axes[1, 1:]], show, strict=False):
        c = sols[k].contact
        pressed = c.force > 0
        for state, colour in colours.items():
            m = pressed & (c.state == state)
            ax.scatter(c.x[m, 0], c.x[m, 1], s=14, color=colour,
                       label="stick" if state == df.ContactData.STICK else "slip")
        q = c.tangential_traction
        ax.quiver(c.x[:, 0], c.x[:, 1], q[:, 0], q[:, 1], scale=None, width=0.004)
        ax.set_aspect("equal")
        ax.set_title(f"step {k}: shift {shift[k]:+.3f}", fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
    fig.suptitle("contact face: stick (grey) / slip (red), friction traction on the upper block "
                 "(arrows scaled per panel)")
    fig.tight_layout()
    fig.savefig(args.out / "load_path3d.png", dpi=110)
report = sols[-1].report
report.converged = all(s.report.converged for s in sols)
if args.json:
    report.save_json(args.json)
# -

# ## Summary

if comm.rank == 0:
    print(f"{shift.size} steps, all converged: {report.converged}")
    print(" step  shift    Q/(F P)  stick  slip  max(|lambda_T| - F lambda_N)  slip vs friction")
    for r in rows:
        print(f"{r['step']:5d} {r['shift']:+.3f} {r['Q'] / (coef * r['P']):+8.3f} "
              f"{r['stick']:6d} {r['slip']:5d} {r['disc']:+.2e}"
              f"                   {r['against']}")
    c = sols[-1].contact
    print(f"released: largest nodal tangential force "
          f"{np.linalg.norm(c.tangential_force, axis=1).max():.3e} (after pressing only: "
          f"{np.linalg.norm(sols[0].contact.tangential_force, axis=1).max():.3e})")
    work = sum(0.5 * (rows[k]["Q"] + rows[k + 1]["Q"]) * (shift[k + 1] - shift[k])
               for k in range(4, 12))
    print(f"energy dissipated over the cycle +0.02 -> -0.02 -> +0.02: {work:.4e}")
    print(f"output in {args.out}/")
