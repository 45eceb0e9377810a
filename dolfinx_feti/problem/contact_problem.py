"""What a user describes: the mesh, the forms, Dirichlet conditions, contact, the decomposition."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from ..errors import InputError, collective
from ..mesh.auto_parts import Auto
from ..mesh.checks import (
    check_boundary_group,
    check_conforming,
    check_contact_surface,
    check_mesh,
)
from ..mesh.data import MeshData
from ..mesh.decompose import ByFunction, ByTags, Parts
from ..mesh.dofpoints import facet_weights
from ..mesh.mixed import MixedMesh
from ..validation import (
    Choice,
    Either,
    Function,
    Instance,
    Integer,
    Maybe,
    Real,
    SequenceOf,
    Text,
    Vector,
    checked,
)
from .rigid_motion import RigidMotion

_POINT_FUNCTION = "a function of the node coordinates x (n, gdim)"


@dataclass(frozen=True)
@checked(group=Text(),
         value=Either(Real(), Vector(), Function(),
                      what=f"a finite number, one per component, or {_POINT_FUNCTION}"),
         components=Maybe(SequenceOf(Integer(ge=0), unique=True, nonempty=True)))
class Dirichlet:
    """Prescribed values on a boundary group.

    Args:
        group: Name of the boundary physical group.
        value: A number, one number per component, or ``value(x) -> (n, ncomp)`` of the node
            coordinates ``x`` (n, gdim).
        components: The constrained components (e.g. ``(0,)`` for a symmetry plane normal to x);
            all components when ``None``.
    """

    group: str
    value: float | Sequence[float] | Callable[[np.ndarray], np.ndarray] = 0.0
    components: Sequence[int] | None = None


@dataclass(frozen=True)
@checked(bound=Either(Real(ge=0, inf=True), Function(),
                      what=f"a slip bound: a number >= 0, inf (no slip) or {_POINT_FUNCTION}"))
class Tresca:
    """Given (Tresca) friction: the tangential traction is bounded by the slip bound ``g``.

    At each contact node the tangential nodal force satisfies |λ_T| <= g(x)·A with A the
    node's lumped area (length in 2D) on the slave surface: the node sticks (no relative
    tangential displacement) while |λ_T| < g(x)·A and slips against the friction force when
    |λ_T| = g(x)·A. In 2D this is a box on one tangential multiplier, in 3D a disc on two.

    Args:
        bound: The slip bound g >= 0, a traction (force per unit area, per unit length in
            2D): a number, ``numpy.inf`` (no slip: the tangential rows become equalities) or
            ``bound(x) -> (n,)`` of the node coordinates ``x`` (n, gdim).
    """

    bound: float | Callable[[np.ndarray], np.ndarray]

    def key(self) -> tuple:
        """What the friction rows' values depend on (a set-up's update compares it)."""
        return "tresca", self.bound if callable(self.bound) else float(self.bound)

    def fixed_point(self) -> None:
        """Tresca is solved by one QP: no fixed point."""
        return None


@dataclass(frozen=True)
@checked(coefficient=Real(ge=0), rtol=Real(gt=0, lt=1), max_steps=Integer(ge=1, le=10**6))
class Coulomb:
    """Coulomb friction, solved by a fixed point on Tresca problems.

    The slip bound of each contact node is 𝓕 times its normal nodal force: g_i = 𝓕 λ_N,i.
    Each fixed-point step solves a Tresca problem (warm-started from the previous step) with
    the bound taken from the previous normal forces; the first step uses g = ∞ (no slip). The
    iteration stops when max_i |g_i − 𝓕 λ_N,i| <= rtol max_i λ_N,i over all Coulomb nodes
    (the Coulomb residual of the iterate, in physical units; the inner solves' accuracy
    follows it, docs/friction.md) or after ``max_steps`` steps (then the report says not
    converged). With several Coulomb pairs the smallest ``rtol`` and the largest
    ``max_steps`` apply.

    Args:
        coefficient: The friction coefficient 𝓕 >= 0.
        rtol: The Coulomb residual max|g − 𝓕 λ_N| / max λ_N that ends the fixed point.
        max_steps: Budget of fixed-point steps (Tresca solves).
    """

    coefficient: float
    rtol: float = 1e-6
    max_steps: int = 50

    def key(self) -> tuple:
        """What the friction rows' values depend on (a set-up's update compares it)."""
        return "coulomb", float(self.coefficient), float(self.rtol), int(self.max_steps)

    def fixed_point(self) -> tuple[float, int]:
        """The fixed point's stopping residual and budget of steps."""
        return float(self.rtol), int(self.max_steps)


