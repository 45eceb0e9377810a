"""dolfinx_feti: contact problems of elasticity by FETI domain decomposition with MPRGP/SMALBE.

A user describes bodies in gmsh, writes the forms in UFL, and calls :func:`solve`::

    mesh = dolfinx_feti.read_gmsh("model.msh")
    problem = dolfinx_feti.ContactProblem(
        mesh, dolfinx_feti.Elasticity(E=200.0, nu=0.3, tractions={"load": (0.0, -1.0)}),
        dirichlet=[dolfinx_feti.Dirichlet("bottom")],
        contact=[dolfinx_feti.NodeToNode(slave="disk_contact", master="block_contact")])
    solution = dolfinx_feti.solve(problem, rtol=1e-8)
"""

# compat first: it loads MPI before PETSc and DOLFINx, as DOLFINx 0.11's wheel needs.
from . import compat  # noqa: F401
from .drivers import newton as _newton  # noqa: F401  (registers solve_by = "newton")
from .drivers import newton_path as _newton_path  # noqa: F401  (and its load paths)
from .drivers.load_path import solve_cases, solve_path
from .errors import InputError, NotConverged, SolveError
from .fem import Elasticity, Poisson, Subdomain
from .fem.hyperelastic import Hyperelastic, NeoHookean, SaintVenantKirchhoff
from .mesh import (
    Auto,
    ByFunction,
    ByTags,
    MeshData,
    MixedMesh,
    Parts,
    build_mesh,
    from_dolfinx,
    read_gmsh,
)
from .options import SolverOptions
from .problem import (
                      ContactProblem,
                      Coulomb,
                      Cylinder,
                      Dirichlet,
                      Mortar,
                      NodeToNode,
                      Plane,
                      RigidObstacle,
                      SignedDistance,
                      Sphere,
                      Tie,
                      Tresca,
)
from .problem.rigid_motion import RigidMotion
from .results.report import Report
from .results.solution import ContactData, Solution
from .setup.stages import DualQP, dual_qp
from .solver import FetiSolver, solve

__all__ = ["Auto", "ByFunction", "ByTags", "ContactData", "ContactProblem", "Coulomb",
           "Cylinder", "Dirichlet", "DualQP", "Elasticity", "FetiSolver", "Hyperelastic",
           "InputError", "MeshData", "MixedMesh", "Mortar", "NeoHookean", "NodeToNode",
           "NotConverged", "Parts", "Plane", "Poisson", "Report", "RigidMotion",
           "RigidObstacle",
           "SaintVenantKirchhoff", "SignedDistance", "Solution", "SolveError", "SolverOptions",
           "Sphere", "Subdomain", "Tie", "Tresca", "build_mesh", "dual_qp", "from_dolfinx",
           "read_gmsh", "solve", "solve_cases", "solve_path"]
