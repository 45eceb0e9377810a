"""Contact of two surfaces with non-matching meshes (or of one with itself): :class:`Mortar`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ...validation import Choice, Maybe, Real, Text, checked
from .base import SurfacePair, check_mortar_pair
from .file_table import file_table
from .friction import FRICTION, Friction

if TYPE_CHECKING:
    from ..contact_problem import ContactProblem


@file_table("contact", "mortar", pair="contact", self_contact=True)
@dataclass(frozen=True)
@checked(slave=Text(), master=Text(), search_distance=Maybe(Real(gt=0)), friction=FRICTION,
         normals=Choice("slave", "flatter"))
class Mortar(SurfacePair):
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

    #: What it makes of its surfaces: ``"contact"`` (inequality rows, in
    #: ``ContactProblem.contact``) or ``"tie"`` (equality rows, in ``ContactProblem.ties``).
    role = "contact"
    #: Whether the rows come from the mortar search (and the report checks them after).
    mortar = True

    @property
    def self_contact(self) -> bool:
        """Whether a body touches itself (one group on both sides)."""
        return self.slave == self.master

    def check(self, problem: ContactProblem) -> None:
        """Refuse, by name, what this condition cannot take on ``problem``'s mesh."""
        check_mortar_pair(problem.mesh, "mortar contact", self)
