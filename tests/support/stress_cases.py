"""The stress cases of issue 7, shared by ``tests/test_stress_*.py`` and ``bench/stress.py``.

Each case is a function of its size (and its parameter) that builds the problem, solves it and
returns a :class:`Case` (the solution or the error, the time, the measured numbers). The tests
call them at a reduced size and assert; ``bench/stress.py`` calls them at the full size and
writes the table of ``docs/robustness.md``.

Geometries are gmsh models built here (run on rank 0 by :func:`dolfinx_feti.build_mesh`). The
material data enter the forms as ``dolfinx.fem.Constant`` (:class:`ConstElasticity`), so a new
value of E or ν costs no new form compilation. :func:`monolithic` is an independent reference
(undecomposed, assembled by ``tests/support/reference.py``, solved by a primal–dual active set
method)
for problems with rigid obstacles and prescribed values.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import dolfinx
import gmsh
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import ufl
from mpi4py import MPI
from petsc4py import PETSc

import dolfinx_feti as df

COMM = MPI.COMM_WORLD

# ------------------------------------------------------------------------------------------
# Geometries (gmsh generators: call through df.build_mesh)
# ------------------------------------------------------------------------------------------


def _name(dim: int, tags: Sequence[int], tag: int, name: str) -> None:
    gmsh.model.addPhysicalGroup(dim, list(tags), tag)
    gmsh.model.setPhysicalName(dim, tag, name)


def _curves_in(x0, y0, x1, y1, eps=1e-7) -> list[int]:
    return [c for _, c in gmsh.model.getEntitiesInBoundingBox(x0 - eps, y0 - eps, -1, x1 + eps,
                                                               y1 + eps, 1, 1)]


def composite(h: float = 0.05, k: int = 2, fill: float = 0.5) -> None:
    """The unit square "matrix" with k×k square "inclusions", glued (one model, fragment).

    Inclusion (i, j) is the square of side fill/k centred in the cell (i, j) of a k×k grid; the
    fragment makes matrix and inclusions share their nodes on the interfaces. Boundary groups:
    "bottom" (y = 0), "top" (y = 1), "interface" (the boundaries of the inclusions).
    """
    gmsh.model.add("composite")
    occ = gmsh.model.occ
    m = occ.addRectangle(0, 0, 0, 1, 1)
    s = fill / k
    squares = [occ.addRectangle((i + 0.5) / k - s / 2, (j + 0.5) / k - s / 2, 0, s, s)
               for i in range(k) for j in range(k)]
    occ.fragment([(2, m)], [(2, t) for t in squares])
    occ.synchronize()
    surfaces = [t for _, t in gmsh.model.getEntities(2)]
    incl = [t for t in surfaces if occ.getMass(2, t) < s * s * (1 + 1e-9)]
    _name(2, [t for t in surfaces if t not in incl], 1, "matrix")
    _name(2, incl, 2, "inclusions")
    _name(1, _curves_in(0, 0, 1, 0), 11, "bottom")
    _name(1, _curves_in(0, 1, 1, 1), 12, "top")
    iface = {abs(c) for t in incl for _, c in gmsh.model.getBoundary([(2, t)], oriented=False)}
    _name(1, sorted(iface), 13, "interface")
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.model.mesh.generate(2)


def rectangle(width: float = 1.0, height: float = 1.0, n: int = 8, structured: bool = True
              ) -> None:
    """A rectangle "block" [0, width] × [0, height], ``n`` cells per unit length.

    Boundary groups "block_bottom", "top", "left", "right" and "block_sides" (left and right).
    Structured: Kuhn triangles of a grid of squares (a discrete model); otherwise gmsh's
    unstructured triangles of size 1/n.
    """
    if structured:
        nx, ny = max(1, round(n * width)), max(1, round(n * height))
        x, cells = grid_arrays(nx, ny, h=1.0)
        x = x * [width / nx, height / ny]
        k = np.arange(nx + 1)
        row = np.arange(ny + 1) * (nx + 1)

        def chain(idx):
            return np.stack([idx[:-1], idx[1:]], axis=1)

        left, right = chain(row), chain(row + nx)
        from_arrays(x, cells, {"block": np.arange(cells.shape[0])},
                    {"block_bottom": chain(k), "top": chain(k + ny * (nx + 1)), "left": left,
                     "right": right, "block_sides": np.concatenate([left, right])})
        return
    gmsh.model.add("rectangle")
    r = gmsh.model.occ.addRectangle(0, 0, 0, width, height)
    gmsh.model.occ.synchronize()
    _name(2, [r], 1, "block")
    _name(1, _curves_in(0, 0, width, 0), 11, "block_bottom")
    _name(1, _curves_in(0, height, width, height), 12, "top")
    _name(1, _curves_in(0, 0, 0, height), 13, "left")
    _name(1, _curves_in(width, 0, width, height), 14, "right")
    _name(1, _curves_in(0, 0, 0, height) + _curves_in(width, 0, width, height), 15,
          "block_sides")
    gmsh.option.setNumber("Mesh.MeshSizeMax", 1.0 / n)
    gmsh.model.mesh.generate(2)


def corner_squares(n: int = 4, glued: bool = True) -> None:
    """Two unit squares of one body "body" that touch only at the corner (1, 1).

    "A" = [0,1]², "B" = [1,2]×[1,2]. ``glued``: the corner is one node (fragment); otherwise
    each square has its own node there. Groups: "bottom_a" (y = 0 of A), "bottom_b" (y = 1 of
    B), "top_b" (y = 2 of B).
    """
    gmsh.model.add("corner_squares")
    occ = gmsh.model.occ
    a = occ.addRectangle(0, 0, 0, 1, 1)
    b = occ.addRectangle(1, 1, 0, 1, 1)
    if glued:
        occ.fragment([(2, a)], [(2, b)])
    occ.synchronize()
    _name(2, [t for _, t in gmsh.model.getEntities(2)], 1, "body")
    _name(1, _curves_in(0, 0, 1, 0), 11, "bottom_a")
    _name(1, _curves_in(1, 1, 2, 1), 12, "bottom_b")
    _name(1, _curves_in(1, 2, 2, 2), 13, "top_b")
    gmsh.option.setNumber("Mesh.MeshSizeMax", 1.0 / n)
    gmsh.model.mesh.generate(2)


def two_squares_one_body(n: int = 4, glued: bool = True, n_right: int | None = None) -> None:
    """[0,1]² and [1,2]×[0,1] in one body "plate" (glued by fragment, or not glued).

    Not glued, each square has its own nodes on x = 1: coincident duplicates with the same mesh
    size, hanging nodes with ``n_right`` != n. Groups "left" (x = 0), "right" (x = 2).
    """
    gmsh.model.add("two_squares")
    occ = gmsh.model.occ
    a = occ.addRectangle(0, 0, 0, 1, 1)
    b = occ.addRectangle(1, 0, 0, 1, 1)
    if glued:
        occ.fragment([(2, a)], [(2, b)])
    occ.synchronize()
    _name(2, [t for _, t in gmsh.model.getEntities(2)], 1, "plate")
    _name(1, _curves_in(0, 0, 0, 1), 11, "left")
    _name(1, _curves_in(2, 0, 2, 1), 12, "right")
    gmsh.option.setNumber("Mesh.MeshSizeMax", 1.0 / n)
    if n_right is not None and not glued:
        pts = gmsh.model.getBoundary([(2, b)], recursive=True)
        gmsh.model.mesh.setSize(pts, 1.0 / n_right)
    gmsh.model.mesh.generate(2)


def from_arrays(x: np.ndarray, cells: np.ndarray, bodies: dict[str, np.ndarray],
                facets: dict[str, np.ndarray]) -> None:
    """A gmsh model holding exactly the given triangles (discrete entities), no checks.

    Args:
        x: (N, 2) node coordinates.
        cells: (C, 3) triangles (node indices).
        bodies: body name → its cells (indices into ``cells``).
        facets: boundary group name → (F, 2) node pairs (may be empty).
    """
    gmsh.model.add("arrays")
    tags = np.arange(1, x.shape[0] + 1)
    xyz = np.zeros((x.shape[0], 3))
    xyz[:, :2] = x
    holder = gmsh.model.addDiscreteEntity(2)
    gmsh.model.mesh.addNodes(2, holder, tags.tolist(), xyz.ravel().tolist())
    for i, (name, which) in enumerate(bodies.items()):
        e = holder if i == 0 else gmsh.model.addDiscreteEntity(2)
        if len(which):
            gmsh.model.mesh.addElementsByType(e, 2, [], tags[cells[which]].ravel().tolist())
        _name(2, [e], i + 1, name)
    for j, (name, f) in enumerate(facets.items()):
        e = gmsh.model.addDiscreteEntity(1)
        if len(f):
            gmsh.model.mesh.addElementsByType(e, 1, [], tags[np.asarray(f)].ravel().tolist())
        _name(1, [e], 11 + j, name)


def grid_arrays(nx: int, ny: int, x0: float = 0.0, y0: float = 0.0, h: float = 1.0
                ) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and Kuhn triangles of an nx × ny grid of squares of side h."""
    i, j = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="xy")
    x = np.stack([x0 + h * i.ravel(), y0 + h * j.ravel()], axis=1)
    v = (np.arange(ny)[:, None] * (nx + 1) + np.arange(nx)[None, :]).ravel()
    cells = np.concatenate([np.stack([v, v + 1, v + nx + 2], axis=1),
                            np.stack([v, v + nx + 2, v + nx + 1], axis=1)])
    return x, cells


