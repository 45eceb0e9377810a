# # Tresca friction in 2D: a block pressed on a foundation and sheared (benchmark B4)
#
# An elastic block $[1, 3] \times [0, 1]$ stands on an elastic foundation
# $[0, 4] \times [-1, 0]$, both with the seed's material $E = 21.19$, $\nu = 0.277$ (plane
# strain). The foundation is clamped at the bottom; the block's top is displaced by
# $(\delta_t, -\delta_n) = (0.02, -0.02)$: pressed down and sheared to the right. On the
# contact surface acts given (Tresca) friction with the slip bound $g = 0.1$ (a traction): a
# node sticks (no relative tangential displacement) while its tangential traction is below
# $g$, and slips against the friction force when it reaches $g$.
#
# In the dual problem the tangential multipliers get the box $-g \le \lambda_T \le g$ (nodal
# forces: $g$ times the node's lumped length); Total FETI with SMALBE-M and MPRGP with upper
# bounds solves it. The demo compares with the frictionless solve, checks the stick/slip
# conditions and plots the tractions and the stick/slip zones.
#
# Run: `python demos/demo_tresca2d.py` (or under `mpirun -n 2`); `--help` lists options.

# +
import argparse
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--n", type=int, default=16, help="elements per unit length")
parser.add_argument("--parts", type=int, default=4, help="subdomains per body")
parser.add_argument("--g", type=float, default=0.1, help="Tresca slip bound (a traction)")
parser.add_argument("--shift", type=float, nargs=2, default=(0.02, -0.02),
                    help="displacement of the block's top (tangential, normal)")
parser.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance")
parser.add_argument("--out", type=Path, default=Path("output/tresca2d"), help="output folder")
parser.add_argument("--json", type=Path, default=None, help="write the solve report here")
args, _ = parser.parse_known_args()  # -feti_* options: read by df.solve(options=sys.argv)
comm = MPI.COMM_WORLD
E, nu = 21.19, 0.277
# -

# ## Mesh and problem
#
# `meshes.tresca2d(n)` builds both rectangles with structured triangles of size $1/n$; the
# block's bottom nodes coincide with foundation nodes, as node-to-node contact needs. The
# friction is an argument of the contact pair.

# +
mesh = df.build_mesh(meshes.tresca2d, n=args.n, comm=comm)


def problem(friction):
    return df.ContactProblem(
        mesh, df.Elasticity(E, nu),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=tuple(args.shift))],
        contact=[df.NodeToNode(slave="block_bottom", master="foundation_top",
                               friction=friction)],
        decomposition=df.Parts(args.parts))


solution = df.solve(problem(df.Tresca(args.g)), comm=comm, options=sys.argv,
                    rtol=args.rtol)
frictionless = df.solve(problem(None), comm=comm, options=sys.argv, rtol=args.rtol)
report = solution.report
# -

# ## Stick and slip
#
# `solution.contact` holds per contact node the normal force and pressure, the friction force
# on the block (`tangential_force`, a vector) and traction, the relative slip of the block
# against the foundation (`slip`), the nodal bound (`slip_bound`) and the state (`STICK` or
# `SLIP`). Where a node slips, the slip points against the friction force.

# +
c = solution.contact
order = np.argsort(c.x[:, 0])
x = c.x[order, 0]
p = c.pressure[order]
q = c.tangential_traction[order, 0]
slip = c.slip[order, 0]
state = c.state[order]
stick = state == df.ContactData.STICK
ft = np.linalg.norm(c.tangential_force, axis=1)
umax = np.abs(solution.nodal_values()).max()
checks = {
    "max |lambda_T| / g": float((ft / c.slip_bound).max()),
    "max |slip| at stick nodes / max|u|": float(np.abs(c.slip[c.state == c.STICK]).max(initial=0)
                                                / umax),
    "slip against the friction force": bool(np.all(c.slip[c.state == c.SLIP, 0]
                                                   * c.tangential_force[c.state == c.SLIP, 0]
                                                   <= 0)),
}
# -

# ## Output: a plot of the tractions and the slip, XDMF, JSON

# +
if comm.rank == 0:
    args.out.mkdir(parents=True, exist_ok=True)
solution.write_xdmf(args.out / "tresca2d.xdmf")
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    for k in np.flatnonzero(stick):
        ax1.axvspan(x[k] - 0.5 / args.n, x[k] + 0.5 / args.n, color="0.9", lw=0)
        ax2.axvspan(x[k] - 0.5 / args.n, x[k] + 0.5 / args.n, color="0.9", lw=0)
    ax1.plot(x, p, "k.-", label="pressure $p$")
    cf = frictionless.contact
    of = np.argsort(cf.x[:, 0])
    ax1.plot(cf.x[of, 0], cf.pressure[of], "k:", label="pressure, frictionless")
    ax1.plot(x, -q, "o-", ms=3, color="C0", label="friction traction on the block, $-q_x$")
    ax1.axhline(args.g, color="C3", ls="--", label="slip bound $g$")
    ax1.set_ylabel("traction")
    ax1.legend(fontsize=8, loc="upper left")
    ax1.set_title(f"B4, Tresca g = {args.g}: stick (grey) / slip zones")
    ax2.plot(x, slip, "s-", ms=3, color="C1")
    ax2.set_ylabel("relative slip $(u_s - u_m)_x$")
    ax2.set_xlabel("x")
    fig.tight_layout()
    fig.savefig(args.out / "tresca2d_stick_slip.png", dpi=120)
if args.json:
    report.save_json(args.json)
# -

# ## Summary

if comm.rank == 0:
    print(report.summary())
    print("frictionless:", frictionless.report.hessian_mults, "F-multiplications; Tresca:",
          report.hessian_mults)
    print("stick/slip along the contact (x ascending):",
          "".join("S" if s else "-" for s in stick))
    print(f"stick zone: x in [{x[stick].min():.4f}, {x[stick].max():.4f}]" if stick.any()
          else "no stick zone")
    for k, v in checks.items():
        print(f"{k}: {v}")
    print(f"output in {args.out}/")
