"""A problem with its loads scaled: proportional loading and unloading (the ``[loading]`` table).

``scaled(problem, s)`` multiplies the tractions, the body force and the Dirichlet values of an
elasticity or hyperelastic problem by ``s`` (the forms' own ``loads_scaled``); the material, the
conditions, rigid obstacles and friction stay. ``values`` gives Dirichlet groups their own
value per step (a non-proportional path).
Constant tractions and body forces stay runtime constants (no compilation per factor); an
affine traction of a problem file is scaled in its coefficients (compiled once per factor).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

from ..errors import InputError
from ..fem.forms import scaled_value
from ..problem.conditions import Dirichlet
from ..problem.contact_problem import ContactProblem
from ..problem.rigid_motion import RigidMotion


def scaled(problem: ContactProblem, s: float, values: Mapping | None = None) -> ContactProblem:
    """``problem`` with its tractions, body force and Dirichlet values times ``s``.

    Args:
        problem: The problem (of forms with ``loads_scaled``: :class:`~dolfinx_feti.Elasticity`,
            :class:`~dolfinx_feti.Hyperelastic`).
        s: The factor.
        values: Dirichlet group → its value (not scaled), for the conditions on that group.

    Raises:
        InputError: For forms whose loads are not known by name (no ``loads_scaled``).
    """
    by_factor = getattr(problem.forms, "loads_scaled", None)
    if by_factor is None:
        raise InputError(f"loading: the loads of {type(problem.forms).__name__} forms cannot be "
                         "scaled; scaled loads need df.Elasticity or a hyperelastic material")
    values = values or {}
    dirichlet = [Dirichlet(bc.group, values[bc.group] if bc.group in values else
                           scaled_value(bc.value, s), bc.components)
                 for bc in problem.dirichlet]
    return replace(problem, forms=by_factor(s), dirichlet=dirichlet)


def moved(problem: ContactProblem, translations: Mapping[str, Sequence[float]]
          ) -> ContactProblem:
    """``problem`` with the rigid obstacles on the given contact groups translated.

    Each moved obstacle carries a :class:`~dolfinx_feti.RigidMotion` whose centre is its
    translation, so that friction on a load path measures the slip against the obstacle's
    surface (a punch slid sideways drags the nodes stuck to it) — in small deformation as
    under Newton.

    Args:
        problem: The problem.
        translations: Contact group → the obstacle's translation from its position in
            ``problem``.
    """
    if not translations:
        return problem
    contact = [replace(c, obstacle=c.obstacle.translated(translations[c.group]),
                       motion=RigidMotion(tuple(float(v) for v in translations[c.group])))
               if getattr(c, "group", None) in translations else c for c in problem.contact]
    return replace(problem, contact=contact)


def with_friction(problem: ContactProblem, values: Mapping[str, float]) -> ContactProblem:
    """``problem`` with the friction value of the contact conditions on the given groups.

    Args:
        problem: The problem.
        values: A contact condition's first group (an obstacle's group, a pair's slave) → its
            friction law's value: Tresca's slip bound or Coulomb's coefficient.
    """
    if not values:
        return problem
    contact = [replace(c, friction=c.friction.with_value(values[c.groups[0]]))
               if c.groups[0] in values else c for c in problem.contact]
    return replace(problem, contact=contact)


__all__ = ["moved", "scaled", "with_friction"]
