"""What ``method="auto"`` is derived from: every method on a range of problems.

Problems with and without floating bodies, in 2D and 3D, with few and many subdomains.

Each row: the problem, whether some body floats (rigid motions its Dirichlet conditions leave
free), the number of subdomains, and per method (TFETI, FETI-1, FETI-DP; default options) the
F-multiplications and the total time of ``df.solve`` (setup included: FETI-DP's coarse problem
costs more to build). The rule in :func:`dolfinx_feti.setup.stages.choose_method` and
docs/solvers.md
reads this table.

Run: ``python bench/method_choice.py`` (~1 min on an idle machine). Writes
``output/bench/method_choice.md`` and ``.json`` (``method_choice_volume.*`` with
``--balance volume``). ``--balance volume`` cuts the ``Parts`` cases by equal volumes instead of
equal cell counts (the graded 2D Hertz and sphere meshes change; the others do not);
``--cases TEXT`` runs only the cases whose name contains TEXT; ``--levels H1,H3`` adds the graded
meshes of docs/peers.md, each cut into Parts(4) and Parts(16).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes

sys.path.insert(0, str(Path(__file__).resolve().parent / "peers"))
import common as C  # noqa: E402  (bench/peers/common.py)
import friction_scaling as fs  # noqa: E402

import problems as P  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
METHODS = ("tfeti", "feti1", "fetidp")


def b4(n: int, H: float | None, friction=None) -> df.ContactProblem:
    """B4 (block sheared on a foundation, both held: no floating body).

    H×H grid of subdomains; None: one subdomain per body.
    """
    return df.ContactProblem(
        df.build_mesh(meshes.tresca2d, n=n), df.Elasticity(fs.E, fs.NU),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=fs.SHIFT)],
        contact=[df.NodeToNode("block_bottom", "foundation_top", friction=friction)],
        decomposition=df.ByTags() if H is None else fs.grid(H))


#: name → (floats?, builder(balance)). Sizes that solve in seconds. ``balance`` is what
#: ``Parts`` makes equal (``"cells"`` or ``"volume"``); the grid and ByTags cases ignore it.
CASES = {
    "B1, H = 1/4, H/h = 16": (True, lambda b: P.b1(64, 1 / 4)),
    "B1, H = 1/8, H/h = 16": (True, lambda b: P.b1(128, 1 / 8)),
    "B1 held, H = 1/4, H/h = 16": (False, lambda b: P.b1_held(64, 1 / 4)),
    "B1 held, H = 1/8, H/h = 16": (False, lambda b: P.b1_held(128, 1 / 8)),
    "2D Hertz, Parts(4)": (True, lambda b: P.hertz2d(decomposition=df.Parts(4, balance=b))),
    "2D Hertz, Parts(16)": (True, lambda b: P.hertz2d(decomposition=df.Parts(16, balance=b))),
    "B4 frictionless, H = 1/4, H/h = 8": (False, lambda b: b4(32, 1 / 4)),
    "B4 Tresca, H = 1/4, H/h = 8": (False, lambda b: b4(32, 1 / 4, df.Tresca(0.1))),
    "3D blocks, Parts(8)": (True, lambda b: P.blocks3d(
        8, sides=True, decomposition=df.Parts(8, balance=b))),
    "3D blocks, no sides, Parts(8)": (True, lambda b: P.blocks3d(
        8, sides=False, decomposition=df.Parts(8, balance=b))),
    "3D blocks, ByTags": (True, lambda b: P.blocks3d(8, 8, sides=True,
                                                      decomposition=df.ByTags())),
    "B1, ByTags": (True, lambda b: P.b1(64, None)),
    "2D Hertz, ByTags": (True, lambda b: P.hertz2d(decomposition=df.ByTags())),
    "B4 Tresca, ByTags": (False, lambda b: b4(32, None, df.Tresca(0.1))),
    "rigid sphere S1, Parts(4)": (False, lambda b: C.sphere_problem("S1", 4, balance=b)),
    "rigid sphere S1, Parts(16)": (False, lambda b: C.sphere_problem("S1", 16, balance=b)),
}


def level_cases(levels: list[str]) -> dict:
    """Cases on the graded meshes of docs/peers.md: 2D Hertz H1–H3, rigid sphere S1–S4."""
    cases = {}
    for level in levels:
        hertz = level.startswith("H")
        for parts in (4, 16):
            name = f"{'2D Hertz' if hertz else 'rigid sphere'} {level}, Parts({parts})"
            make = C.hertz_problem if hertz else C.sphere_problem
            cases[name] = (hertz, lambda b, make=make, level=level, parts=parts:
                           make(level, parts, b))
    return cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--balance", choices=("cells", "volume"), default="cells",
                        help="what Parts(n) makes equal in the Parts cases")
    parser.add_argument("--cases", default="",
                        help="run only the cases whose name contains this text")
    parser.add_argument("--levels", default="",
                        help="comma-separated graded meshes of docs/peers.md (H1-H3, S1-S4) "
                             "to add, each with Parts(4) and Parts(16)")
    parser.add_argument("--out", type=Path, default=None,
                        help="output/bench/method_choice.md (method_choice_volume.md with "
                             "--balance volume) if not given")
    args = parser.parse_args()
    if args.out is None:
        suffix = "" if args.balance == "cells" else "_volume"
        args.out = ROOT / f"output/bench/method_choice{suffix}.md"
    comm = MPI.COMM_WORLD
    rows = []
    cases = {**CASES, **level_cases([x for x in args.levels.split(",") if x])}
    for name, (floats, build) in cases.items():
        if args.cases not in name:
            continue
        row = {"case": name, "floats": floats, "balance": args.balance}
        for method in METHODS:
            problem = build(args.balance)  # outside the timer: the first build makes the mesh
            t0 = time.perf_counter()
            sol = df.solve(problem, comm=comm, rtol=args.rtol, method=method, max_it=20000)
            t = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
            r = sol.report
            row["subdomains"] = r.sizes["subdomains"]
            row["primal"] = r.sizes["primal"]
            row[method] = {"F_mults": r.hessian_mults, "time": round(t, 2), "solver": r.solver,
                           "converged": r.converged}
        rows.append(row)
        if comm.rank == 0:
            print(json.dumps(row), flush=True)
    if comm.rank != 0:
        return
    lines = [f"Every method, default options, rtol {args.rtol:g}, {comm.size} rank(s), "
             f"Parts(n, balance={args.balance!r}): "
             "F-mults / total time [s] (setup included); the fewest F-mults in bold", "",
             "| case | floating body | subdomains | primal | TFETI | FETI-1 | FETI-DP |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        best = min(r[m]["F_mults"] for m in METHODS)
        cells = []
        for m in METHODS:
            c = f"{r[m]['F_mults']} / {r[m]['time']}"
            cells.append((f"**{c}**" if r[m]["F_mults"] == best else c)
                         + ("" if r[m]["converged"] else " (not converged)"))
        lines.append(f"| {r['case']} | {'yes' if r['floats'] else 'no'} | {r['subdomains']} | "
                     f"{r['primal']} | " + " | ".join(cells) + " |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n")
    args.out.with_suffix(".json").write_text(json.dumps(rows, indent=1))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
