"""The compiled linear form of a subdomain, kept for the next load case of the same shape.

A new load case (``FetiSolver.update``, a load path's step) changes numbers only: traction
vectors, the body force, the load factor. Building the UFL form again and handing it to DOLFINx
costs far more than the assembly itself on small subdomains (the form's signature, the JIT
cache's lookup on disk). A material that names the shape of its loads (``load_key(sub)``) and
their values in the order it creates its runtime constants (``load_values(sub)``) has its
compiled form kept here: a new case of the same shape sets the constants and assembles.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np
import ufl
from ufl.algorithms.analysis import extract_constants

from .. import compat


class LoadForm:
    """One subdomain's compiled linear form and its runtime constants in creation order.

    Args:
        key: The shape of the loads it was built for (the material's ``load_key(sub)``).
        L: The UFL linear form; None for no load on the subdomain (then the vector is zero).
    """

    def __init__(self, key: Hashable, L: ufl.Form | None) -> None:
        self.key = key
        self.compiled = None if L is None else compat.compile_form(L)
        # UFL numbers its objects as they are made: sorted by count = the material's order
        self.constants = [] if L is None else sorted(extract_constants(L),
                                                     key=lambda c: c.count())

    @classmethod
    def of(cls, forms, sub, L: ufl.Form | None) -> LoadForm | None:
        """The kept form for ``L`` (None: zero) when ``forms`` names its load shape, else None."""
        key = _key(forms, sub)
        if key is None or not (L is None or isinstance(L, ufl.Form)):
            return None
        kept = cls(key, L)
        values = forms.load_values(sub) if L is not None else []
        if len(values) != len(kept.constants):  # constants the material does not name
            return None
        return kept

    def matches(self, forms, sub) -> bool:
        """Whether a new material's loads on ``sub`` have the shape this form was built for."""
        key = _key(forms, sub)
        return key is not None and key == self.key

    def assemble(self, values: Sequence | None = None) -> np.ndarray | None:
        """The vector for the constants' ``values`` (None: as they are), in DOLFINx's numbering.

        None for a subdomain without load.
        """
        if self.compiled is None:
            return None
        if values is not None:
            self.set(values)
        b = compat.assemble_vector(self.compiled)
        out = b.array.copy()
        b.destroy()
        return out

    def set(self, values: Sequence) -> None:
        """Write the runtime constants, in the material's order."""
        for c, v in zip(self.constants, values, strict=True):
            c.value = np.asarray(v, dtype=c.value.dtype).reshape(c.value.shape)


def _key(forms, sub) -> Hashable | None:
    load_key = getattr(forms, "load_key", None)
    return None if load_key is None else load_key(sub)
