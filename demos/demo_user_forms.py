# # Your own UFL forms: a heated block expanding against a rigid wall
#
# The helpers `df.Elasticity` and `df.Poisson` cover the common cases. Anything else is a
# function `forms(V, sub) -> (a, L)` that writes the bilinear and linear forms in UFL on the
# function space `V` the library gives for a subdomain; `sub` gives the measures (`sub.dx()`,
# `sub.ds("group")`) and per-body coefficients (`sub.cellwise({...})`).
#
# Here: thermal expansion. A block $[0, 1]^2$ (plane strain, $E = 100$, $\nu = 0.3$) rests on
# rollers at the bottom and on a symmetry plane on the left; it is heated by $\Delta T$ with
# expansion coefficient $\alpha$, so that its stress is
# $\sigma = \mathbb{C} : (\varepsilon(u) - \alpha \Delta T\, I)$ (with $\varepsilon_{zz} = 0$).
# On the right, at a gap $g_0$ (half of the free expansion), stands a rigid wall: the block
# touches it and presses on it. The state is homogeneous, so the contact pressure has an
# exact value,
#
# $$ \varepsilon_{xx} = g_0, \quad
#    \varepsilon_{yy} = \frac{(3\lambda + 2\mu)\theta - \lambda g_0}{\lambda + 2\mu}, \quad
#    p = -\sigma_{xx} = -\lambda(\varepsilon_{xx} + \varepsilon_{yy} - 3\theta)
#        - 2\mu(\varepsilon_{xx} - \theta), \quad \theta = \alpha\Delta T, $$
#
# which every element reproduces to solver tolerance: the demo checks it, on quadrilaterals
# with a degree-2 space (`degree=2` of `ContactProblem`, since the forms are our own).
#
# Run: `python demos/demo_user_forms.py` (or under `mpirun -n 2`); `--help` lists options.

# +
import argparse
import sys
from pathlib import Path

import gmsh
import numpy as np
import ufl
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io.meshes import physical_groups

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=float, default=0.1, help="element size")
parser.add_argument("--degree", type=int, default=2, help="Lagrange degree (1 or 2)")
parser.add_argument("--parts", type=int, default=4, help="subdomains")
parser.add_argument("--rtol", type=float, default=1e-10, help="relative tolerance")
parser.add_argument("--out", type=Path, default=Path("output/user_forms"),
                    help="output folder")
parser.add_argument("--json", type=Path, default=None, help="write the solve report here")
args, _ = parser.parse_known_args()  # -feti_* options: read by df.solve(options=sys.argv)
comm = MPI.COMM_WORLD
E, nu, theta = 100.0, 0.3, 1e-3  # theta = alpha * Delta T
mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
# -

# ## The mesh: quadrilaterals from gmsh
#
# A unit square meshed by gmsh and recombined into quadrilaterals, with physical groups for the
# body and the four sides. `build_mesh` runs the model on rank 0 and shares the mesh.


# +
def square(h):
    s = gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
    gmsh.model.occ.synchronize()
    gmsh.model.addPhysicalGroup(2, [s], 1)
    gmsh.model.setPhysicalName(2, 1, "block")
    for tag, (name, box) in enumerate({"left": (-0.1, -0.1, 0.1, 1.1),
                                       "right": (0.9, -0.1, 1.1, 1.1),
                                       "bottom": (-0.1, -0.1, 1.1, 0.1)}.items(), start=11):
        a, b, c, d = box
        curves = [e for _, e in gmsh.model.getEntitiesInBoundingBox(a, b, -1, c, d, 1, 1)]
        gmsh.model.addPhysicalGroup(1, curves, tag)
        gmsh.model.setPhysicalName(1, tag, name)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.RecombineAll", 1)
    gmsh.model.mesh.generate(2)
    return physical_groups()


mesh = df.build_mesh(square, args.h, comm=comm)
# -

# ## The forms
#
# The thermal strain enters the linear form: $a(u, v) = \int \sigma_e(u) : \varepsilon(v)$,
# $L(v) = \int (3\lambda + 2\mu)\,\theta\, \mathrm{tr}\,\varepsilon(v)$ (the stress of the
# thermal strain $\theta I_3$ restricted to the plane). `V` is the space the library gives:
# vector valued, of the problem's degree, on the subdomain's own serial mesh. A form on
# another space is refused with a message that says so.


# +
def forms(V, sub):
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)

    def eps(w):
        return ufl.sym(ufl.grad(w))

    def sigma(w):
        return 2 * mu * eps(w) + lmbda * ufl.tr(eps(w)) * ufl.Identity(2)

    a = ufl.inner(sigma(u), eps(v)) * sub.dx()
    L = (3 * lmbda + 2 * mu) * theta * ufl.tr(eps(v)) * sub.dx()
    return a, L


free = (3 * lmbda + 2 * mu) * theta / (2 * lmbda + 2 * mu)  # free expansion in x and y
g0 = 0.5 * free
wall = df.Plane(point=(1.0 + g0, 0.0), normal=(-1.0, 0.0))  # the obstacle is x >= 1 + g0
problem = df.ContactProblem(
    mesh, forms, value_size=2, degree=args.degree,
    dirichlet=[df.Dirichlet("left", components=[0]), df.Dirichlet("bottom", components=[1])],
    contact=[df.RigidObstacle("right", wall)],
    decomposition=df.Parts(args.parts))
solution = df.solve(problem, comm=comm, options=sys.argv, rtol=args.rtol)
# -

# ## Check against the exact state

# +
e_yy = ((3 * lmbda + 2 * mu) * theta - lmbda * g0) / (lmbda + 2 * mu)
p_exact = -lmbda * (g0 + e_yy - 3 * theta) - 2 * mu * (g0 - theta)
x = problem.dof_points.x  # the dof points of the degree-2 space
u_exact = np.stack([g0 * x[:, 0], e_yy * x[:, 1]], axis=1)
u_err = np.abs(solution.nodal_values() - u_exact).max() / np.abs(u_exact).max()
p_err = np.abs(solution.contact.pressure - p_exact).max() / p_exact
if comm.rank == 0:
    print(solution.report.summary())
    print(f"contact pressure: exact {p_exact:.6f}, computed {solution.contact.pressure.min():.6f}"
          f" .. {solution.contact.pressure.max():.6f} (relative error {p_err:.1e})")
    print(f"displacement: relative error {u_err:.1e} at {x.shape[0]} dof points")
assert solution.report.converged and u_err < 1e-8 and p_err < 1e-8
args.out.mkdir(parents=True, exist_ok=True) if comm.rank == 0 else None
solution.write_xdmf(args.out / "thermal_wall.xdmf")  # displacement and contact pressure
if args.json:
    solution.report.save_json(args.json)
# -
