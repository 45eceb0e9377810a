"""The cost of building mortar rows against the assembly of K on the same mesh (serial).

Two blocks stacked with independent meshes (``meshes_occ.stacked_blocks``: unit width, the
upper block's element size h, the lower one's 1.7 h, both ``--layers`` elements thick so that
the contact surface is large against the volume: the worst case for the mortar's share). The
upper block's bottom is the slave surface, with the default search distance. Timed, best of
``--repeat``:

- search + integration: :func:`dolfinx_feti.constraints.mortar.mortar_coupling`;
- rows: :func:`dolfinx_feti.constraints.mortar_rows.mortar_contact_rows` (search, integration,
  the rows and the rim detection: what the solve's setup runs per Mortar condition);
- K: the library's subdomain assembly on the whole mesh as one subdomain: the serial DOLFINx
  mesh (``Subdomain``) and the assembly of the elasticity K (``Subdomain.assemble``; forms
  compiled beforehand).

Run: ``python bench/mortar_assembly.py`` (2D and 3D, the sizes of docs/benchmarks.md);
``--dim 3 --h 0.02 0.01`` for other sizes; ``--recombine`` for structured quadrilaterals and
hexahedra (the bilinear facets' dual basis and clipping, :mod:`.constraints.mortar_quad`);
``--degree 2`` for P2/Q2 (the coupling at the dof points: 3-node segments, 6-node triangles,
9-node quadrilaterals; K of degree 2).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.constraints.mortar import mortar_coupling
from dolfinx_feti.constraints.mortar_p2 import quadratic_coupling
from dolfinx_feti.constraints.mortar_rows import mortar_contact_rows
from dolfinx_feti.fem.subdomain import Subdomain
from dolfinx_feti.io import meshes_occ
from dolfinx_feti.mesh.decompose import decompose
from dolfinx_feti.mesh.dofpoints import dof_points

SIZES = {2: [1e-2, 1e-3, 1e-4], 3: [0.04, 0.02, 0.01, 0.006, 0.004]}


def best(fn, repeat: int) -> tuple[float, object]:
    """The shortest of ``repeat`` runs of ``fn()`` and its last result."""
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def whole_mesh_subdomain(mesh: df.MeshData, points) -> Subdomain:
    """The whole mesh as one serial DOLFINx subdomain (as the solve's setup builds them)."""
    cells = np.arange(mesh.cells.shape[0])
    nodes = np.unique(points.cell_points)
    return Subdomain([0], mesh, [cells], [nodes], [{}], points=points)


def run(dim: int, h: float, layers: int, repeat: int, recombine: bool = False,
        degree: int = 1) -> dict:
    """Mesh the two blocks at size h and time the three phases."""
    t0 = time.perf_counter()
    mesh = df.build_mesh(meshes_occ.stacked_blocks, dim, h_lower=1.7 * h, h_upper=h,
                         height=layers * h, recombine=recombine, comm=MPI.COMM_SELF)
    t_gmsh = time.perf_counter() - t0
    slave, master = mesh.facets("upper_bottom"), mesh.facets("lower_top")
    points = dof_points(mesh, degree)
    if degree == 1:
        t_coupling, coupling = best(lambda: mortar_coupling(
            mesh.x, mesh.cells, slave, master, cell_type=mesh.cell_type), repeat)
    else:
        t_coupling, coupling = best(lambda: quadratic_coupling(
            mesh.x, mesh.cells, slave, master, points, cell_type=mesh.cell_type), repeat)
    dec = decompose(mesh, df.Parts(1), 1, points)
    node_ptr, node_subs = dec.node_subdomains()
    spec = df.Mortar(slave="upper_bottom", master="lower_top")
    t_rows, (rows, _) = best(
        lambda: mortar_contact_rows(mesh, spec, 0, node_ptr, node_subs, dim, points), repeat)
    forms = df.Elasticity(1000.0, 0.3, degree=degree)
    forms.check(mesh)
    t_mesh, sub = best(lambda: whole_mesh_subdomain(mesh, points), repeat)
    t_K, (K, _) = best(lambda: sub.assemble(forms, dim), repeat)
    return {"dim": dim, "h": h, "cell_type": mesh.cell_type, "cells": mesh.cells.shape[0],
            "dofs": K.shape[0],
            "slave": slave.shape[0], "master": master.shape[0], "pairs": coupling.pairs,
            "rows": rows.size, "coupling": t_coupling, "rows_time": t_rows, "mesh": t_mesh,
            "K": t_K, "gmsh": t_gmsh}


def main() -> None:
    """Print a markdown table, one line per mesh."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--dim", type=int, nargs="+", default=[2, 3])
    parser.add_argument("--h", type=float, nargs="+", default=None,
                        help="element sizes of the slave block (default: the table's)")
    parser.add_argument("--layers", type=int, default=5, help="elements across a block")
    parser.add_argument("--repeat", type=int, default=3, help="runs per timing (the best)")
    parser.add_argument("--recombine", action="store_true",
                        help="structured quadrilaterals/hexahedra instead of simplices")
    parser.add_argument("--degree", type=int, default=1, choices=(1, 2))
    args = parser.parse_args()
    for dim in (2, 3):  # compile the forms before any timing
        run(dim, 0.2, 2, 1, args.recombine, args.degree)
    print("| dim | h (slave) | cells | dofs | slave facets | master facets | facet pairs | rows "
          "| search + integration [s] | rows, all [s] | DOLFINx mesh [s] | K assembly [s] "
          "| rows / (mesh + K) | gmsh [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for dim in args.dim:
        for h in args.h or SIZES[dim]:
            r = run(dim, h, args.layers, args.repeat if h > 0.005 else 1, args.recombine,
                    args.degree)
            print(f"| {dim}D | {h:g} | {r['cells']:,} {r['cell_type']} | {r['dofs']:,} | "
                  f"{r['slave']:,} | "
                  f"{r['master']:,} | {r['pairs']:,} | {r['rows']:,} | {r['coupling']:.3f} | "
                  f"{r['rows_time']:.3f} | {r['mesh']:.3f} | {r['K']:.3f} | "
                  f"{r['rows_time'] / (r['mesh'] + r['K']):.2f} | {r['gmsh']:.1f} |",
                  flush=True)


if __name__ == "__main__":
    main()