Friction = Tresca | Coulomb
_FRICTION = Maybe(Instance(Tresca, Coulomb))


@dataclass(frozen=True)
@checked(slave=Text(), master=Text(), gap=Maybe(Real()), match_tol=Real(gt=0, lt=1),
         friction=_FRICTION)
class NodeToNode:
    """Contact of two surfaces of different bodies with matching nodes.

    Each node of the ``slave`` surface is paired with the master node at the same position
    along the master surface (up to the initial gap along the master's normal). The normal is
    the master's outward normal n; the condition at a pair is (u_slave − u_master)·n >= −gap,
    with gap = (x_slave − x_master)·n from the geometry unless ``gap`` is given. For a scalar
    problem the condition is u_slave − u_master <= gap (gap 0 by default).

    Args:
        slave: Boundary group of the slave side.
        master: Boundary group of the master side.
        gap: Override of the initial gap (a number for every pair).
        match_tol: Pairing tolerance relative to the mean edge length of the slave surface,
            in (0, 1). On a curved (second-order) mesh the edge nodes of the two sides are
            placed by the mesher independently (on an arc at its mid-angle, on a segment at
            its midpoint) and may be off by ~h²/R along the surface: raise it (e.g. 1e-2).
        friction: ``None`` (frictionless), :class:`Tresca` or :class:`Coulomb`. The relative
            slip is the tangential part of u_slave − u_master.
    """

    slave: str
    master: str
    gap: float | None = None
    match_tol: float = 1e-4
    friction: Friction | None = None

    #: Whether the rows come from the mortar search (and the report checks them after).
    mortar = False
    #: Two surfaces of different bodies (one group with itself is refused: :meth:`check`).
    self_contact = False

    @property
    def group(self) -> str:
        """The surface whose nodes carry the rows (the slave)."""
        return self.slave

    @property
    def groups(self) -> tuple[str, ...]:
        """The boundary groups the condition reads."""
        return self.slave, self.master

    def check(self, problem: ContactProblem) -> None:
        """Refuse, by name, what this condition cannot take on ``problem``'s mesh."""
        problem.mesh.facets(self.slave)
        problem.mesh.facets(self.master)
        if self.slave == self.master:
            raise InputError(f"contact pair {self.slave!r} with itself")
        if self.gap is not None and not np.isfinite(self.gap):
            raise InputError(f"contact pair {self.slave!r}/{self.master!r}: gap is not finite")

    def structure_key(self) -> tuple:
        """What a set-up depends on (:mod:`.changes`): the condition, friction or not."""
        return _structure_key(self)


@dataclass(frozen=True)
@checked(slave=Text(), master=Text(), search_distance=Maybe(Real(gt=0)), friction=_FRICTION,
         normals=Choice("slave", "flatter"))
