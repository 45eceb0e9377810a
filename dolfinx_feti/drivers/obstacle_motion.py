"""How far the obstacles' surfaces carried a contact node's material point in a load step.

The friction rows of a load step measure the slip increment against the obstacle: a node
stuck to the obstacle's surface goes where the surface's material point goes. Per contact
condition, between the last step's problem and this one's:

- both with a :class:`~dolfinx_feti.RigidMotion`: the rigid motion of the body between the
  two poses, at the node's position (a spinning disc moves its surface without moving it);
- neither: the Newton driver takes the translation of the point that moves with the obstacle
  (:data:`ORIGIN`: a Plane's ``point``, a Sphere's ``center``, a Cylinder's ``point``), a
  small-deformation path none (the slip in the fixed frame, as before the motion existed);
- one only: refused by name.

Used by :mod:`.newton_friction` (the increment's rows in the current configuration) and by
:meth:`~dolfinx_feti.FetiSolver.update` with ``slip_from`` (:func:`carried_slip`).
"""

from __future__ import annotations

import numpy as np

from ..constraints.rows import Kind
from ..errors import InputError
from ..problem.conditions import Cylinder, Plane, Sphere
from ..problem.contact_problem import ContactProblem
from ..problem.rigid_motion import material_displacement

#: Obstacle type → the point that moves with it (its translation is the obstacle's motion
#: between two load steps when no RigidMotion is given). A type missing here stands still.
ORIGIN = {Plane: lambda o: o.point, Sphere: lambda o: o.center, Cylinder: lambda o: o.point}


def _origin(cond, gdim: int) -> np.ndarray:
    at = ORIGIN.get(type(getattr(cond, "obstacle", None)))
    return np.zeros(gdim) if at is None else np.asarray(at(cond.obstacle), dtype=float)[:gdim]


def obstacle_motion(before: ContactProblem, after: ContactProblem, spec: np.ndarray,
                    y: np.ndarray, translate: bool) -> np.ndarray:
    """The displacement (k, gdim) of the obstacles' material points at ``y`` in the step.

    Args:
        before: The problem of the last converged step.
        after: The problem of this step.
        spec: Per point, the index of its contact condition.
        y: The points (k, gdim): the nodes where the last step left them.
        translate: Without a RigidMotion, take the obstacle's translation (:data:`ORIGIN`);
            else no motion.

    Raises:
        InputError: A condition with a motion in one step and not in the other.
    """
    gdim = y.shape[1]
    out = np.zeros_like(y, dtype=float)
    for k in np.unique(spec):
        m = spec == k
        c0, c1 = before.contact[int(k)], after.contact[int(k)]
        m0, m1 = getattr(c0, "motion", None), getattr(c1, "motion", None)
        if (m0 is None) != (m1 is None):
            raise InputError(f"RigidObstacle on {c1.group!r}: motion given at one step of the "
                             "path and not at the next; give a RigidMotion at every step")
        if m0 is not None:
            out[m] = material_displacement(m0, m1, y[m])
        elif translate:
            out[m] = _origin(c1, gdim) - _origin(c0, gdim)
    return out


def carried_slip(share, tangential: np.ndarray, before: ContactProblem,
                 after: ContactProblem) -> np.ndarray:
    """B_t D on the rank's tangential rows: D the obstacles' motion at the reference nodes.

    What a small-deformation step adds to the rows' right-hand sides c_t = B_t u (of the last
    step) so that B_t u − c_t is the slip against the moving surface. Zero for conditions
    without a RigidMotion.

    Args:
        share: The rank's share (its rows, dof points).
        tangential: Local indices of the rank's tangential rows.
        before: The problem of the last step.
        after: The problem of this step.
    """
    own = share.rows.own
    out = np.zeros(tangential.size)
    if not tangential.size or not any(getattr(c, "motion", None) is not None
                                      for c in (*after.contact, *before.contact)):
        return out
    pos = np.full(own.size, -1)
    pos[tangential] = np.arange(tangential.size)
    ent = np.flatnonzero((pos[own.e_row] >= 0) & (own.kind[own.e_row] == Kind.TANGENT))
    gdim = own.normal.shape[1]
    y = share.points.x[np.searchsorted(share.point_ids, own.e_node[ent])][:, :gdim]
    d = obstacle_motion(before, after, own.spec[own.e_row[ent]], y, translate=False)
    vals = own.e_coef[ent] * d[np.arange(ent.size), own.e_comp[ent]]
    return np.bincount(pos[own.e_row[ent]], weights=vals, minlength=tangential.size)


__all__ = ["ORIGIN", "carried_slip", "obstacle_motion"]
