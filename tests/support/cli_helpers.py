"""Helpers of the command and problem-file tests: a folder shared by the ranks, the demos'
problems through the Python API, files in a folder."""

from __future__ import annotations

import shutil
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import ufl
from mpi4py import MPI

import dolfinx_feti as df

ROOT = Path(__file__).resolve().parents[2]
PROBLEMS = ROOT / "problems"
MESHES = ROOT / "meshes"
COMM = MPI.COMM_WORLD


def shared_dir(prefix: str) -> Path:
    """A new folder made by rank 0, the same path on every rank (pytest's tmp_path is not)."""
    path = Path(tempfile.mkdtemp(prefix=prefix)) if COMM.rank == 0 else None
    return COMM.bcast(path, root=0)


def remove_shared(path: Path) -> None:
    COMM.barrier()
    if COMM.rank == 0:
        shutil.rmtree(path, ignore_errors=True)
    COMM.barrier()


def write_text(path: Path, text: str) -> Path:
    """Write a file on rank 0; every rank returns once it exists."""
    if COMM.rank == 0:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    COMM.barrier()
    return path


def files_in(folder: Path) -> list[str]:
    """Every file under ``folder`` (hidden temporaries included), relative, sorted."""
    if not folder.exists():
        return []
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


# ------------------------------------------------------------------------------------------
# The shipped problems, written with the Python API as in demos/
# ------------------------------------------------------------------------------------------


def _membrane_source(x):
    left = ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0)
    right = ufl.conditional(ufl.lt(x[1], 0.25), -1.0, 0.0)
    return ufl.conditional(ufl.lt(x[0], 1.0), left, right)


def _grid(H: float) -> df.ByFunction:
    k = int(round(2 / H))
    return df.ByFunction(
        lambda m: (np.floor(m[:, 0] / H) + k * np.floor(m[:, 1] / H)).astype(np.int64))


def api_problem(name: str) -> df.ContactProblem:
    """The problem of ``problems/<name>.toml``, built as the demos build it."""
    if name in ("hertz2d", "hertz2d_rigid"):
        mesh = df.read_gmsh(MESHES / "hertz2d.msh")
        forms = df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -10.0 / 2 / 8.0)})
        dirichlet = [df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])]
        if name == "hertz2d":
            return df.ContactProblem(
                mesh, forms, dirichlet=dirichlet,
                contact=[df.NodeToNode(slave="disk_contact", master="block_contact")],
                decomposition=df.Parts(2))
        return df.ContactProblem(
            mesh, forms, dirichlet=dirichlet,
            contact=[df.RigidObstacle("disk_contact", df.Plane((0.0, 0.0), (0.0, 1.0)))],
            decomposition=df.Parts({"disk": 2, "block": 1}))
    if name in ("hertz2d_mortar", "disk_block2d"):  # element sizes 1 : 1 and 1 : 1.7
        msh = "disk_on_block.msh" if name == "hertz2d_mortar" else "disk_on_block_17.msh"
        return df.ContactProblem(
            df.read_gmsh(MESHES / msh),
            df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -10.0 / 2 / 8.0)}),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
            contact=[df.Mortar(slave="disk_contact", master="block_contact")],
            decomposition=df.Parts(2))
    if name == "blocks2d_tie":
        return df.ContactProblem(
            df.read_gmsh(MESHES / "stacked_blocks2d.msh"),
            df.Elasticity(100.0, 0.3, tractions={"top": (0.0, -1.0)}),
            dirichlet=[df.Dirichlet("bottom", components=[1]),
                       df.Dirichlet("sym0", components=[0])],
            ties=[df.Tie(slave="upper_bottom", master="lower_top")], decomposition=df.Parts(2))
    if name in ("sphere_block3d", "inclusions"):
        return _mortar_demo_problem(name)
    if name in ("membranes", "membranes_8"):
        n = 16 if name == "membranes" else 8
        mesh = df.read_gmsh(MESHES / f"membranes_{n}.msh")
        return df.ContactProblem(
            mesh, df.Poisson(source=_membrane_source), dirichlet=[df.Dirichlet("dirichlet")],
            contact=[df.NodeToNode(slave="contact_left", master="contact_right")],
            decomposition=_grid(0.25) if n == 16 else df.ByTags())
    if name == "blocks3d":
        mesh = df.read_gmsh(MESHES / "blocks3d.msh")
        return df.ContactProblem(
            mesh, df.Elasticity(E={"lower": 1000.0, "upper": 500.0}, nu=0.3,
                                tractions={"top": (0.0, 0.0, -1.0)}),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sides_upper", components=[0, 1])],
            contact=[df.NodeToNode(slave="contact_upper", master="contact_lower")],
            decomposition=df.Parts(2))
    return _friction_problem(name)


