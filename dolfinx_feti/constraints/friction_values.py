"""The friction values of a new load case on the friction rows of a set-up.

On a load path the friction coefficient or the Tresca bound may change from step to step (a
lubricant, a temperature): the tangential rows stay, their slip bounds change. The rows'
structure (which conditions have friction) is that of the set-up; per condition the model may
go from Tresca to Coulomb and back, the values may change. A Tresca bound given as a function
of the position may not change (its values at the nodes are the set-up's): give a number.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import InputError
from ..problem.contact_problem import ContactProblem
from ..setup.share import RankRows
from .friction import NODAL_VALUES, FrictionData


def friction_key(c) -> tuple:
    """What of a condition's friction the rows' values depend on (None: frictionless)."""
    fr = getattr(c, "friction", None)
    return (None,) if fr is None else fr.key()


def with_friction_of(data: FrictionData, old: ContactProblem, new: ContactProblem,
                     rows: RankRows) -> FrictionData:
    """``data`` with the coefficients and Tresca bounds of ``new``'s conditions.

    Args:
        data: The friction rows of the set-up (global, the same on every rank).
        old: The problem ``data`` holds the values of.
        new: The new load case (same conditions, checked by the caller).
        rows: This rank's rows (the contact rows every rank keeps give each row's condition).

    Raises:
        InputError: For a Tresca bound given as a function that changed.
    """
    spec = rows.contact.spec[rows.contact_rows(data.rows)]
    tresca, coefficient = data.tresca.copy(), data.coefficient.copy()
    rtol, max_steps = np.inf, 0
    for i, (c_old, c_new) in enumerate(zip(old.contact, new.contact, strict=True)):
        fr = getattr(c_new, "friction", None)
        if fr is None:  # frictionless: no rows of its own here (the set-up's structure is kept)
            continue
        m = spec == i
        if (fixed := fr.fixed_point()) is not None:
            rtol, max_steps = min(rtol, fixed[0]), max(max_steps, fixed[1])
        old_key, new_key = friction_key(c_old), friction_key(c_new)
        if old_key == new_key or not np.any(m):
            continue
        if any(callable(v) for v in (*old_key, *new_key)):
            raise InputError(f"update: the friction on {c_new.group!r} is given by a function "
                             "that changed (a Tresca bound of x); on one set-up friction values "
                             "may change as numbers only")
        tresca[m], coefficient[m] = NODAL_VALUES[type(fr)](fr, None, c_new.group, data.area[m])
    return replace(data, tresca=tresca, coefficient=coefficient,
                   rtol=float(rtol) if np.isfinite(rtol) else data.rtol,
                   max_steps=int(max_steps) if max_steps else data.max_steps)


__all__ = ["friction_key", "with_friction_of"]
