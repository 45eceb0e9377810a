"""Friction under Newton in 3D: the cost of the increment QPs, with and without their floor.

A neo-Hookean unit cube (E = 10, ν = 0.3, tetrahedra of size ``h``, ``Parts(2)``, FETI-DP) is
pressed 10 % onto a rigid plane with Tresca friction (g = 0.3) and its top slid by 0.1 along
x. Per step: Newton iterations, F-multiplications per iteration, the QPs' stop reasons and the
seconds. ``--no-floor`` runs it as before the fix (newton.U_FLOOR = 0: the increment's KKT test
against ‖Δu‖∞ alone; kkt_stop.ROUND_OFF = 0: bounds below the gradient's round-off asked for),
with ``--max-it`` Newton iterations per step and no cut-back, to show where the time went.
Run:

    OMP_NUM_THREADS=1 PYTHONPATH=$PWD python bench/newton_friction3d.py [--no-floor] [--h 0.5]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))

from element_models import box  # noqa: E402

import dolfinx_feti as df  # noqa: E402
from dolfinx_feti.drivers import kkt_stop, newton  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--h", type=float, default=0.5)
    ap.add_argument("--no-floor", action="store_true")
    ap.add_argument("--max-it", type=int, default=6)
    args = ap.parse_args()
    if args.no_floor:
        newton.U_FLOOR, kkt_stop.ROUND_OFF = 0.0, 0.0
    cube = df.build_mesh(box, h=args.h, gdim=3)

    def problem(t):
        return df.ContactProblem(
            cube, df.NeoHookean(10.0, 0.3),
            dirichlet=[df.Dirichlet("z1", (max(t - 1, 0) * 0.1, 0.0, -0.1 * min(t, 1)))],
            contact=[df.RigidObstacle("z0", df.Plane((0, 0, 0), (0, 0, 1)),
                                      friction=df.Tresca(0.3))],
            decomposition=df.Parts(2))

    t0 = time.perf_counter()
    sols = df.solve_path(problem, [0.5, 1.0, 2.0], rtol=1e-10, newton_rtol=1e-9,
                         method="fetidp", progress=False, newton_max_it=args.max_it,
                         max_cutbacks=0)
    total = time.perf_counter() - t0
    print(f"floor {'off' if args.no_floor else 'on'}, h = {args.h}, "
          f"{sols[0].u_vec.getSize()} primal dofs")
    print("| t | converged | Newton its | F-mults per iteration | QP stops | seconds |")
    print("|---|---|---|---|---|---|")
    for s in sols:
        h = s.report.extra["newton"]
        print(f"| {s.report.extra['time']:g} | {s.report.converged} | {len(h)} | "
              f"{', '.join(str(x['hessian_mults']) for x in h)} | "
              f"{', '.join(x['qp_reason'] for x in h)} | {sum(x['seconds'] for x in h):.1f} |")
    print(f"total {total:.1f} s")


if __name__ == "__main__":
    main()
