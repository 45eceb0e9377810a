"""The seed's "3D 2 blocks problem", matching and non-matching grids: SMALBE iteration counts.

The seed reports SMALBE counts for two elastic blocks in 3D, with matching grids and with
non-matching grids (the latter coupled by mortars), without defining the blocks. Our case:
the lower block [0,1]² × [0,0.5] (E = 1000), the upper one [0,1]² × [0.5,1] (E = 500),
ν = 0.3, each meshed on its own by gmsh (``meshes_occ.stacked_blocks``), rollers on the
planes x = 0 and y = 0 and on the base (u_z = 0), frictionless contact between the blocks,
a traction on the top of the upper block, and the library defaults (Total FETI, SMALBE-M
with MPRGP) with ||g^P|| <= 1e-6 ||b||. Two loads:

- uniform, t_z = −1: the exact solution is uniaxial stress, so the contact pressure is 1
  everywhere (the check column gives max |p − 1|);
- varying, t_z = 0.5 − 2x: it pulls the top up near x = 0 and pushes it down beyond, so the
  contact opens near x = 0 (a partly active set); the contact force must equal the net load
  0.5 (the check column gives its relative error).

Matching grids: ``meshes.blocks3d`` (structured, n = 1/h cells per unit length, the two
contact faces triangulated alike) with ``NodeToNode``; non-matching grids:
``meshes_occ.stacked_blocks`` (unstructured, element sizes h on the upper block and 1.7 h
on the lower one, each meshed on its own) with ``Mortar``, the upper block's face as slave.

Run: ``python bench/seed_blocks3d.py`` (about a minute).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import ufl
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes, meshes_occ

E = {"lower": 1000.0, "upper": 500.0}
NU = 0.3
LOADS = {"uniform": (0.0, 0.0, -1.0),
         "varying": lambda x: ufl.as_vector((0.0, 0.0, 0.5 - 2.0 * x[0]))}
NET_LOAD = {"uniform": 1.0, "varying": 0.5}


def matching_mesh(h: float, comm) -> df.MeshData:
    """blocks3d with the group names of stacked_blocks (the symmetry planes split out)."""
    m = df.build_mesh(meshes.blocks3d, int(round(1 / h)), comm=comm)
    sides = np.concatenate([m.facets("sides_lower"), m.facets("sides_upper")])
    groups = {"bottom": m.facets("bottom"), "top": m.facets("top"),
              "upper_bottom": m.facets("contact_upper"), "lower_top": m.facets("contact_lower"),
              "sym0": sides[np.all(m.x[sides][:, :, 0] == 0.0, axis=1)],
              "sym1": sides[np.all(m.x[sides][:, :, 1] == 0.0, axis=1)]}
    return df.MeshData(m.x, m.cells, m.cell_type, m.cell_body, m.body_names, groups,
                       m.node_tags)


def solve(h: float, matching: bool, load: str, parts: int, comm) -> dict:
    """One solve: the mesh, the problem, the counts and the check."""
    h_lower = h if matching else 1.7 * h
    mesh = matching_mesh(h, comm) if matching else df.build_mesh(
        meshes_occ.stacked_blocks, 3, h_lower=h_lower, h_upper=h, width=1.0, height=0.5,
        comm=comm)
    contact = (df.NodeToNode if matching else df.Mortar)(slave="upper_bottom",
                                                           master="lower_top")
    problem = df.ContactProblem(
        mesh, df.Elasticity(E, NU, tractions={"top": LOADS[load]}),
        dirichlet=[df.Dirichlet("bottom", components=[2]), df.Dirichlet("sym0", components=[0]),
                   df.Dirichlet("sym1", components=[1])],
        contact=[contact], decomposition=df.Parts(parts))
    t0 = time.perf_counter()
    sol = df.solve(problem, comm=comm, rtol=1e-6)
    elapsed = time.perf_counter() - t0
    r = sol.report
    p = sol.contact.pressure
    if load == "uniform":
        check = f"max abs(p - 1) = {np.abs(p - 1.0).max():.1e}"
    else:
        err = abs(sol.total_contact_force[2] - NET_LOAD[load]) / NET_LOAD[load]
        check = f"force error {err:.1e}"
    return {"grids": "matching" if matching else "non-matching",
            "contact": "node-to-node" if matching else "mortar",
            "h": f"{h:g} / {h_lower:g}", "nodes": mesh.num_nodes, "load": load,
            "subdomains": r.sizes["subdomains"],
            "primal": r.sizes["primal"], "dual": r.sizes["dual"],
            "contact_rows": r.sizes["inequality"], "active": int((p > 1e-8 * p.max()).sum()),
            "outer": r.outer_iterations, "inner": r.iterations, "mults": r.hessian_mults,
            "time": elapsed, "check": check, "converged": r.converged}


def main() -> None:
    """Print a markdown table, one line per solve."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--h", type=float, nargs="+", default=[0.1, 0.05],
                        help="element sizes of the upper block")
    parser.add_argument("--parts", type=int, nargs="+", default=[2, 8],
                        help="subdomains per block")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    rows = [solve(h, matching, load, parts, comm)
            for load in LOADS for h in args.h for parts in args.parts
            for matching in (True, False)]
    if comm.rank == 0:
        print("| load | grids, contact | h upper / lower | nodes | subdomains | primal / dual dofs "
              "| contact rows (active) | outer | inner | F-mults | time [s] | check |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            print(f"| {r['load']} | {r['grids']}, {r['contact']} | {r['h']} | "
                  f"{r['nodes']:,} | {r['subdomains']} | {r['primal']:,} / {r['dual']:,} | "
                  f"{r['contact_rows']} ({r['active']}) | {r['outer']} | {r['inner']} | "
                  f"{r['mults']} | {r['time']:.2f} | {r['check']}"
                  f"{'' if r['converged'] else ' NOT CONVERGED'} |")
        print("seed (its table, SMALBE, columns 'inner outer'): matching grids 13 29, "
              "non-matching grids 10 29")


if __name__ == "__main__":
    main()
