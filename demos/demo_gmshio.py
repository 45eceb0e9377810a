# # From gmsh through DOLFINx: a cylinder on a rigid plane, curved cells, degree 2
#
# A FEniCSx user usually has a DOLFINx mesh already: read from gmsh by `dolfinx.io.gmshio`,
# distributed over the ranks, with cell tags and facet tags. `df.from_dolfinx` takes it as it
# is; the solution comes back as a `dolfinx.fem.Function` on that very mesh, so the user goes
# on with UFL and DOLFINx's own output.
#
# The problem: an elastic cylinder of radius $R = 1$ ($E = 100$, $\nu = 0.3$, plane strain)
# pressed by a line load $P = 0.5$ onto a rigid plane; half model by symmetry. Hertz's theory
# for a cylinder on a rigid flat gives the contact half-width and peak pressure
#
# $$ a = 2\sqrt{\frac{R P}{\pi E^*}}, \qquad p_0 = \frac{2P}{\pi a}, \qquad
#    E^* = \frac{E}{1 - \nu^2}. $$
#
# The quarter disk is meshed with curved second-order quadrilaterals (gmsh's `setOrder(2)`:
# the edge nodes lie on the circle), so the displacement space is isoparametric Q2.
#
# Run: `python demos/demo_gmshio.py` (or under `mpirun -n 2`); `--help` lists options.

# +
import argparse
import sys
from pathlib import Path

# mpi4py before dolfinx: DOLFINx 0.11's PyPI wheel finds its MPI library once mpi4py has loaded it
from mpi4py import MPI

# isort: split
import dolfinx.fem
import dolfinx.io
import gmsh
import numpy as np
import ufl

import dolfinx_feti as df

try:  # DOLFINx 0.5 to 0.9
    from dolfinx.io import gmshio
except ImportError:  # DOLFINx 0.10 and later
    from dolfinx.io import gmsh as gmshio

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=float, default=0.02, help="element size at the contact")
parser.add_argument("--parts", type=int, default=4, help="subdomains")
parser.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance")
parser.add_argument("--out", type=Path, default=Path("output/gmshio"), help="output folder")
parser.add_argument("--json", type=Path, default=None, help="write the solve report here")
args, _ = parser.parse_known_args()  # -feti_* options: read by df.solve(options=sys.argv)
comm = MPI.COMM_WORLD
R, P, E, nu = 1.0, 0.5, 100.0, 0.3
# -

# ## The gmsh model, on rank 0
#
# A quarter disk $x \ge 0$, $y \le R$ of the disk centred at $(0, R)$, which touches the plane
# $y = 0$ at the origin. Physical groups name the body and the boundary parts; the mesh is
# refined towards the contact point and recombined into quadrilaterals.

# +
names = None
if comm.rank == 0:
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    occ = gmsh.model.occ
    disk = occ.addDisk(0, R, 0, R, R)
    box = occ.addRectangle(0, 0, 0, R, R)
    quarter, _ = occ.intersect([(2, disk)], [(2, box)])
    occ.synchronize()
    surface = quarter[0][1]
    curves = {}
    for _, c in gmsh.model.getBoundary(quarter, oriented=False):
        x, y, _ = occ.getCenterOfMass(1, c)
        curves["symmetry" if x < 1e-9 else "load" if abs(y - R) < 1e-9 else "arc"] = c
    names = {"cylinder": (2, 1), "arc": (1, 11), "load": (1, 12), "symmetry": (1, 13)}
    gmsh.model.addPhysicalGroup(2, [surface], 1)
    for name, (dim, tag) in names.items():
        gmsh.model.setPhysicalName(dim, tag, name)
        if dim == 1:
            gmsh.model.addPhysicalGroup(1, [curves[name]], tag)
            gmsh.model.setPhysicalName(1, tag, name)
    origin = occ.addPoint(0, 0, 0)
    occ.synchronize()
    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "PointsList", [origin])
    size = field.add("Threshold")
    field.setNumber(size, "InField", dist)
    field.setNumber(size, "SizeMin", args.h)
    field.setNumber(size, "SizeMax", 0.2)
    field.setNumber(size, "DistMin", 0.3)
    field.setNumber(size, "DistMax", 1.0)
    field.setAsBackgroundMesh(size)
    gmsh.option.setNumber("Mesh.RecombineAll", 1)
    gmsh.model.mesh.generate(2)
    gmsh.model.mesh.setOrder(2)
