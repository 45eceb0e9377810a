"""The cost of a Newton step of large-deformation contact against one linear contact solve.

The rubber cylinder of demos/demo_rubber_cylinder.py (quarter model, neo-Hookean E = 1,
ν = 0.3, frictionless rigid plate rising by δ): per load step of the Newton path, the wall
time per Newton iteration (reassembly of the tangent and the residual, refactorization, the
contact QP, the line search's residual assemblies) and the F-multiplications of its QP; against
one linear contact solve (df.Elasticity, the same mesh, decomposition, method and plate travel
δ/steps): its set-up and its solve. Run:

    OMP_NUM_THREADS=1 python bench/newton_cost.py [--h 0.005] [--h-far 0.03] [--parts 4] [--steps 4]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io.meshes_rubber import quarter_disk

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=float, default=0.005)
parser.add_argument("--h-far", type=float, default=0.03)
parser.add_argument("--parts", type=int, default=4)
parser.add_argument("--steps", type=int, default=4)
parser.add_argument("--delta", type=float, default=0.2)
args = parser.parse_args()
comm = MPI.COMM_WORLD
R = 1.0
mesh = df.build_mesh(quarter_disk, R=R, h_contact=args.h, h_far=args.h_far, comm=comm, gdim=2)


def problem(material, t):
    return df.ContactProblem(
        mesh, material,
        dirichlet=[df.Dirichlet("top", 0.0, components=[1]),
                   df.Dirichlet("axis", 0.0, components=[0])],
        contact=[df.RigidObstacle("arc", df.Plane((0.0, -R + t), (0.0, 1.0)))],
        decomposition=df.Parts(args.parts))


times = args.delta * np.arange(1, args.steps + 1) / args.steps
wall = time.perf_counter()
sols = df.solve_path(lambda t: problem(df.NeoHookean(1.0, 0.3), t), times, comm=comm,
                     rtol=1e-10, newton_rtol=1e-9, progress=False)
wall = comm.allreduce(time.perf_counter() - wall, op=MPI.MAX)

t0 = time.perf_counter()
solver = df.FetiSolver(problem(df.Elasticity(1.0, 0.3), times[0]), comm=comm, rtol=1e-10,
                       method="fetidp")
t1 = time.perf_counter()
lin = solver.solve()
t2 = time.perf_counter()
solver.destroy()
setup = comm.allreduce(t1 - t0, op=MPI.MAX)
solve = comm.allreduce(t2 - t1, op=MPI.MAX)

if comm.rank == 0:
    print(f"mesh: {mesh.num_nodes} nodes, {lin.report.sizes['primal']} primal dofs, "
          f"{args.parts} subdomains, {comm.size} rank(s); Newton path of {args.steps} steps "
          f"to δ = {args.delta} R: {wall:.2f} s, "
          f"{sum(s.report.hessian_mults for s in sols)} F-multiplications")
    print("| step | Newton iterations | s per iteration | F-mults per iteration |")
    print("|---|---|---|---|")
    for k, s in enumerate(sols):
        h = s.report.extra["newton"]
        print(f"| {k + 1} | {len(h)} | {np.mean([x['seconds'] for x in h]):.3f} | "
              f"{np.mean([x['hessian_mults'] for x in h]):.0f} |")
    print(f"linear contact solve (Elasticity, same mesh and δ/steps): set-up {setup:.3f} s, "
          f"solve {solve:.3f} s, {lin.report.hessian_mults} F-mults")
