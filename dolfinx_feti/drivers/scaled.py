"""A problem with its loads scaled: proportional loading and unloading (the ``[loading]`` table).

``scaled(problem, s)`` multiplies the tractions, the body force and the Dirichlet values of an
elasticity problem by ``s``; the material, the conditions, rigid obstacles and friction stay.
``values`` gives Dirichlet groups their own value per step (a non-proportional path).
Constant tractions and body forces stay runtime constants (no compilation per factor); an
affine traction of a problem file is scaled in its coefficients (compiled once per factor).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from ..errors import InputError
from ..fem import Elasticity
from ..problem.conditions import Dirichlet
from ..problem.contact_problem import ContactProblem


def _scaled_value(v, s: float):
    """A traction, body force or Dirichlet value times s."""
    if v is None:
        return None
    scale = getattr(v, "scaled", None)
    if callable(scale):  # e.g. problemfile.AffineTraction
        return scale(s)
    if callable(v):
        def times(x, _v=v):
            return s * _v(x)
        return times
    a = np.asarray(v, dtype=float) * s
    return float(a) if a.ndim == 0 else tuple(float(c) for c in a)


def scaled(problem: ContactProblem, s: float, values: Mapping | None = None) -> ContactProblem:
    """``problem`` with its tractions, body force and Dirichlet values times ``s``.

    Args:
        problem: The problem (of :class:`~dolfinx_feti.Elasticity` forms).
        s: The factor.
        values: Dirichlet group → its value (not scaled), for the conditions on that group.

    Raises:
        InputError: For forms other than :class:`~dolfinx_feti.Elasticity` (their loads are
            not known by name).
    """
    forms = problem.forms
    if type(forms) is not Elasticity:
        raise InputError(f"loading: the loads of {type(forms).__name__} forms cannot be scaled; "
                         "scaled loads need df.Elasticity")
    new = Elasticity(forms.E, forms.nu,
                     tractions={g: _scaled_value(t, s) for g, t in forms.tractions.items()},
                     body_force=_scaled_value(forms.body_force, s), degree=forms.degree)
    values = values or {}
    dirichlet = [Dirichlet(bc.group, values[bc.group] if bc.group in values else
                           _scaled_value(bc.value, s), bc.components)
                 for bc in problem.dirichlet]
    return replace(problem, forms=new, dirichlet=dirichlet)


__all__ = ["scaled"]