names = comm.bcast(names, root=0)
# -

# ## DOLFINx reads it, distributed; `from_dolfinx` takes it
#
# `model_to_mesh` returns the mesh with its cell and facet tags (DOLFINx 0.10 and later return
# them in one object, with the names: `from_dolfinx` accepts that object whole). The names of
# the physical groups map group names to tags.

# +
out = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=2)
if comm.rank == 0:
    gmsh.finalize()
if hasattr(out, "facet_tags"):  # DOLFINx 0.10 and later: one object, names included
    msh, facet_tags = out.mesh, out.facet_tags
    mesh = df.from_dolfinx(out)
else:
    msh, cell_tags, facet_tags = out
    mesh = df.from_dolfinx(msh, cell_tags, facet_tags, names=names)
# -

# ## The problem and the solve
#
# The load acts on the flat top, the symmetry plane $x = 0$ has $u_x = 0$, and the arc may
# not cross the rigid plane $y \ge 0$ (whose outward normal is $(0, 1)$ towards the body).
# The mesh is curved, so `df.Elasticity` takes degree 2 (isoparametric).

# +
plane = df.Plane(point=(0.0, 0.0), normal=(0.0, 1.0))
problem = df.ContactProblem(
    mesh, df.Elasticity(E, nu, tractions={"load": (0.0, -P / 2 / R)}),
    dirichlet=[df.Dirichlet("symmetry", components=[0])],
    contact=[df.RigidObstacle("arc", plane)],
    decomposition=df.Parts(args.parts))
solution = df.solve(problem, comm=comm, options=sys.argv, rtol=args.rtol)
# -

# ## Back in DOLFINx: the solution is a Function on the user's mesh
#
# `solution.u` lives on `msh` itself: UFL works on it directly. Here the strain energy and the
# work of the load, whose difference is the energy the solver minimized, and the output to
# XDMF with DOLFINx's own writer (degree 2 on the degree-2 mesh).

# +
u = solution.u
assert u.function_space.mesh is msh
mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
eps = ufl.sym(ufl.grad(u))
sigma = 2 * mu * eps + lmbda * ufl.tr(eps) * ufl.Identity(2)
ds = ufl.Measure("ds", domain=msh, subdomain_data=facet_tags)
load = ufl.as_vector((0.0, -P / 2 / R))


def integral(form):
    return comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(form)), op=MPI.SUM)


strain_energy = integral(0.5 * ufl.inner(sigma, eps) * ufl.dx)
work = integral(ufl.inner(load, u) * ds(names["load"][1]))
args.out.mkdir(parents=True, exist_ok=True) if comm.rank == 0 else None
comm.barrier()
with dolfinx.io.XDMFFile(comm, str(args.out / "cylinder.xdmf"), "w") as f:
    f.write_mesh(msh)
    f.write_function(u)
# -

# ## Comparison with Hertz

# +
E_star = E / (1 - nu**2)
a = 2 * np.sqrt(R * P / (np.pi * E_star))
p0 = 2 * P / (np.pi * a)
c = solution.contact
x, p = c.x[:, 0], c.pressure
active = p > 1e-8 * p.max()
hertz = p0 * np.sqrt(np.maximum(1 - x**2 / a**2, 0.0))
inner = x < 0.9 * a
energy = solution.energy  # collective: on every rank
if comm.rank == 0:
    print(solution.report.summary())
    print(f"mesh: {mesh.cells.shape[0]} curved {mesh.cell_type}s, "
          f"{problem.dof_points.num_points} dof points (degree {problem.degree})")
    print(f"energy: UFL on the user's mesh {strain_energy - work:.8e}, "
          f"solver {energy:.8e}")
    print(f"Hertz: a = {a:.4f}, p0 = {p0:.4f}; computed: last point in contact at "
          f"x = {x[active].max():.4f}, peak {p.max():.4f} ({100 * (p.max() - p0) / p0:+.2f} %), "
          f"largest error for x < 0.9 a: {100 * np.abs(p - hertz)[inner].max() / p0:.2f} % of p0")
    print(f"total contact force {solution.total_contact_force[1]:.6f} (P/2 = {P / 2})")
    print(f"output: {args.out / 'cylinder.xdmf'}")
if args.json:
    solution.report.save_json(args.json)
# -
