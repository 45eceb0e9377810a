"""problems/ironing_path.toml written with the Python API (a rigid die in a neo-Hookean block)."""

from __future__ import annotations

import dolfinx_feti as df


def die_at(mesh, d: tuple[float, float]) -> df.ContactProblem:
    """The block with the die moved by ``d`` from its start (centre (3, 4), radius 1), Coulomb
    0.3 on the slip relative to the die (its RigidMotion the translation), ``Parts(2)``."""
    return df.ContactProblem(
        mesh, df.NeoHookean(1.0, 0.3), dirichlet=[df.Dirichlet("bottom")],
        contact=[df.RigidObstacle("top", df.Sphere((3.0 + d[0], 4.0 + d[1]), 1.0),
                                  friction=df.Coulomb(0.3), motion=df.RigidMotion(d))],
        decomposition=df.Parts(2))
