"""The shipped rubber cylinder (problems/rubber_cylinder.toml) as a Python problem."""

from __future__ import annotations

from pathlib import Path

import dolfinx_feti as df


def rubber_cylinder(root: Path) -> df.ContactProblem:
    """The quarter cylinder of meshes/rubber_quarter_disk.msh pressed 0.1 onto a rigid plane."""
    mesh = df.read_gmsh(root / "meshes/rubber_quarter_disk.msh")
    return df.ContactProblem(
        mesh, df.NeoHookean(1.0, 0.3),
        dirichlet=[df.Dirichlet("top", -0.1, components=[1]),
                   df.Dirichlet("axis", 0.0, components=[0])],
        contact=[df.RigidObstacle("arc", df.Plane((0.0, -1.0), (0.0, 1.0)))],
        decomposition=df.Parts(2))