# ------------------------------------------------------------------------------------------
# Forms with constants (no recompilation for new values)
# ------------------------------------------------------------------------------------------


def _const(V, value):
    return dolfinx.fem.Constant(V.mesh, PETSc.ScalarType(value))


class ConstElasticity:
    """Plane-strain elasticity with E, ν per body as ``Constant``s, constant tractions.

    Like :class:`dolfinx_feti.Elasticity` (the same forms), but a new value of E or ν reuses
    the compiled form: the tests and the benchmark sweep E ratios and ν without compiling.
    """

    value_size = "vector"

    def __init__(self, E: float | dict, nu: float | dict,
                 tractions: dict[str, Sequence[float]] | None = None,
                 zero_E: Sequence[str] = ()) -> None:
        self.E, self.nu, self.tractions = E, nu, dict(tractions or {})
        self.zero_E = tuple(zero_E)  # bodies whose stiffness is multiplied by 0 (a fault)

    def _value(self, v, body):
        return v[body] if isinstance(v, dict) else v

    def check(self, mesh) -> None:
        for name in self.tractions:
            mesh.facets(name)

    def __call__(self, V, sub):
        u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
        d = len(u)

        def eps(z):
            return ufl.sym(ufl.grad(z))

        a = 0
        for body in sub.bodies:
            E = _const(V, 0.0 if body in self.zero_E else self._value(self.E, body))
            nu = _const(V, self._value(self.nu, body))
            mu, lmbda = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
            sig = 2 * mu * eps(u) + lmbda * ufl.tr(eps(u)) * ufl.Identity(d)
            a = a + ufl.inner(sig, eps(w)) * sub.dx(body)
        L = None
        for name, t in self.tractions.items():
            if sub.has_facets(name):
                term = ufl.inner(dolfinx.fem.Constant(V.mesh, np.asarray(t, dtype=float)), w) \
                    * sub.ds(name)
                L = term if L is None else L + term
        return a, L