def _mortar_demo_problem(name: str) -> df.ContactProblem:
    """The problems of the mortar demos sphere_block3d and inclusions."""
    if name == "sphere_block3d":
        return df.ContactProblem(
            df.read_gmsh(MESHES / "sphere_on_block.msh"),
            df.Elasticity(200.0, 0.3, tractions={"load": (0.0, 0.0, -20.0 / (np.pi * 64.0))}),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sym_x", components=[0]),
                       df.Dirichlet("sym_y", components=[1])],
            contact=[df.Mortar(slave="sphere_contact", master="block_contact")],
            decomposition=df.Parts(2))
    return df.ContactProblem(
        df.read_gmsh(MESHES / "slab_with_inclusions.msh"),
        df.Elasticity({"matrix": 100.0, "inclusions": 1e5, "foundation": 100.0}, 0.3,
                      tractions={"load": (0.0, -1.0)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.Mortar(slave="slab_bottom", master="foundation_top")],
        ties=[df.Tie(slave="holes", master="inclusion_surface")],
        decomposition=df.Parts({"matrix": 2, "inclusions": 1, "foundation": 2}))


def _friction_problem(name: str) -> df.ContactProblem:
    """The problems of the friction demos (tresca2d, tresca3d, coulomb_cylinders)."""
    from dolfinx_feti.io import meshes

    if name == "tresca2d":
        mesh = df.build_mesh(meshes.tresca2d, n=16)
        return df.ContactProblem(
            mesh, df.Elasticity(21.19, 0.277),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=(0.02, -0.02))],
            contact=[df.NodeToNode(slave="block_bottom", master="foundation_top",
                                   friction=df.Tresca(0.1))],
            decomposition=df.Parts(4))
    if name == "tresca3d":
        mesh = df.build_mesh(meshes.blocks3d, n=8)
        return df.ContactProblem(
            mesh, df.Elasticity(1.0, 0.3),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=(0.02, 0.01, -0.02))],
            contact=[df.NodeToNode("contact_upper", "contact_lower",
                                   friction=df.Tresca(0.0075))],
            decomposition=df.Parts(2))
    if name == "coulomb_cylinders":
        R, P, F = 8.0, 10.0, 0.4
        Q = 0.5 * F * P
        m = 3.0 * Q / (2.0 * R**2)
        mesh = df.build_mesh(meshes.hertz2d_full, h_contact=0.05, R=R)
        return df.ContactProblem(
            mesh, df.Elasticity(200.0, 0.3, tractions={
                "load": lambda x: ufl.as_vector((Q / (2 * R), -P / (2 * R) + m * x[0]))}),
            dirichlet=[df.Dirichlet("bottom")],
            contact=[df.NodeToNode("disk_contact", "block_contact", friction=df.Coulomb(F))],
            decomposition=df.Parts(2))
    raise KeyError(name)


FRICTION = ("coulomb_cylinders", "tresca2d", "tresca3d")
SHIPPED = ("blocks3d", "hertz2d", "hertz2d_rigid", "hertz2d_mortar", "membranes", "membranes_8",
           "blocks2d_tie", "sphere_block3d", "disk_block2d", "inclusions", *FRICTION)
HAS_FRICTION = hasattr(df, "Tresca") and hasattr(df, "Coulomb")


def file_rtol(name: str) -> float:
    """The [solver] rtol of a shipped problem file."""
    with open(PROBLEMS / f"{name}.toml", "rb") as f:
        return tomllib.load(f)["solver"]["rtol"]
