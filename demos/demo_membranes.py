# # Two membranes in contact (Dostál's model problem, B1)
#
# Two unit squares $\Omega_1 = (0,1)^2$ and $\Omega_2 = (1,2)\times(0,1)$ carry membranes
# $-\Delta u_i = f_i$. $\Omega_1$ is clamped on $x = 0$; $\Omega_2$ floats and rests on
# $\Omega_1$ along $x = 1$: $u_1 \le u_2$ there, with complementarity. The loads are
# $f = -3$ on $(0,1)\times[0.75,1)$ and $f = -1$ on $(1,2)\times[0,0.25)$. The problem is
# solvable because the net load on $\Omega_2$, $-0.25$, pushes it onto $\Omega_1$; by the
# equilibrium of $\Omega_2$ the contact forces sum to exactly $0.25$ on every mesh.
#
# This is the seed's scalability benchmark: with a regular $H \times H$ decomposition, the
# number of $F$-multiplications should stay bounded as $H$ shrinks with $H/h$ fixed.
#
# Run: `python demos/demo_membranes.py --n 32 --H 0.25` (`--help` for options).

# +
import argparse
import sys
from pathlib import Path

import numpy as np
import ufl
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--n", type=int, default=32, help="elements per unit length")
parser.add_argument("--H", type=float, default=0.25,
                    help="subdomain size of a regular grid; 0 = one subdomain per membrane")
parser.add_argument("--rtol", type=float, default=1e-8)
parser.add_argument("--out", type=Path, default=Path("output/membranes"))
parser.add_argument("--json", type=Path, default=None)
args, _ = parser.parse_known_args()
comm = MPI.COMM_WORLD
# -

# The mesh: each square an $n \times n$ grid of squares cut along their
# $(i,j) \to (i+1,j+1)$ diagonals, with separate (matching) nodes on $x = 1$.

mesh = df.build_mesh(meshes.membranes, args.n, comm=comm)

# The load as a UFL expression of the coordinates, and the decomposition: either the two
# membranes themselves or a regular grid of $H \times H$ squares (a function of the cell
# midpoints).

# +


def source(x):
    left = ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0)
    right = ufl.conditional(ufl.lt(x[1], 0.25), -1.0, 0.0)
    return ufl.conditional(ufl.lt(x[0], 1.0), left, right)


if args.H > 0:
    k = int(round(2 / args.H))
    decomposition = df.ByFunction(
        lambda m: (np.floor(m[:, 0] / args.H) + k * np.floor(m[:, 1] / args.H)).astype(np.int64))
else:
    decomposition = df.ByTags()

problem = df.ContactProblem(
    mesh, df.Poisson(source=source),
    dirichlet=[df.Dirichlet("dirichlet")],
    contact=[df.NodeToNode(slave="contact_left", master="contact_right")],  # u_1 - u_2 <= 0
    decomposition=decomposition)
solution = df.solve(problem, comm=comm, options=sys.argv, rtol=args.rtol)
# -

# ## Checks and output
#
# The multiplier sum is a sharp, mesh-independent check; the energy can be compared with
# the reference table of `BENCHMARKS.md` for $n = 8 \dots 256$.

# +
reference = {8: -0.25883957, 16: -0.26012652, 32: -0.26046064, 64: -0.26054510,
             128: -0.26056624, 256: -0.26057153}
energy = solution.energy
force_sum = solution.contact.force.sum()
solution.write_xdmf(args.out / "membranes.xdmf")
if args.json:
    solution.report.save_json(args.json)
if comm.rank == 0:
    print(solution.report.summary())
    print(f"sum of contact forces = {force_sum:.12f} (exact: 0.25)")
    if args.n in reference:
        ref = reference[args.n]
        print(f"energy = {energy:.10f}, reference {ref:.8f}, relative difference "
              f"{abs(energy - ref) / abs(ref):.1e}")
    in_contact = solution.contact.x[solution.contact.force > 1e-10, 1]
    print(f"contact set on x = 1: y in [{in_contact.min():.6f}, {in_contact.max():.6f}]")
# -