class Mortar:
    """Contact of two surfaces of different bodies with independent (non-matching) meshes.

    Segment-to-segment mortar with dual Lagrange multipliers on the slave side: one
    non-penetration row and one bound λ_j >= 0 per slave node j, coupling it to the master
    surface through the integrals of the slave's dual basis against the master's shape
    functions over the overlap of each slave facet with the master facets projected onto it
    (see :mod:`dolfinx_feti.constraints.mortar`). The normal at a slave node is the average of
    its facets' normals; the initial gap comes from the geometry (weighted). Degree 1 on
    triangles, tetrahedra, quadrilaterals and hexahedra (warped bilinear facets included);
    degree 2 in 2D (3-node segments, straight or curved: rows at vertices and edge points) and
    on first-order tetrahedra (6-node triangles, the slave side in the transformed basis of
    positive weights of Popp, Wohlmuth, Gee and Wall 2012) and hexahedra (9-node
    quadrilaterals, whose functions have positive weights already).

    The two groups may be whole candidate surfaces, much larger than the contact zone: pairs
    of facets are searched automatically; slave nodes with no master facet within
    ``search_distance`` get no row (the report says how many), and after the solve every node
    of both surfaces is checked against the other surface (the report warns about a
    penetration, or about an active row on the rim of a candidate surface). Take as slave the
    surface with the finer mesh, or the smaller one.

    **Self-contact**: ``Mortar(slave=g, master=g)`` with one boundary group ``g`` (a body
    touching itself: a C-clip closing, a folding strip). The search then leaves out each
    facet's own neighbourhood (the facets sharing a vertex with it) and the facets that do not
    face it from the outside (the two sides of a thin wall), and keeps each pair of zones
    that face each other once: the zone first in the group's facet order is the slave
    (:mod:`dolfinx_feti.constraints.self_contact`). The rows, friction and the report are
    those of two surfaces; the report's penetration check runs on the zones paired before
    and after the deformation.

    Args:
        slave: Boundary group of the slave side.
        master: Boundary group of the master side.
        friction: ``None`` (frictionless), :class:`Tresca` or :class:`Coulomb`; the slip is
            the tangential part of u_slave − Σ_k w_k u_k (the weighted master point).
        search_distance: How far apart two facets may be (along the slave normal, either
            side) and still be coupled; by default twice the larger mean facet size of the
            two surfaces, and at least 5 % of the slave surface's extent.
        normals: The direction of each row: ``"slave"`` (the slave's averaged normal, the
            usual choice) or ``"flatter"`` (per slave node the normal of whichever surface
            bends less there, :mod:`dolfinx_feti.constraints.mortar_normals`): use it where
            the slave has kinks or fillets in the contact zone and the master is flat (a
            filleted punch as slave on a block), so that the normal forces carry no
            tangential load and the friction forces sum to the applied shear.
    """

    slave: str
    master: str
    friction: Friction | None = None
    search_distance: float | None = None
    normals: str = "slave"

    #: Whether the rows come from the mortar search (and the report checks them after).
    mortar = True

    @property
    def group(self) -> str:
        """The surface whose nodes carry the rows (the slave)."""
        return self.slave

    @property
    def groups(self) -> tuple[str, ...]:
        """The boundary groups the condition reads."""
        return self.slave, self.master

    @property
    def self_contact(self) -> bool:
        """Whether a body touches itself (one group on both sides)."""
        return self.slave == self.master

    def check(self, problem: ContactProblem) -> None:
        """Refuse, by name, what this condition cannot take on ``problem``'s mesh."""
        _check_pair(problem.mesh, "mortar contact", self)

    def structure_key(self) -> tuple:
        """What a set-up depends on (:mod:`.changes`): the condition, friction or not."""
        return _structure_key(self)


@dataclass(frozen=True)
@checked(slave=Text(), master=Text(), search_distance=Maybe(Real(gt=0)))
class Tie:
    """Gluing of two surfaces with independent (non-matching) meshes by mortar equality rows.

    For pieces of a body (or of several bodies) meshed on their own, e.g. gmsh volumes that
    were not fragmented, or stiff inclusions meshed apart from the matrix: at each slave node
    u_slave = Σ_k w_k u_k (the same dual-basis weights as :class:`Mortar`), per component.

    Args:
        slave: Boundary group of the slave side (preferably the finer mesh).
        master: Boundary group of the master side.
        search_distance: As for :class:`Mortar`.
    """

    slave: str
    master: str
    search_distance: float | None = None

    #: Whether the rows come from the mortar search (and the report checks them after).
    mortar = True
    #: A tie glues two surfaces: it has no friction.
    friction = None
    #: One group with itself is refused (:meth:`check`).
    self_contact = False

    @property
    def groups(self) -> tuple[str, ...]:
        """The boundary groups the condition reads."""
        return self.slave, self.master

    def check(self, problem: ContactProblem) -> None:
        """Refuse, by name, what this condition cannot take on ``problem``'s mesh."""
        if self.slave == self.master:
            problem.mesh.facets(self.slave)
            raise InputError(f"tie {self.slave!r} with itself")
        _check_pair(problem.mesh, "tie", self)

    def structure_key(self) -> tuple:
        """What a set-up depends on (:mod:`.changes`): the condition itself."""
        return _structure_key(self)


