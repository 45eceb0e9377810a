"""The B1 membranes (Dostál's two membranes in contact) on the 16 × 16 mesh, H = 1/4."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import ufl

import dolfinx_feti as df


def b1_source(x):
    """The load of B1: −3 on the upper quarter of the left membrane, −1 on its lower quarter."""
    return ufl.conditional(ufl.lt(x[0], 1.0), ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0),
                           ufl.conditional(ufl.lt(x[1], 0.25), -1.0, 0.0))


def b1_grid(root: Path) -> df.ContactProblem:
    """B1 on ``meshes/membranes_16.msh`` cut into a regular grid of 1/4 × 1/4 subdomains."""
    mesh = df.read_gmsh(root / "meshes/membranes_16.msh")
    grid = df.ByFunction(lambda m: (np.floor(m[:, 0] / 0.25)
                                    + 100 * np.floor(m[:, 1] / 0.25)).astype(np.int64))
    return df.ContactProblem(mesh, df.Poisson(source=b1_source),
                             dirichlet=[df.Dirichlet("dirichlet")],
                             contact=[df.NodeToNode("contact_left", "contact_right")],
                             decomposition=grid)
