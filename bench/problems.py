"""Problem builders shared by the benchmark scripts in ``bench/``.

Every builder returns a :class:`dolfinx_feti.ContactProblem`; meshes are built in memory by
gmsh on rank 0 (``read_gmsh`` broadcasts them) and cached per process, so a script that solves
one mesh with several decompositions or solver options builds it once.

Problems:

- :func:`b1` — Dostál's two membranes (BENCHMARKS.md B1) on an n×n grid per membrane, with a
  regular H×H decomposition (or one subdomain per membrane).
- :func:`b1_held` — B1 with the right membrane held on x = 2 too (coercive: every body held).
- :func:`hertz2d` — the 2D Hertz half model of ``demos/demo_hertz2d.py`` (disk R = 8 on a
  20×20 block, E = 200, ν = 0.3, line load 10), cut into ``Parts(parts)``.
- :func:`blocks3d` — two stacked 3D blocks (E = 1000, ν = 0.3, top traction (0, 0, −1)),
  lower one clamped at the bottom, ``Parts(parts)``.
- :func:`squares2d` — B1's two unit squares in plane-strain elasticity with a regular H×H
  decomposition: the 2D elasticity analogue of B1, used for the B5 scalability table of 2D
  elasticity contact (see ``docs/benchmarks.md``).
"""

from __future__ import annotations

import argparse
import functools
from collections.abc import Callable

import gmsh
import numpy as np
import ufl
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes
from dolfinx_feti.options import command_line_options

# ------------------------------------------------------------------------------------------------
# Meshes
# ------------------------------------------------------------------------------------------------


def gmsh_mesh(build: Callable[[], object], comm: MPI.Comm = MPI.COMM_WORLD) -> df.MeshData:
    """Run ``build()`` in a fresh gmsh session on rank 0 and read the model on every rank."""
    if comm.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            build()
        except BaseException:
            gmsh.finalize()
            raise
    try:
        return df.read_gmsh(None, comm)
    finally:
        if comm.rank == 0:
            gmsh.finalize()


@functools.lru_cache(maxsize=4)
def membranes_mesh(n: int) -> df.MeshData:
    """B1's two unit squares, n×n grid each (cached)."""
    return gmsh_mesh(lambda: meshes.membranes(n))


def _membranes_held_model(n: int) -> None:
    """B1's membranes with one more group: "right_end" (1, 14) = {2}×[0,1]."""
    meshes.membranes(n)
    curves = gmsh.model.getEntitiesInBoundingBox(2.0 - 1e-9, -1e-9, -1.0, 2.0 + 1e-9,
                                                 1.0 + 1e-9, 1.0, dim=1)
    gmsh.model.addPhysicalGroup(1, [c[1] for c in curves], 14)
    gmsh.model.setPhysicalName(1, 14, "right_end")


@functools.lru_cache(maxsize=4)
def membranes_held_mesh(n: int) -> df.MeshData:
    """B1's two unit squares with the group "right_end" on x = 2 (cached)."""
    return gmsh_mesh(lambda: _membranes_held_model(n))


@functools.lru_cache(maxsize=4)
def hertz2d_mesh(h_contact: float = 0.05, h_far: float = 1.0) -> df.MeshData:
    """The 2D Hertz half model of :func:`dolfinx_feti.io.meshes.hertz2d` (cached)."""
    return gmsh_mesh(lambda: meshes.hertz2d(h_contact=h_contact, h_far=h_far))


@functools.lru_cache(maxsize=4)
def blocks3d_mesh(n: int = 4) -> df.MeshData:
    """Two stacked 3D blocks of :func:`dolfinx_feti.io.meshes.blocks3d` (cached)."""
    return gmsh_mesh(lambda: meshes.blocks3d(n))


