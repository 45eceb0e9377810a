"""The seed's FETI-DP table for mortars (Dostál et al., "orthogonalized constraints").

B1's two membranes (the unit squares (0,1)² and (1,2)×(0,1), the left one held on x = 0,
B1's load) with non-matching grids: the left membrane cut into N₁ = rows × columns
subdomains of H₁/h₁ elements a side, the right one into N₂ subdomains of H₂/h₂ elements
(1×2 against 1×3, 2×4 against 2×5, 4×8 against 4×11; H₁/h₁ = 4, 8, 16 against
H₂/h₂ = 7, 13, 25), so the subdomains are rectangles of structured triangles and the contact
edge x = 1 carries r₁·H₁/h₁ elements on the left and r₂·H₂/h₂ on the right. Mortar contact,
the right (finer) side as slave, as the seed's dual counts imply; a scalar mortar row reads
u_s − Σ_k w_k u_k ≤ 0, the opposite of B1's u_left ≤ u_right with the right side as slave, so
B1's load is taken with its sign turned (u → −u maps the one problem onto the other);
FETI-DP with our corners (the cross points of the subdomain grid and its ends on the
boundary; in a strip of subdomains, 1 × n, fewer).

What the seed's counts imply: primal = subdomains × (H/h + 1)² (ours equal); corners = the
cross points and every end of a subdomain interface (ours equal but in the strips); dual =
the gluing rows (Dirichlet eliminated) plus 2·r₁·H₁/h₁ − 2·(corners on the contact edge)
mortar rows: two per element of the coarser (left) edge, a discontinuous linear multiplier
on that side (its "orthogonalized constraints"). Ours: one row per node of the finer (slave)
edge, the continuous dual basis of :mod:`dolfinx_feti.constraints.mortar`.

Table: primal/dual/corner nodes and F-multiplications, ours beside the seed's two tables
(the talk does not say what differs between them), for B1 as specified (the right membrane
floats: semicoercive FETI-DP, SMALBE) and its coercive variant (the right membrane also held
on x = 2: MPRGP alone).

Run: ``python bench/seed_fetidp_mortar.py`` (``--help``; ~1 min). Writes
``output/bench/seed_fetidp_mortar.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import gmsh
import numpy as np
from mpi4py import MPI
from seed_fetidp import cell, solve

import dolfinx_feti as df
from dolfinx_feti.io.meshes import (
    add_group,
    add_structured_box,
    physical_groups,
    set_output_options,
)
from problems import b1_source, gmsh_mesh

ROOT = Path(__file__).resolve().parent.parent

#: The columns of the seed's table: (N₁, N₂) as (rows, columns).
LAYOUTS = [((1, 2), (1, 3)), ((2, 4), (2, 5)), ((4, 8), (4, 11))]
#: Its rows: (H₁/h₁, H₂/h₂).
RATIOS = [(4, 7), (8, 13), (16, 25)]
#: The seed's two tables: (H₁/h₁, N₁ columns) → (primal, dual, corners, iterations).
SEED = [{(4, 2): (242, 23, 6, 15), (4, 4): (840, 122, 25, 34), (4, 8): (3616, 620, 97, 49),
         (8, 2): (750, 47, 6, 29), (8, 4): (2608, 256, 25, 49), (8, 8): (11216, 1298, 97, 59),
         (16, 2): (2606, 95, 6, 33), (16, 4): (9072, 524, 25, 57),
         (16, 8): (38992, 2654, 97, 78)},
        {(4, 2): (242, 23, 6, 20), (4, 4): (840, 122, 25, 37), (4, 8): (3616, 620, 97, 52),
         (8, 2): (750, 47, 6, 36), (8, 4): (2608, 256, 25, 56), (8, 8): (11216, 1298, 97, 70),
         (16, 2): (2606, 95, 6, 39), (16, 4): (9072, 524, 25, 65),
         (16, 8): (38992, 2654, 97, 84)}]


def _model(cells_left: tuple[int, int], cells_right: tuple[int, int]) -> dict:
    """The two membranes with their own structured grids (cells along x and y)."""
    gmsh.model.add(f"membranes_{cells_left}_{cells_right}")
    set_output_options()
    left, ls, tag = add_structured_box((0.0, 0.0), (1.0, 1.0), cells_left, 1)
    right, rs, _ = add_structured_box((1.0, 0.0), (2.0, 1.0), cells_right, tag)
    add_group(2, [left], 1, "left")
    add_group(2, [right], 2, "right")
    add_group(1, [ls[0, 0]], 11, "dirichlet")
    add_group(1, [ls[0, 1]], 12, "contact_left")
    add_group(1, [rs[0, 0]], 13, "contact_right")
    add_group(1, [rs[0, 1]], 14, "right_end")
    return physical_groups()


def problem(n1: tuple[int, int], n2: tuple[int, int], k1: int, k2: int,
            held: bool) -> df.ContactProblem:
    """B1 on the layouts n1, n2 (rows, columns) of subdomains of k1, k2 elements a side."""
    mesh = gmsh_mesh(lambda: _model((n1[1] * k1, n1[0] * k1), (n2[1] * k2, n2[0] * k2)))

    def label(m):
        left = m[:, 0] < 1.0
        col = (m[:, 0] - (~left)) * np.where(left, n1[1], n2[1])
        row = m[:, 1] * np.where(left, n1[0], n2[0])
        return (np.floor(col) + 100 * np.floor(row) + 10000 * (~left)).astype(np.int64)

    dirichlet = [df.Dirichlet("dirichlet")] + ([df.Dirichlet("right_end")] if held else [])
    return df.ContactProblem(mesh, df.Poisson(source=lambda x: -b1_source(x)),
                             dirichlet=dirichlet,
                             contact=[df.Mortar("contact_right", "contact_left")],
                             decomposition=df.ByFunction(label))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench/seed_fetidp_mortar.md")
    args = parser.parse_args()
    comm = MPI.COMM_WORLD
    out: dict = {"rtol": args.rtol, "ranks": comm.size, "rows": []}
    for k1, k2 in RATIOS:
        for n1, n2 in LAYOUTS:
            for held in (False, True):
                row = {"H1/h1": k1, "H2/h2": k2, "N1": f"{n1[0]}x{n1[1]}",
                       "N2": f"{n2[0]}x{n2[1]}", "held": held,
                       **solve(problem(n1, n2, k1, k2, held), "fetidp", args.rtol, comm)}
                out["rows"].append(row)
                if comm.rank == 0:
                    print(json.dumps(row), flush=True)
    if comm.rank != 0:
        return
    lines = [f"FETI-DP, B1 with mortar contact on non-matching grids, rtol {args.rtol:g} "
             f"(default options), {comm.size} rank(s): primal/dual/corner nodes **F-mults**; "
             "the seed's primal/dual/corners iterations", "",
             "| H₁/h₁ / H₂/h₂ | N₁ / N₂ | B1 (semicoercive) | B1 held (coercive) | "
             "seed, 1st table | seed, 2nd table |", "|---|---|---|---|---|---|"]
    rows = {(r["H1/h1"], r["N1"], r["held"]): r for r in out["rows"]}
    for k1, k2 in RATIOS:
        for n1, n2 in LAYOUTS:
            key = f"{n1[0]}x{n1[1]}"
            seed = ["{}/{}/{} **{}**".format(*t[(k1, n1[1])]) for t in SEED]
            lines.append(f"| {k1} / {k2} | {key} / {n2[0]}x{n2[1]} | "
                         f"{cell(rows[k1, key, False])} | {cell(rows[k1, key, True])} | "
                         f"{seed[0]} | {seed[1]} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    args.out.with_suffix(".json").write_text(json.dumps(out, indent=1))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
