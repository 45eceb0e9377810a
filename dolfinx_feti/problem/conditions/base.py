"""What the condition classes share: the description of a point function, the pair helpers."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...errors import InputError
from ...mesh.data import MeshData

#: How a user function of the node coordinates is named in the checks' messages.
POINT_FUNCTION = "a function of the node coordinates x (n, gdim)"


def pair_structure_key(c) -> tuple:
    """A pair condition's part of the set-up's structure.

    Itself without its friction values (whether there is friction counts).
    """
    fr = getattr(c, "friction", None) is not None
    return type(c).__name__, replace(c, friction=None) if fr else c, fr


def check_mortar_pair(mesh: MeshData, what: str, c) -> None:
    """The groups of a mortar condition (a Mortar or a Tie) exist, the search distance is sane.

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



class SurfacePair:
    """What a condition between a slave and a master surface does alike (a mixin).

    Its rows sit on the slave's nodes; it reads both groups; a set-up depends on it without
    its friction values.
    """

    @property
    def group(self) -> str:
        """The surface whose nodes carry the rows (the slave)."""
        return self.slave

    @property
    def groups(self) -> tuple[str, ...]:
        """The boundary groups the condition reads."""
        return self.slave, self.master

    def structure_key(self) -> tuple:
        """What a set-up depends on (:mod:`..changes`): the condition, friction or not."""
        return pair_structure_key(self)