# ------------------------------------------------------------------------------------------
# An independent monolithic reference with obstacles and prescribed values
# ------------------------------------------------------------------------------------------


def monolithic(mesh: df.MeshData, E: float | dict, nu: float | dict, *,
               dirichlet: Sequence[tuple[str, Sequence[int] | None, Sequence[float]]] = (),
               obstacles: Sequence[tuple[str, object]] = (),
               tractions: dict[str, Sequence[float]] | None = None) -> np.ndarray:
    """Nodal displacement (N, 2) of the undecomposed problem (serial, every rank alike).

    K and f are assembled by ``tests/support/reference.py`` (bodies glued through shared nodes),
    Dirichlet values eliminated, obstacle rows −n·u <= φ/|∇φ| at the nodes of each group, and
    the QP solved by a primal–dual active set method (exact to round-off).
    """
    import reference as ref

    def forms(u, v, x, body):
        msh = u.ufl_function_space().mesh
        Eb = dolfinx.fem.Constant(msh, PETSc.ScalarType(E[body] if isinstance(E, dict) else E))
        nb = dolfinx.fem.Constant(msh, PETSc.ScalarType(nu[body] if isinstance(nu, dict)
                                                         else nu))
        mu, lmbda = Eb / (2 * (1 + nb)), Eb * nb / ((1 + nb) * (1 - 2 * nb))
        e_u, e_v = ufl.sym(ufl.grad(u)), ufl.sym(ufl.grad(v))
        return ufl.inner(2 * mu * e_u + lmbda * ufl.tr(e_u) * ufl.Identity(2), e_v) * ufl.dx, \
            None

    K, f = ref.assemble(mesh, 2, forms)
    for group, t in (tractions or {}).items():
        f = f + ref.traction_load(mesh, group, t)
    n = K.shape[0]
    fixed = np.zeros(n, dtype=bool)
    value = np.zeros(n)
    for group, comps, val in dirichlet:
        nodes = np.unique(mesh.facet_groups[group])
        for j, c in enumerate(range(2) if comps is None else comps):
            fixed[2 * nodes + c] = True
            value[2 * nodes + c] = np.broadcast_to(np.asarray(val, dtype=float), (2,))[j]
    rows, cols, vals, g = [], [], [], []
    r0 = 0
    for group, obstacle in obstacles:
        nodes = np.unique(mesh.facet_groups[group])
        phi, grad = obstacle.distance(mesh.x[nodes])
        gn = np.linalg.norm(grad, axis=1)
        nrm = grad / gn[:, None]
        for c in range(2):
            rows.append(r0 + np.arange(nodes.size))
            cols.append(2 * nodes + c)
            vals.append(-nrm[:, c])
        g.append(phi / gn)
        r0 += nodes.size
    B = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(r0, n)) if r0 else sp.csr_matrix((0, n))
    g = np.concatenate(g) if g else np.zeros(0)
    free = np.flatnonzero(~fixed)
    Kf = K[free][:, free].tocsc()
    ff = f[free] - K[free][:, fixed] @ value[fixed]
    Bf = B[:, free].tocsr()
    gf = g - B[:, fixed] @ value[fixed]
    c = float(np.mean(K.diagonal()))
    live = np.diff(Bf.indptr) > 0  # rows on fixed dofs only hold or not by themselves
    if np.any(gf[~live] < -1e-14 * max(1.0, np.abs(gf).max(initial=0.0))):
        raise RuntimeError("monolithic reference: prescribed values penetrate an obstacle")
    active = live.copy()
    for _ in range(100):
        BA = Bf[active]
        KKT = sp.bmat([[Kf, BA.T], [BA, None]], format="csc")
        rhs = np.r_[ff, gf[active]]
        lu = spla.splu(KKT)
        z = lu.solve(rhs)
        for _ in range(3):
            z += lu.solve(rhs - KKT @ z)
        lam = np.zeros(r0)
        lam[active] = z[free.size:]
        new = (lam + c * (Bf @ z[:free.size] - gf) > 0.0) & live
        if np.array_equal(new, active):
            break
        active = new
    else:
        raise RuntimeError("monolithic reference: the active set method did not converge")
    u = value.copy()
    u[free] = z[:free.size]
    return u.reshape(-1, 2)


