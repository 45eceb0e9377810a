# # Two stacked blocks (3D)
#
# A block $[0,1]^2\times[0.5,1]$ rests on a block $[0,1]^2\times[0,0.5]$; the lower one is
# clamped at the bottom and the upper one is pressed by a uniform traction $q$ on its top. The
# contact surfaces have matching nodes. The upper block's horizontal motions are held by
# rollers on its sides ($u_x = u_y = 0$), so its only support in the vertical direction is the
# contact. Equilibrium demands that the contact forces add up to the applied load $q \cdot 1$.
#
# Run: `python demos/demo_blocks3d.py --n 6 --parts 2` (`--help` for options).

# +
import argparse
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--n", type=int, default=6, help="elements per unit length")
parser.add_argument("--parts", type=int, default=2, help="subdomains per block")
parser.add_argument("--q", type=float, default=1.0, help="pressure on the top")
parser.add_argument("--rtol", type=float, default=1e-8)
parser.add_argument("--out", type=Path, default=Path("output/blocks3d"))
parser.add_argument("--json", type=Path, default=None)
args, _ = parser.parse_known_args()
comm = MPI.COMM_WORLD

mesh = df.build_mesh(meshes.blocks3d, args.n, comm=comm)
# -

# The two blocks may have different materials: the forms helper takes one value per body.

problem = df.ContactProblem(
    mesh,
    df.Elasticity(E={"lower": 1000.0, "upper": 500.0}, nu=0.3,
                  tractions={"top": (0.0, 0.0, -args.q)}),
    dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sides_upper", components=[0, 1])],
    contact=[df.NodeToNode(slave="contact_upper", master="contact_lower")],
    decomposition=df.Parts(args.parts))
solution = df.solve(problem, comm=comm, options=sys.argv, rtol=args.rtol)

# ## Equilibrium and output

# +
force = solution.total_contact_force
solution.write_xdmf(args.out / "blocks3d.xdmf")
if args.json:
    solution.report.save_json(args.json)
if comm.rank == 0:
    print(solution.report.summary())
    print(f"total contact force = {force.round(12)}, applied load = {args.q:.6f}, relative "
          f"error {abs(force[2] - args.q) / args.q:.1e}")
    print(f"largest penetration = {solution.report.max_penetration:.2e}; "
          f"mean pressure = {np.mean(solution.contact.pressure):.6f}")
# -