def _squares2d_model(n: int) -> None:
    """B1's geometry for plane elasticity, as a gmsh model.

    "left" = [0,1]² and "right" = [1,2]×[0,1], each an n×n grid of squares cut into two
    triangles (transfinite), each with its own nodes on x = 1. Physical groups: "left" (2, 1),
    "right" (2, 2), "clamp" (1, 11) = x = 0, "contact_left" (1, 12) and "contact_right"
    (1, 13) = x = 1 of each square, "bottom_right" (1, 14) = the right square's side y = 0.
    """
    gmsh.model.add(f"squares2d_{n}")
    gmsh.option.setNumber("Mesh.ElementOrder", 1)
    geo = gmsh.model.geo

    def square(x0: float) -> tuple[int, list[int]]:
        p = [geo.addPoint(x0, 0.0, 0.0), geo.addPoint(x0 + 1.0, 0.0, 0.0),
             geo.addPoint(x0 + 1.0, 1.0, 0.0), geo.addPoint(x0, 1.0, 0.0)]
        lines = [geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]  # bottom, right, top, left
        return geo.addPlaneSurface([geo.addCurveLoop(lines)]), lines

    left, lc = square(0.0)
    right, rc = square(1.0)
    geo.synchronize()
    for curve in lc + rc:
        gmsh.model.mesh.setTransfiniteCurve(curve, n + 1)
    for surface in (left, right):
        gmsh.model.mesh.setTransfiniteSurface(surface, "Right")
    groups = [(2, [left], 1, "left"), (2, [right], 2, "right"), (1, [lc[3]], 11, "clamp"),
              (1, [lc[1]], 12, "contact_left"), (1, [rc[3]], 13, "contact_right"),
              (1, [rc[0]], 14, "bottom_right")]
    for dim, entities, tag, name in groups:
        gmsh.model.addPhysicalGroup(dim, entities, tag)
        gmsh.model.setPhysicalName(dim, tag, name)
    gmsh.model.mesh.generate(2)


@functools.lru_cache(maxsize=4)
def squares2d_mesh(n: int) -> df.MeshData:
    """B1's two unit squares for plane elasticity, n×n grid each (cached; see squares2d)."""
    return gmsh_mesh(lambda: _squares2d_model(n))


# ------------------------------------------------------------------------------------------------
# Decompositions
# ------------------------------------------------------------------------------------------------


def grid(H: float) -> df.ByFunction:
    """Regular H×H squares (labels from the cell midpoints; 1/H must be an integer)."""
    k = 1000  # more columns than any grid here

    def label(m: np.ndarray) -> np.ndarray:
        return (np.floor(m[:, 0] / H) + k * np.floor(m[:, 1] / H)).astype(np.int64)

    return df.ByFunction(label)


def elements_per_unit(H: float, H_over_h: int) -> int:
    """n = (H/h) / H, checked to be an integer."""
    n = H_over_h / H
    if abs(n - round(n)) > 1e-9:
        raise ValueError(f"(H/h)/H = {H_over_h}/{H} is not an integer")
    return int(round(n))


# ------------------------------------------------------------------------------------------------
# Problems
# ------------------------------------------------------------------------------------------------


def b1_source(x):
    """B1's load: −3 on (0,1)×[0.75,1), −1 on (1,2)×[0,0.25), 0 elsewhere."""
    return ufl.conditional(ufl.lt(x[0], 1.0), ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0),
                           ufl.conditional(ufl.lt(x[1], 0.25), -1.0, 0.0))


def b1(n: int, H: float | None) -> df.ContactProblem:
    """B1 on an n×n grid per membrane; H×H subdomains (H = None: one per membrane)."""
    return df.ContactProblem(
        membranes_mesh(n), df.Poisson(source=b1_source), dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")],
        decomposition=df.ByTags() if H is None else grid(H))


def b1_held(n: int, H: float | None) -> df.ContactProblem:
    """The coercive variant of B1: the right membrane held too, u_2 = 0 on {2}×[0,1].

    Every body is held, so FETI-DP's K̃ is positive definite (no coarse space on the dual).
    """
    return df.ContactProblem(
        membranes_held_mesh(n), df.Poisson(source=b1_source),
        dirichlet=[df.Dirichlet("dirichlet"), df.Dirichlet("right_end")],
        contact=[df.NodeToNode("contact_left", "contact_right")],
        decomposition=df.ByTags() if H is None else grid(H))