# ------------------------------------------------------------------------------------------
# Running a case
# ------------------------------------------------------------------------------------------


@dataclass
class Case:
    """The outcome of one stress case: a solution or an error, with what was measured.

    Attributes:
        name: The case (first column of the table).
        solution: The solution, or None when the solve raised.
        error: The exception raised, or None.
        seconds: Wall time of the solve (problem set-up included, mesh excluded).
        numbers: Anything measured (differences to a reference, sizes, ...).
    """

    name: str
    solution: df.Solution | None = None
    error: Exception | None = None
    seconds: float = 0.0
    numbers: dict = field(default_factory=dict)

    @property
    def report(self) -> df.Report:
        return self.solution.report

    def outcome(self) -> str:
        """One line for the table: iterations and residuals, or the error message."""
        if self.error is not None:
            msg = str(self.error)
            return f"{type(self.error).__name__}: {msg[:160]}{'…' if len(msg) > 160 else ''}"
        r = self.report
        kkt = max(v for k, v in r.kkt.items())
        state = "converged" if r.converged else f"**not converged** ({r.reason})"
        extra = "".join(f", {k} {_fmt(v)}" for k, v in self.numbers.items())
        return (f"{state}: {r.outer_iterations} outer / {r.iterations} inner it., "
                f"{r.hessian_mults} F-mults, max KKT {kkt:.1e}{extra}")


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.1e}" if v != 0 and (abs(v) < 1e-2 or abs(v) >= 1e4) else f"{v:.3g}"
    return str(v)


