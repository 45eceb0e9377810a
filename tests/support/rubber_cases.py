"""The rubber cases as Python problems: the shipped cylinder (problems/rubber_cylinder.toml)
and the soft hemisphere of the 3D demo, with its bounds for SNES VI."""

from __future__ import annotations

from pathlib import Path

import numpy as np

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


def rubber_hemisphere(mesh, t: float, parts: int, E: float = 1.0, nu: float = 0.3,
                      R: float = 1.0) -> df.ContactProblem:
    """The quarter hemisphere of ``io.meshes_rubber.quarter_hemisphere`` (neo-Hookean), its top
    pushed down by ``t`` onto the frictionless rigid plane z = −R, in ``Parts(parts)``."""
    return df.ContactProblem(
        mesh, df.NeoHookean(E, nu),
        dirichlet=[df.Dirichlet("top", -t, components=[2]),
                   df.Dirichlet("x0", 0.0, components=[0]),
                   df.Dirichlet("y0", 0.0, components=[1])],
        contact=[df.RigidObstacle("sphere", df.Plane((0.0, 0.0, -R), (0.0, 0.0, 1.0)))],
        decomposition=df.Parts(parts))


def hemisphere_bounds(X: np.ndarray, comp: np.ndarray, load: float):
    """The Dirichlet conditions of :func:`rubber_hemisphere` as SNES VI's equal bounds
    (``snes_vi``'s ``fixed``): per blocked dof, whether it is prescribed, and the values."""
    top = (comp == 2) & (np.abs(X[:, 2]) < 1e-12)
    sym = ((comp == 0) & (np.abs(X[:, 0]) < 1e-12)) | ((comp == 1) & (np.abs(X[:, 1]) < 1e-12))
    m = top | sym
    return m, np.where(top, -load, 0.0)[m]
