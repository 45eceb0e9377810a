"""The Hertz problems on the models of ``io.meshes_occ`` (a disk or a sphere on a block).

Shared by the tests of mortar contact and of bodies of different cell types, and by
``bench/mixed_cell_types.py``.
"""

from __future__ import annotations

import numpy as np

import dolfinx_feti as df

R, E_H, NU_H = 8.0, 200.0, 0.3
E_STAR = E_H / (2.0 * (1.0 - NU_H**2))
#: 2D (plane strain): the load per unit thickness on the half model's disk, Hertz's contact
#: half-width and peak pressure.
DISK_P = 10.0
DISK_A = 2.0 * np.sqrt(R * DISK_P / (np.pi * E_STAR))
DISK_P0 = np.sqrt(DISK_P * E_STAR / (np.pi * R))
#: 3D: the force on the whole sphere, Hertz's contact radius and peak pressure.
SPHERE_F = 20.0
SPHERE_A = (3 * SPHERE_F * R / (4 * E_STAR)) ** (1 / 3)
SPHERE_P0 = 3 * SPHERE_F / (2 * np.pi * SPHERE_A**2)


def disk_problem(mesh, slave: str = "disk_contact", decomposition=None) -> df.ContactProblem:
    """The half model of ``disk_on_block``: the disk's flat top loaded, mortar contact."""
    return df.ContactProblem(
        mesh, df.Elasticity(E_H, NU_H, tractions={"load": (0.0, -DISK_P / 2 / R)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.Mortar(slave, "block_contact")],
        decomposition=decomposition or df.Parts(4))


def sphere_problem(mesh, decomposition=None) -> tuple[df.ContactProblem, float]:
    """The quarter model of ``sphere_on_block`` under SPHERE_F, and the traction on its top."""
    t = SPHERE_F / 4 / (np.pi * R**2 / 4)
    problem = df.ContactProblem(
        mesh, df.Elasticity(E_H, NU_H, tractions={"load": (0.0, 0.0, -t)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sym_x", components=[0]),
                   df.Dirichlet("sym_y", components=[1])],
        contact=[df.Mortar("sphere_contact", "block_contact")],
        decomposition=decomposition or df.Parts(8))
    return problem, t


def mixed_figures(sol, mesh, dim: int) -> tuple[float, float, float]:
    """Of a Hertz solve on a mixed mesh (:class:`df.MixedMesh`): the peak pressure, the
    contact half-width (2D) or radius (3D: the farthest slave node with pressure), and the
    block's element size there (its top facets' extent within 0.3–0.5 of Hertz's value).
    """
    f = sol.forces(0)
    pmax = f["pressure"].max()
    r = np.abs(f["x"][:, 0]) if dim == 2 else np.linalg.norm(f["x"][:, :2], axis=1)
    reach = r[f["pressure"] > 1e-6 * pmax].max()
    block = mesh.parts[mesh.part_of_body("block")]
    top = block.x[block.facets("block_contact")][:, :, :dim - 1]
    a = DISK_A if dim == 2 else SPHERE_A
    near = np.abs(np.linalg.norm(top.mean(axis=1), axis=1) - a) < (0.5 if dim == 2 else 0.3)
    return pmax, reach, float(np.ptp(top[near], axis=1).max())