def run(name: str, build: Callable[[], df.ContactProblem], **options) -> Case:
    """Build and solve; an InputError/SolveError is recorded, not raised."""
    t0 = time.perf_counter()
    case = Case(name)
    try:
        case.solution = df.solve(build(), **options)
    except (df.InputError, df.SolveError) as e:
        case.error = e
    case.seconds = time.perf_counter() - t0
    return case


#: The key of the difference to the monolithic reference in ``Case.numbers``.
VS_MONO = "‖u − u_mono‖/‖u‖"


def rel_diff(a: np.ndarray, b: np.ndarray) -> float:
    """max |a − b| / max |b|."""
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


# ------------------------------------------------------------------------------------------
# The cases
# ------------------------------------------------------------------------------------------

#: The composite pressed on a rigid cylinder: top u_x = 0 and a downward traction.
COMPOSITE_LOAD = (0.0, -0.05)
COMPOSITE_OBSTACLE = df.Sphere((0.5, -5.0), 5.0)


def grid_labels(H: float | tuple[float, float], origin=(0.0, 0.0)) -> Callable:
    """ByFunction labels of a regular grid of boxes of size H."""
    Hx, Hy = (H, H) if np.isscalar(H) else H

    def fn(x):
        i = np.floor((x[:, 0] - origin[0]) / Hx).astype(np.int64)
        j = np.floor((x[:, 1] - origin[1]) / Hy).astype(np.int64)
        return i * 100003 + j

    return fn


def composite_problem(mesh, ratio: float, decomposition, nu: float = 0.3,
                      gluing: str = "orthonormal") -> df.ContactProblem:
    """The composite with E = 1 in the matrix and E = ratio in the inclusions."""
    return df.ContactProblem(
        mesh, ConstElasticity({"matrix": 1.0, "inclusions": ratio}, nu,
                              tractions={"top": COMPOSITE_LOAD}),
        dirichlet=[df.Dirichlet("top", components=[0])],
        contact=[df.RigidObstacle("bottom", COMPOSITE_OBSTACLE)],
        decomposition=decomposition, gluing=gluing)


def composite_reference(mesh, ratio: float, nu: float = 0.3) -> np.ndarray:
    return monolithic(mesh, {"matrix": 1.0, "inclusions": ratio}, nu,
                      dirichlet=[("top", [0], [0.0])],
                      obstacles=[("bottom", COMPOSITE_OBSTACLE)],
                      tractions={"top": COMPOSITE_LOAD})


DECOMPOSITIONS = {
    "tags": df.ByTags(),  # subdomain boundaries = the material interfaces
    "grid": df.ByFunction(grid_labels(1.0 / 3.0)),  # 3×3 boxes cutting the inclusions
}


def coefficient_jump(mesh, ratio: float, decomposition: str, preconditioner: str = "none",
                     rtol: float = 1e-8, reference: np.ndarray | None = None, **options) -> Case:
    """The composite at one E ratio, decomposition and preconditioner."""
    case = run(f"E ratio {ratio:.0e}, {decomposition}, {preconditioner}",
               lambda: composite_problem(mesh, ratio, DECOMPOSITIONS[decomposition]),
               rtol=rtol, preconditioner=preconditioner, **options)
    if reference is not None and case.solution is not None:
        case.numbers[VS_MONO] = rel_diff(case.solution.nodal_values(), reference)
    return case


def block_on_plane(mesh, *, gap: float = 0.0, load=(0.0, -0.01), E: float = 1.0,
                   nu: float = 0.3, sides: bool = True, obstacles=None, **kwargs
                   ) -> df.ContactProblem:
    """The block of :func:`rectangle` on the rigid plane y = −gap, loaded on its top.

    ``sides``: u_x = 0 on the sides (else the block floats horizontally).
    """
    obstacles = obstacles if obstacles is not None else \
        [df.RigidObstacle("block_bottom", df.Plane((0.0, -gap), (0.0, 1.0)))]
    return df.ContactProblem(
        mesh, ConstElasticity(E, nu, tractions={"top": load}),
        dirichlet=[df.Dirichlet("block_sides", components=[0])] if sides else [],
        contact=obstacles, **kwargs)


