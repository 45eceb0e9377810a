"""Contact of two surfaces with matching nodes: :class:`NodeToNode`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ...errors import InputError
from ...validation import Maybe, Real, Text, checked
from .base import SurfacePair
from .file_table import file_table
from .friction import FRICTION, Friction

if TYPE_CHECKING:
    from ..contact_problem import ContactProblem


@file_table("contact", "node_to_node", keys={"gap": Maybe(Real(ge=0))},
            infer_from=("slave", "master"), pair="contact")
@dataclass(frozen=True)
@checked(slave=Text(), master=Text(), gap=Maybe(Real()), match_tol=Real(gt=0, lt=1),
         friction=FRICTION)
class NodeToNode(SurfacePair):
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
            slip is the tangential part of u_slave − u_master (under Newton, hyperelastic
            forms: its increment in each load step, in the tangents of the deformed master
            surface; the nodes stay paired, so the slip must stay within an element).
    """

    slave: str
    master: str
    gap: float | None = None
    match_tol: float = 1e-4
    friction: Friction | None = None

    #: What it makes of its surfaces: ``"contact"`` (inequality rows, in
    #: ``ContactProblem.contact``) or ``"tie"`` (equality rows, in ``ContactProblem.ties``).
    role = "contact"
    #: Whether the rows come from the mortar search (and the report checks them after).
    mortar = False
    #: Two surfaces of different bodies (one group with itself is refused: :meth:`check`).
    self_contact = False

    def check(self, problem: ContactProblem) -> None:
        """Refuse, by name, what this condition cannot take on ``problem``'s mesh."""
        problem.mesh.facets(self.slave)
        problem.mesh.facets(self.master)
        if self.slave == self.master:
            raise InputError(f"contact pair {self.slave!r} with itself")
        if self.gap is not None and not np.isfinite(self.gap):
            raise InputError(f"contact pair {self.slave!r}/{self.master!r}: gap is not finite")
