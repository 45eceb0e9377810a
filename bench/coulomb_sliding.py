"""Coulomb friction up to gross sliding: F-multiplications per lateral load, full and half model.

The case of issue 22 as a new user builds it: a steel punch (E = 210, ν = 0.3, radius 1,
height 1, bottom edge filleted with radius 0.25) on an aluminium block (E = 70, ν = 0.33,
4 × 4 × 1.5, clamped at its base), :func:`dolfinx_feti.io.meshes_occ.punch_on_block`, mortar
contact (slave: the punch), Coulomb 𝓕 = 0.3. The punch floats: its top carries the traction
(k 𝓕 p, 0, −p), p = 0.1, so the lateral force is k·𝓕N; only contact and friction hold it. The
half model (y >= 0, symmetry plane y = 0 through the contact zone, u_y = 0 there) has the same
load. For each k the table gives the F-multiplications of the whole solve, their multiple of
the frictionless solve of the normal load alone (k = 0), the Coulomb fixed-point steps, the
F-multiplications of each step, the Coulomb residual max|g − 𝓕λ_N|/max λ (``report.kkt``) and
the seconds (a shared machine: indicative only).

With ``--tresca G`` the friction is Tresca with the traction bound G instead (no fixed point:
the same QP in the full and the half model, which isolates what the symmetry plane costs).

Run: ``python bench/coulomb_sliding.py`` (``--help``; solver options pass through:
``-feti_mprgp_reuse 160``); writes ``output/bench/coulomb_sliding.md``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from mpi4py import MPI

import dolfinx_feti as df
import problems as P  # bench/problems.py (the script's folder is on sys.path)
from dolfinx_feti.io.meshes_occ import punch_on_block

ROOT = Path(__file__).resolve().parent.parent
PRESSURE, MU = 0.1, 0.3


def problem(mesh, ratio: float, half: bool, parts: int, friction) -> df.ContactProblem:
    """The punch pressed by p and pushed sideways by ratio·𝓕·p."""
    dirichlet = [df.Dirichlet("bottom")]
    if half:
        dirichlet.append(df.Dirichlet("symmetry", components=(1,)))
    return df.ContactProblem(
        mesh, df.Elasticity({"punch": 210.0, "block": 70.0}, {"punch": 0.3, "block": 0.33},
                            tractions={"load": (ratio * MU * PRESSURE, 0.0, -PRESSURE)}),
        dirichlet=dirichlet,
        contact=[df.Mortar("punch_contact", "block_contact", friction=friction)],
        decomposition=df.Parts(parts))


def main() -> None:
    """Solve the frictionless reference and each lateral load; write the table."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--ratios", default="0.5,0.6,0.7,0.9,0.99",
                        help="lateral load / 𝓕N, comma-separated")
    parser.add_argument("--models", default="full,half")
    parser.add_argument("--h-punch", type=float, default=0.15)
    parser.add_argument("--h-block", type=float, default=0.25)
    parser.add_argument("--parts", type=int, default=4)
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--max-it", type=int, default=100000)
    parser.add_argument("--rho", type=float, default=None, help="SMALBE's smalbe_rho")
    parser.add_argument("--rho-growth", type=float, default=None,
                        help="SMALBE's smalbe_rho_growth (default: none, ρ fixed)")
    parser.add_argument("--acceleration", default=None,
                        help="SMALBE's smalbe_acceleration (default: the solver's)")
    parser.add_argument("--tresca", type=float, default=None,
                        help="Tresca bound (a traction) instead of Coulomb")
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench/coulomb_sliding.md")
    args, feti = P.parse_with_feti_options(parser)  # e.g. -feti_mprgp_reuse 160
    comm = MPI.COMM_WORLD
    lines = [f"Punch on block, mortar, Coulomb {MU}, Parts({args.parts}), rtol {args.rtol}, "
             f"h = {args.h_punch}/{args.h_block}, {comm.size} rank(s)", "",
             "| model | k = Q/(𝓕N) | F-mults | × frictionless | fixed-point steps | "
             "F-mults per step | converged | Coulomb residual | stick / slip nodes | s |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for model in args.models.split(","):
        half = model == "half"
        mesh = df.build_mesh(punch_on_block, h_punch=args.h_punch, h_block=args.h_block,
                             half=half, comm=comm)
        ref = df.solve(problem(mesh, 0.0, half, args.parts, None), rtol=args.rtol, comm=comm,
                       options=feti)
        base = ref.report.hessian_mults
        lines.append(f"| {model} | frictionless | {base} | 1 | – | – | "
                     f"{ref.report.converged} | – | – | – |")
        for ratio in (float(v) for v in args.ratios.split(",")):
            t0 = time.perf_counter()
            friction = df.Coulomb(MU) if args.tresca is None else df.Tresca(args.tresca)
            sol = df.solve(problem(mesh, ratio, half, args.parts, friction),
                           rtol=args.rtol, max_it=args.max_it, smalbe_rho=args.rho,
                           smalbe_rho_growth=args.rho_growth,
                           smalbe_acceleration=args.acceleration, comm=comm, options=feti)
            dt = time.perf_counter() - t0
            rep = sol.report
            fr = rep.extra["friction"]
            per_step = "/".join(str(s["hessian_mults"]) for s in fr.get("steps", []))
            state = sol.contact.state
            lines.append(
                f"| {model} | {ratio} | {rep.hessian_mults} | {rep.hessian_mults / base:.0f} | "
                f"{fr.get('fixed_point_steps', '–')} | {per_step or '–'} | {rep.converged} | "
                f"{rep.kkt.get('coulomb_bound', float('nan')):.1e} | "
                f"{int((state == 1).sum())} / {int((state == 2).sum())} | {dt:.0f} |")
            if comm.rank == 0:
                print(lines[-1], flush=True)
    if comm.rank == 0:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text("\n".join(lines) + "\n")
        print("\n".join(lines))


if __name__ == "__main__":
    main()
