"""Gluing of two surfaces with non-matching meshes: :class:`Tie`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ...errors import InputError
from ...validation import Maybe, Real, Text, checked
from .base import SurfacePair, check_mortar_pair
from .file_table import file_table

if TYPE_CHECKING:
    from ..contact_problem import ContactProblem


@file_table("tie", pair="tie")
@dataclass(frozen=True)
@checked(slave=Text(), master=Text(), search_distance=Maybe(Real(gt=0)))
class Tie(SurfacePair):
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

    #: What it makes of its surfaces: ``"contact"`` (inequality rows, in
    #: ``ContactProblem.contact``) or ``"tie"`` (equality rows, in ``ContactProblem.ties``).
    role = "tie"
    #: Whether the rows come from the mortar search (and the report checks them after).
    mortar = True
    #: A tie glues two surfaces: it has no friction.
    friction = None
    #: One group with itself is refused (:meth:`check`).
    self_contact = False

    def check(self, problem: ContactProblem) -> None:
        """Refuse, by name, what this condition cannot take on ``problem``'s mesh."""
        if self.slave == self.master:
            problem.mesh.facets(self.slave)
            raise InputError(f"tie {self.slave!r} with itself")
        check_mortar_pair(problem.mesh, "tie", self)