class Obstacle(Protocol):
    """A rigid obstacle as a signed distance: positive outside the obstacle."""

    def distance(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance φ(x) and its gradient at the points ``x`` (n, gdim)."""


@dataclass(frozen=True)
@checked(point=Vector(), normal=Vector(nonzero=True))
class Plane:
    """The half-space {(x − point)·normal <= 0}; ``normal`` points out of the obstacle.

    ``point`` and ``normal`` have one coordinate per dimension of the mesh.
    """

    point: Sequence[float]
    normal: Sequence[float]

    def coordinates(self) -> dict[str, Sequence[float]]:
        """The vectors that need one coordinate per dimension of the mesh."""
        return {"point": self.point, "normal": self.normal}

    def distance(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D102
        n = np.asarray(self.normal, dtype=float)
        n = n / np.linalg.norm(n)
        p = np.asarray(self.point, dtype=float)
        return (x - p) @ n, np.broadcast_to(n, x.shape).copy()


@dataclass(frozen=True)
@checked(center=Vector(), radius=Real(gt=0))
class Sphere:
    """A rigid ball (a disc in 2D) of radius ``radius`` centred at ``center``."""

    center: Sequence[float]
    radius: float

    def coordinates(self) -> dict[str, Sequence[float]]:
        """The vectors that need one coordinate per dimension of the mesh."""
        return {"center": self.center}

    def distance(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D102
        d = x - np.asarray(self.center, dtype=float)
        r = np.linalg.norm(d, axis=1)
        return r - self.radius, d / np.maximum(r, 1e-300)[:, None]


@dataclass(frozen=True)
@checked(point=Vector(3), axis=Vector(3, nonzero=True), radius=Real(gt=0))
class Cylinder:
    """A rigid infinite cylinder (3D) with an axis through ``point`` along ``axis``."""

    point: Sequence[float]
    axis: Sequence[float]
    radius: float

    def coordinates(self) -> dict[str, Sequence[float]]:
        """The vectors that need one coordinate per dimension of the mesh."""
        return {"point": self.point, "axis": self.axis}

    def distance(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D102
        a = np.asarray(self.axis, dtype=float)
        a = a / np.linalg.norm(a)
        d = x - np.asarray(self.point, dtype=float)
        d = d - np.outer(d @ a, a)
        r = np.linalg.norm(d, axis=1)
        return r - self.radius, d / np.maximum(r, 1e-300)[:, None]


@dataclass(frozen=True)
@checked(fn=Function(f"{_POINT_FUNCTION} returning (phi (n,), grad (n, gdim))"))
class SignedDistance:
    """A rigid obstacle given by a user signed distance ``fn(x) -> (phi, grad)``."""

    fn: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]

    def distance(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: D102
        return self.fn(x)


@dataclass(frozen=True)
@checked(group=Text(), obstacle=Instance(methods=("distance",), what="an obstacle (Plane, "
                                         "Sphere, Cylinder, SignedDistance)"),
         friction=_FRICTION, motion=Maybe(Instance(RigidMotion)))
class RigidObstacle:
    """Contact of a body's boundary group with a rigid obstacle.

    The condition at each node is φ(x + u) >= 0, linearized: ∇φ(x)·u >= −φ(x). Nodes that
    start inside the obstacle (φ < 0) are pushed out: an initial penetration is honoured.
    ``friction`` (``None``, :class:`Tresca` or :class:`Coulomb`) acts on the tangential part
    of u (the obstacle does not move). On a load path, ``motion`` (a
    :class:`~dolfinx_feti.problem.rigid_motion.RigidMotion`: the pose of the obstacle's body,
    a centre and a rotation angle, given at every step) makes the friction rows measure each
    node's slip against the material point of the obstacle's surface (a spinning or rolling
    disc); without it a small-deformation path measures the slip in the fixed frame and the
    Newton driver against the translation of the obstacle (docs/friction.md).
    """

    group: str
    obstacle: Obstacle
    friction: Friction | None = None
    motion: RigidMotion | None = None

    #: Whether the rows come from the mortar search (and the report checks them after).
    mortar = False
    #: A body against an obstacle, not against itself.
    self_contact = False

    @property
    def groups(self) -> tuple[str, ...]:
        """The boundary groups the condition reads."""
        return (self.group,)

    def check(self, problem: ContactProblem) -> None:
        """Refuse, by name, what this condition cannot take on ``problem``'s mesh."""
        problem.mesh.facets(self.group)
        if problem.value_size == 1:
            raise InputError("rigid obstacles need a vector (elasticity) problem")
        if self.motion is not None:
            self.motion.check_dimension(problem.mesh.gdim, self.group)

    def structure_key(self) -> tuple:
        """What a set-up depends on (:mod:`.changes`).

        Not the obstacle's position, nor the friction values: only the obstacle's kind and
        whether there is friction.
        """
        return (type(self).__name__, self.group, type(self.obstacle).__name__,
                self.friction is not None)


#: The contact conditions; each has ``group``, the surface whose nodes carry its rows.
Contact = NodeToNode | Mortar | RigidObstacle


@dataclass
@checked(mesh=Instance(MeshData, MixedMesh, what="a MeshData (see read_gmsh; for a DOLFINx "
                       "mesh, from_dolfinx(mesh, cell_tags, facet_tags))"),
         forms=Function("a function forms(V, sub) -> (a, L)"),
         value_size=Maybe(Integer(ge=1, le=3)), dirichlet=SequenceOf(Instance(Dirichlet)),
         contact=SequenceOf(Instance(object, what="a contact condition")),
         decomposition=Instance(Auto, ByTags, Parts, ByFunction,
                                what="a decomposition: Auto(), ByTags(), Parts(n) or "
                                "ByFunction(fn)"),
         gluing=Choice("orthonormal", "redundant", "nonredundant"),
         ties=SequenceOf(Instance(Tie)), degree=Maybe(Integer(ge=1, le=2)))
class ContactProblem:
    """A contact problem: mesh, forms, boundary conditions, contact and decomposition.

    Args:
        mesh: The mesh (see :func:`dolfinx_feti.read_gmsh`). For a mesh only rank 0 holds
            (``read_gmsh(..., replicate=False)``) create the problem on every rank of its
            communicator: rank 0 checks it. A :class:`~dolfinx_feti.MixedMesh` (bodies of
            several cell types) splits the problem into one per mesh and the Mortar and Tie
            conditions between them (:mod:`.mixed_problem`; solved by ``df.solve``).
        forms: ``forms(V, sub) -> (a, L)``: the bilinear and linear UFL forms on a subdomain's
            function space ``V``; ``sub`` (:class:`dolfinx_feti.fem.Subdomain`) tells which
            body it belongs to and gives the tagged measures ``sub.dx(...)``, ``sub.ds(...)``.
        value_size: 1 for a scalar problem, the geometric dimension for elasticity; taken from
            ``forms.value_size`` when the helpers are used.
        dirichlet: Dirichlet conditions.
        contact: Contact conditions (:class:`Mortar`, :class:`NodeToNode`,
            :class:`RigidObstacle`).
        decomposition: :class:`Auto` (the default: Parts by the mesh's size and the
            number of ranks, docs/solvers.md), :class:`ByTags`, :class:`Parts` or
            :class:`ByFunction`.
        gluing: ``"orthonormal"`` (default: at a node shared by k subdomains, k − 1
            orthonormal rows), ``"redundant"`` (all pairs) or ``"nonredundant"`` (a chain).
        degree: Degree of the Lagrange space ``V`` given to ``forms`` (1 or 2); taken from
            ``forms.degree`` when the helpers are used, else the degree of the mesh's geometry
            (1, or 2 for a curved second-order mesh: isoparametric).
        ties: :class:`Tie` conditions gluing non-matching interfaces by mortar rows.
    """

    mesh: MeshData
    forms: Callable
    value_size: int | None = None
    dirichlet: Sequence[Dirichlet] = field(default_factory=list)
    contact: Sequence[Contact] = field(default_factory=list)
    decomposition: Auto | ByTags | Parts | ByFunction = field(default_factory=Auto)
    gluing: str = "orthonormal"
    ties: Sequence[Tie] = field(default_factory=list)
    degree: int | None = None

    #: On a mesh of several cell types, the problem split per mesh
    #: (:class:`~.mixed_problem.MixedParts`); None otherwise.
    mixed = None

    def __post_init__(self) -> None:
        """Fill defaults and check what can be checked before any heavy work."""
        if isinstance(self.mesh, MixedMesh):  # one problem per cell type, and what joins them
            from .mixed_problem import split_problem

            if self.value_size is None:
                vs = getattr(self.forms, "value_size", None)
                self.value_size = self.mesh.gdim if vs == "vector" else vs
            self.mixed = split_problem(self)
            self.degree = 1
            return
        self.degree = _degree(self.degree, self.forms, self.mesh.geometry_degree)
        if self.mesh.geometry_degree == 2 and self.degree != 2:
            raise InputError("the mesh is of second order (curved cells): it needs a degree-2 "
                             "space (isoparametric), e.g. df.Elasticity(..., degree=2); a "
                             "degree-1 space on curved cells does not hold the rigid motions")
        if self.value_size is None:
            vs = getattr(self.forms, "value_size", None)
            self.value_size = self.mesh.gdim if vs == "vector" else vs
        if self.value_size is None:
            raise InputError("value_size is needed (1 for a scalar problem, the geometric "
                             "dimension for elasticity) when the forms are a plain function")
        if self.value_size not in (1, self.mesh.gdim):
            raise InputError(f"value_size must be 1 or {self.mesh.gdim}, got {self.value_size}")
        check = getattr(self.forms, "check", None)
        if check is not None:
            check(self.mesh)
        for bc in self.dirichlet:
            self.mesh.facets(bc.group)
            comps = range(self.value_size) if bc.components is None else bc.components
            if any(int(c) < 0 or int(c) >= self.value_size for c in comps):
                raise InputError(f"Dirichlet on {bc.group!r}: components {list(comps)} out of "
                                 f"range for a problem with {self.value_size} component(s)")
        for t in self.ties:
            if not isinstance(t, Tie):
                raise InputError(f"ties must be df.Tie conditions, got {t!r}")
            t.check(self)
        for c in self.contact:
            if isinstance(c, Tie) or not callable(getattr(c, "check", None)):
                raise InputError(f"unknown contact condition {c!r}")
            c.check(self)
            fr = c.friction
            if fr is not None and not isinstance(fr, (Tresca, Coulomb)):
                raise InputError(f"friction must be None, df.Tresca or df.Coulomb, got {fr!r}")
            if fr is not None and self.value_size == 1:
                raise InputError("friction needs a vector (elasticity) problem")
        check_dimensions(self)
        contact_groups = [g for c in [*self.contact, *self.ties] for g in c.groups]
        if self.mesh.part is not None:  # rank 0 checked the whole mesh at input
            _check_verdicts(self.mesh.part.verdicts, self, contact_groups)
        elif self.mesh.root_only is None:
            _check_distinct_surfaces(self.mesh, [*self.contact, *self.ties])
            _check_mesh(self.mesh, contact_groups, self.forms)
        else:  # collective on the mesh's ranks: rank 0 holds the arrays
            comm, points = self.mesh.root_only, None
            with collective(comm, "mesh"):
                if self.mesh.holds_arrays:
                    _check_distinct_surfaces(self.mesh, [*self.contact, *self.ties])
                    _check_mesh(self.mesh, contact_groups, self.forms)
                    points = self.dof_points.num_points
            points = comm.bcast(points, root=0)
            if not self.mesh.holds_arrays:
                self.mesh.counts[f"points{self.degree}"] = points
        mortar = [c for c in [*self.contact, *self.ties] if c.mortar]
        if mortar and self.mesh.gdim == 3 and self.mesh.geometry_degree != 1:
            raise InputError(
                f"mortar contact and ties ({mortar[0].slave!r}/{mortar[0].master!r}) in 3D are "
                "implemented on first-order (straight-sided) meshes, for degree 1 and 2: the "
                "facets of this second-order mesh are curved; use a first-order mesh")
        if contact_groups and np.any(facet_weights(self.mesh.cell_type, self.degree) <= 0):
            raise InputError(
                f"contact on a Lagrange space of degree {self.degree} on {self.mesh.cell_type} "
                "cells is not supported: its facets' dof points have no positive lumped area")
        if contact_groups and self.degree == 2 and self.mesh.cell_type == "tetrahedron" \
                and self.mesh.geometry_degree != 1:
            raise InputError(
                "contact on curved (second-order) tetrahedra is not supported yet: the "
                "transformed basis of the contact rows on 6-node triangles (Popp, Wohlmuth, Gee "
                "and Wall 2012) is built for straight-sided ones; use a first-order mesh with "
                "degree 2, or degree 1")

    @property
    def dof_points(self):
        """The global dof points of the space (:mod:`.mesh.dofpoints`): the vertices for P1."""
        from ..mesh.dofpoints import dof_points
        return dof_points(self.mesh, self.degree)


def _degree(degree, forms, default: int) -> int:
    """The Lagrange degree from the problem or the forms helper (they must agree)."""
    helper = getattr(forms, "degree", None)
    if degree is None:
        degree = default if helper is None else helper
    elif helper is not None and helper != degree:
        raise InputError(f"degree={degree} given to ContactProblem but the forms have "
                         f"degree={helper}")
    if isinstance(degree, bool) or degree not in (1, 2):
        raise InputError(f"degree must be 1 or 2 (Lagrange elements), got {degree!r}")
    return int(degree)


def _structure_key(c) -> tuple:
    """A pair condition's part of the set-up's structure.

    Itself without its friction values (whether there is friction counts).
    """
    fr = getattr(c, "friction", None) is not None
    return type(c).__name__, replace(c, friction=None) if fr else c, fr


def _check_pair(mesh: MeshData, what: str, c: Mortar | Tie) -> None:
    """The groups of a mortar condition exist, the search distance is sane.

    One group with itself is self-contact (:class:`Mortar` only; a tie is refused).
    """
    mesh.facets(c.slave)
    mesh.facets(c.master)
    if mesh.tdim != mesh.gdim:
        raise InputError(f"{what}: mortar needs a mesh of full dimension (tdim = gdim)")
    d = c.search_distance
    if d is not None and not (isinstance(d, (int, float)) and np.isfinite(d) and d > 0):
        raise InputError(f"{what} {c.slave!r}/{c.master!r}: search_distance must be a finite "
                         f"number > 0, got {d!r}")


def _check_distinct_surfaces(mesh: MeshData, pairs) -> None:
    """The two groups of a pair are two surfaces, not one surface under two names.

    Two physical groups may hold the same facets (a group named twice, e.g. "contact" and
    "top"); a pair of them is no interface, and each later check would name another cause.
    """
    for c in pairs:
        if len(c.groups) != 2 or c.groups[0] == c.groups[1]:  # an obstacle; self-contact
            continue
        a = np.unique(np.sort(mesh.facets(c.groups[0]), axis=1), axis=0)
        b = np.unique(np.sort(mesh.facets(c.groups[1]), axis=1), axis=0)
        if a.shape == b.shape and np.array_equal(a, b):
            kind = "tie" if isinstance(c, Tie) else "contact pair"
            raise InputError(f"{kind} {c.slave!r} (slave) / {c.master!r} (master): the two "
                             f"groups hold the same {a.shape[0]} facets (one surface under two "
                             "names); an interface needs the surfaces of its two sides")


def check_dimensions(problem: ContactProblem) -> None:
    """Vectors with one coordinate per dimension of the mesh, values one per component."""
    gdim = problem.mesh.gdim
    for bc in problem.dirichlet:
        n = len(bc.components) if bc.components is not None else problem.value_size
        if isinstance(bc.value, tuple) and len(bc.value) not in (1, n):
            raise InputError(f"Dirichlet on {bc.group!r}: value has {len(bc.value)} numbers for "
                             f"{n} constrained component(s); give one number or {n}")
    for c in problem.contact:
        vectors = getattr(getattr(c, "obstacle", None), "coordinates", dict)()
        for name, v in vectors.items():
            if len(v) != gdim:
                kind = type(c.obstacle).__name__
                raise InputError(f"obstacle on {c.group!r}: {kind}.{name} has {len(v)} "
                                 f"coordinates, the mesh is {gdim}D"
                                 + (" (a Cylinder is 3D only; use a Sphere, a disc, in 2D)"
                                    if kind == "Cylinder" else ""))


def _check_verdicts(verdicts, problem: ContactProblem, contact_groups: list[str]) -> None:
    """:func:`_check_mesh` of a distributed mesh, from the verdicts of its check at input."""
    for bc in problem.dirichlet:
        verdicts.check_group(bc.group, "")
    for group in contact_groups:
        verdicts.check_group(group)
    for what in ("tractions", "flux"):
        groups = getattr(problem.forms, what, None)
        for group in groups if isinstance(groups, dict) else ():
            verdicts.check_group(group, f"{what} on the group")
    verdicts.check_conforming(contact_groups)


def _check_mesh(mesh: MeshData, contact_groups: list[str], forms) -> None:
    """Mesh faults that no later step would notice (:mod:`.mesh.checks`)."""
    check_mesh(mesh)
    for group in contact_groups:
        check_contact_surface(mesh, group)
    for what in ("tractions", "flux"):  # the loaded groups of df.Elasticity, df.Poisson
        groups = getattr(forms, what, None)
        for group in groups if isinstance(groups, dict) else ():
            check_boundary_group(mesh, group, f"{what} on the group")
    check_conforming(mesh, exempt_groups=contact_groups)