def block_reference(mesh, *, gap: float = 0.0, load=(0.0, -0.01), E: float = 1.0,
                    nu: float = 0.3, obstacles=None) -> np.ndarray:
    obstacles = obstacles if obstacles is not None else \
        [("block_bottom", df.Plane((0.0, -gap), (0.0, 1.0)))]
    return monolithic(mesh, E, nu, dirichlet=[("block_sides", [0], [0.0])],
                      obstacles=obstacles, tractions={"top": load})


# -- Hertz (node-to-node, curved) for units, tolerances and incompressibility ----------------

HERTZ_R, HERTZ_P, HERTZ_E = 8.0, 10.0, 200.0


def hertz_problem(mesh, *, length: float = 1.0, stress: float = 1.0, nu: float = 0.3,
                  parts: int = 2) -> df.ContactProblem:
    """The 2D Hertz half model of ``demos/demo_hertz2d.py`` in other units.

    Lengths are multiplied by ``length`` (the mesh is scaled exactly), stresses (E and the
    traction) by ``stress``; the displacement then scales with ``length`` and the nodal forces
    with ``stress · length``.
    """
    m = mesh if length == 1.0 else dataclasses.replace(mesh, x=mesh.x * length)
    t = (0.0, -HERTZ_P / 2 / HERTZ_R * stress)
    return df.ContactProblem(
        m, ConstElasticity(HERTZ_E * stress, nu, tractions={"load": t}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.NodeToNode("disk_contact", "block_contact")],
        decomposition=df.Parts(parts))


def hertz_peak(sol: df.Solution) -> float:
    """The largest contact pressure."""
    return float(sol.contact.pressure.max())


def hertz_p0(nu: float) -> float:
    """Hertz's peak pressure for the disk and the block of the same material (plane strain)."""
    e_star = HERTZ_E / (2.0 * (1.0 - nu**2))
    return float(np.sqrt(HERTZ_P * e_star / (np.pi * HERTZ_R)))


def unit_change(mesh, length: float, stress: float, base: df.Solution, rtol: float = 1e-10
                ) -> Case:
    """The Hertz problem in other units, compared with ``base`` (unit 1, 1)."""
    case = run(f"units: lengths ×{length:g}, stresses ×{stress:g}",
               lambda: hertz_problem(mesh, length=length, stress=stress), rtol=rtol)
    if case.solution is not None:
        u = case.solution.nodal_values() / length
        f = case.solution.contact.force / (stress * length)
        order = np.argsort(case.solution.contact.node)
        border = np.argsort(base.contact.node)
        case.numbers["du"] = rel_diff(u, base.nodal_values())
        case.numbers["dforce"] = rel_diff(f[order], base.contact.force[border])
    return case


# -- B1 (scalar) for large H/h and many subdomains ------------------------------------------


def b1_source(x):
    """B1's load: −3 on (0,1)×[0.75,1), −1 on (1,2)×[0,0.25), 0 elsewhere."""
    return ufl.conditional(ufl.lt(x[0], 1.0), ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0),
                           ufl.conditional(ufl.lt(x[1], 0.25), -1.0, 0.0))


def b1_problem(mesh, decomposition) -> df.ContactProblem:
    """Dostál's two membranes (BENCHMARKS.md B1) on ``meshes.membranes(n)``."""
    return df.ContactProblem(mesh, df.Poisson(source=b1_source),
                             dirichlet=[df.Dirichlet("dirichlet")],
                             contact=[df.NodeToNode("contact_left", "contact_right")],
                             decomposition=decomposition)


def b1_case(mesh, n: int, H: float | None, rtol: float = 1e-6, **options) -> Case:
    """B1 with H×H boxes (H = None: one subdomain per membrane)."""
    dec = df.ByTags() if H is None else df.ByFunction(grid_labels(H))
    hh = n if H is None else round(n * H)
    case = run(f"B1 n={n}, H/h={hh}", lambda: b1_problem(mesh, dec), rtol=rtol, **options)
    if case.solution is not None:
        case.numbers["subdomains"] = case.report.sizes["subdomains"]
    return case


__all__ = ["COMM", "Case", "ConstElasticity", "composite", "monolithic", "run"]