def b1_linear(n: int, H: float | None) -> df.ContactProblem:
    """B1's linear floor: the same mesh, load and decomposition, the contact surfaces clamped.

    Both membranes are then fixed on one side and there is no inequality: the solve is
    projected CG on P F P of the same subdomains, i.e. the cost of one linear FETI solve.
    """
    return df.ContactProblem(
        membranes_mesh(n), df.Poisson(source=b1_source),
        dirichlet=[df.Dirichlet("dirichlet"), df.Dirichlet("contact_left"),
                   df.Dirichlet("contact_right")],
        contact=[], decomposition=df.ByTags() if H is None else grid(H))


def hertz2d(parts: int = 4, h_contact: float = 0.05, h_far: float = 1.0,
            decomposition=None) -> df.ContactProblem:
    """The 2D Hertz half model (disk R = 8 on a block, E = 200, ν = 0.3, P = 10)."""
    R, P = 8.0, 10.0
    return df.ContactProblem(
        hertz2d_mesh(h_contact, h_far),
        df.Elasticity(200.0, 0.3, tractions={"load": (0.0, -P / 2 / R)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.NodeToNode("disk_contact", "block_contact")],
        decomposition=decomposition or df.Parts(parts))


def blocks3d(n: int = 4, parts: int = 2, sides: bool = True,
             decomposition=None) -> df.ContactProblem:
    """Two stacked 3D blocks, lower clamped at the bottom, top traction (0, 0, −1).

    sides: rollers (u_x = u_y = 0) on the upper block's sides; without them the upper block's
    horizontal motions are left undetermined (and unloaded).
    """
    dirichlet = [df.Dirichlet("bottom")]
    if sides:
        dirichlet.append(df.Dirichlet("sides_upper", components=[0, 1]))
    return df.ContactProblem(
        blocks3d_mesh(n), df.Elasticity(1000.0, 0.3, tractions={"top": (0.0, 0.0, -1.0)}),
        dirichlet=dirichlet, contact=[df.NodeToNode("contact_upper", "contact_lower")],
        decomposition=decomposition or df.Parts(parts))


def squares2d_body_force(x):
    """B1's load turned in-plane: (−3, 0) on (0,1)×[0.75,1), (−1, 0) on (1,2)×[0,0.25)."""
    fx = ufl.conditional(ufl.lt(x[0], 1.0), ufl.conditional(ufl.ge(x[1], 0.75), -3.0, 0.0),
                         ufl.conditional(ufl.lt(x[1], 0.25), -1.0, 0.0))
    return ufl.as_vector((fx, 0.0))


def squares2d(n: int, H: float | None) -> df.ContactProblem:
    """The plane-elasticity analogue of B1 (E = 1, ν = 0.3, plane strain).

    B1's squares and H×H decomposition, n×n squares per body cut into two triangles each; the
    left square is clamped on x = 0, the right one rests against it (node-to-node contact on
    x = 1, normal x) and is held by rollers on its bottom side (u_y = 0, which also stop its
    rotation), so its horizontal motion is stopped by the contact only. B1's loads act
    in-plane, along x: (−3, 0) on the left square's top quarter pulls it away from the
    interface, (−1, 0) on the right square's bottom quarter pushes that square onto it. The
    contact set is a proper part of the interface (as in B1). H×H subdomains (H = None: one
    per body).
    """
    return df.ContactProblem(
        squares2d_mesh(n), df.Elasticity(1.0, 0.3, body_force=squares2d_body_force),
        dirichlet=[df.Dirichlet("clamp"), df.Dirichlet("bottom_right", components=[1])],
        contact=[df.NodeToNode("contact_right", "contact_left")],
        decomposition=df.ByTags() if H is None else grid(H))


# ------------------------------------------------------------------------------------------------
# Helpers for the scripts
# ------------------------------------------------------------------------------------------------


def parse_with_feti_options(parser: argparse.ArgumentParser) -> tuple[argparse.Namespace, list]:
    """The script's arguments and the ``-feti_<name> value`` tokens for ``df.solve(options=)``.

    The solver options pass through (``-feti_mprgp_expansion projcg``), checked by name and
    type before any mesh is built; any other unknown token is the parser's error.
    """
    args, rest = parser.parse_known_args()
    command_line_options(rest)  # InputError: an unknown -feti_ name or a bad value
    stray = [t for i, t in enumerate(rest) if not t.startswith("-feti_")
             and not (i > 0 and rest[i - 1].startswith("-feti_"))]
    if stray:
        parser.error(f"unrecognized arguments: {' '.join(stray)}")
    return args, rest


def is_root(comm: MPI.Comm = MPI.COMM_WORLD) -> bool:
    """Rank 0 writes the tables and the figures."""
    return comm.rank == 0


def md_table(header: list[str], rows: list[list]) -> str:
    """A markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def write_outputs(out, lines: list[str], rows: list[dict]) -> None:
    """Write the markdown ``lines`` to ``out`` and the ``rows`` beside it as JSON; print them."""
    import json
    from pathlib import Path

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    out.with_suffix(".json").write_text(json.dumps(rows, indent=1))
    print("\n".join(lines))


def machine() -> str:
    """One line about where the numbers were measured."""
    import os
    import platform

    cores = os.cpu_count()
    try:
        with open("/proc/meminfo") as f:
            mem = int(f.readline().split()[1]) / 2**20
    except OSError:
        mem = float("nan")
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    return (f"{platform.node() or 'host'}: {cores} cores, {mem:.0f} GiB, "
            f"{MPI.COMM_WORLD.size} MPI rank(s), OMP_NUM_THREADS="
            f"{os.environ.get('OMP_NUM_THREADS', 'unset')}, Python {platform.python_version()}, "
            f"load average at the end {load} (the machine is shared: times are noisy)")


def solve_record(problem: df.ContactProblem, repeat: int = 1, **options) -> dict:
    """Solve ``repeat`` times with the given options and return one row of measurements.

    Counts come from the first solve (they do not change between repeats); times are the
    minimum over the repeats (the least disturbed run). "solve" time = preconditioner setup +
    iterations, the part of the time that depends on the solver options; "total" includes
    decomposition, assembly, factorization, the coarse problem and the recovery.
    """
    import time

    row = None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        sol = df.solve(problem, **options)
        wall = time.perf_counter() - t0
        r = sol.report
        t = r.timings
        solve_time = t.get("preconditioner", 0.0) + t.get("iterations", 0.0)
        if row is None:
            row = {"primal": r.sizes["primal"], "dual": r.sizes["dual"],
                   "inequality": r.sizes["inequality"], "subdomains": r.sizes["subdomains"],
                   "converged": r.converged, "reason": r.reason,
                   "outer": r.outer_iterations, "inner": r.iterations,
                   "mults": r.hessian_mults, "mults_total": r.hessian_mults_total,
                   "precond": r.counts.get("precond", 0), "cg": r.counts.get("cg", 0),
                   "expansion": r.counts.get("expansion", 0),
                   "proportioning": r.counts.get("proportioning", 0),
                   "gP_rel": r.gP_rel, "G_lambda": r.G_lambda, "norm_F": r.norm_F,
                   "t_iter": t.get("iterations", 0.0), "t_prec": t.get("preconditioner", 0.0),
                   "t_solve": solve_time, "t_total": t["total"], "wall": wall,
                   "timings": dict(t)}
        else:
            for key, value in (("t_iter", t.get("iterations", 0.0)),
                               ("t_prec", t.get("preconditioner", 0.0)),
                               ("t_solve", solve_time), ("t_total", t["total"]),
                               ("wall", wall)):
                row[key] = min(row[key], value)
        del sol
    return row


def git_state() -> str:
    """The commit the numbers were measured on (and whether the tree had local changes)."""
    import subprocess
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, text=True,
                              capture_output=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "dolfinx_feti"],
                               cwd=root, text=True, capture_output=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + (" + uncommitted changes in dolfinx_feti/" if dirty else "")
