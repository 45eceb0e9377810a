"""What a user describes: :class:`ContactProblem` and its checks.

The mesh, the forms, the conditions (their classes in :mod:`.conditions`), the decomposition.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

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
from ..validation import Choice, Function, Instance, Integer, Maybe, SequenceOf, checked
from .conditions.dirichlet import Dirichlet
from .conditions.friction import FRICTION
from .conditions.mortar import Mortar
from .conditions.node_to_node import NodeToNode
from .conditions.rigid_obstacle import RigidObstacle
from .conditions.tie import Tie

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
            if getattr(t, "role", None) != "tie":
                raise InputError(f"ties must be df.Tie conditions, got {t!r}")
            t.check(self)
        for c in self.contact:
            if getattr(c, "role", None) != "contact" or not callable(getattr(c, "check", None)):
                raise InputError(f"unknown contact condition {c!r}")
            c.check(self)
            fr = c.friction
            if not FRICTION.ok(fr)[0]:
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
            kind = "tie" if c.role == "tie" else "contact pair"
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
