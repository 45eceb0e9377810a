"""How far inside the tolerance a solve stops: contact pressures against a tight solve, per rtol.

The sphere-on-block problem of ``demos/demo_sphere_block3d.py`` (mortar contact, h = 0.1 /
0.17, 2 parts per body) is solved at rtol 1e-6 … 1e-11 and at 1e-12 (the reference), with the
stiffness scaling's merge cap ``feti.precond.MERGE_MAX`` at its default (the mortar contact
group of 579 rows is then split into its node blocks) and raised above the group (Z exact).
For each run: outer and inner iterations, the relative error of the peak nodal pressure, the
largest pressure error relative to the peak, the preconditioner's setup time and the solve
time.

Each run writes its pressures to ``output/bench/stop_accuracy_<ranks>.json``; when the file
of the other rank count (1 or 2) is there, the differences between the two are printed too.

``--trace K`` prints ‖b‖ (split into the rows with a bound and the others) and, for outer
iteration K of the first run, every inner iterate's ‖gᴾ‖, SMALBE's inner threshold
M‖Gλ − e‖ and the stop decision (it wraps ``MPGP.solve`` and reads the stop test's closure:
a measuring aid tied to ``qp/smalbe.py``'s internals).

Run: ``python bench/stop_accuracy.py`` and ``mpirun -n 2 python bench/stop_accuracy.py``
(~1 minute each); ``--h 0.05 --rtols 1e-8`` for a finer mesh; ``--perturb 1e-13`` to see how
far a rounding-size change of the load moves the answer at each rtol.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes_occ

precond = sys.modules["dolfinx_feti.feti.precond"]
ROOT = Path(__file__).resolve().parent.parent
parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--rtols", default="1e-6,1e-7,1e-8,1e-9,1e-10,1e-11")
parser.add_argument("--h", type=float, default=0.1, help="element size of the sphere")
parser.add_argument("--trace", type=int, default=None, help="outer iteration to trace")
parser.add_argument("--perturb", type=float, default=0.0,
                    help="also solve with the load scaled by 1 + this (a rounding-size change) "
                    "and print how far that moves the answer")
parser.add_argument("--caps", default=f"{precond.MERGE_MAX},100000",
                    help="values of MERGE_MAX to compare")
args = parser.parse_args()
comm = MPI.COMM_WORLD

R, F, E, nu = 8.0, 20.0, 200.0, 0.3
mesh = df.build_mesh(meshes_occ.sphere_on_block, h_contact_sphere=args.h,
                     h_contact_block=1.7 * args.h,
                     R=R, comm=comm)


def make_problem(load_factor: float) -> df.ContactProblem:
    """The demo's problem, its load scaled by ``load_factor``."""
    traction = load_factor * F / (np.pi * R**2)
    return df.ContactProblem(
        mesh, df.Elasticity(E, nu, tractions={"load": (0.0, 0.0, -traction)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sym_x", components=[0]),
                   df.Dirichlet("sym_y", components=[1])],
        contact=[df.Mortar(slave="sphere_contact", master="block_contact")],
        decomposition=df.Parts(2))


problem = make_problem(1.0)
perturbed = make_problem(1.0 + args.perturb) if args.perturb else None


def traced(solve, outer: int):
    """``MPGP.solve`` printing the inner iterates of SMALBE's outer iteration ``outer`` (rank 0)."""
    def run(self, qp, x, *, stop=None, **kw):
        if not tracing:
            return solve(self, qp, x, stop=stop, **kw)
        k, tracing[0] = tracing[0], tracing[0] + 1
        if k == 0 and qp.constraints is not None:  # b - Dᵀμ with μ = 0: b, by row kind
            b = qp.b.array_r
            bounded = np.isfinite(qp.constraints.l) | np.isfinite(qp.constraints.u)
            parts = [comm.allreduce(float(b[m] @ b[m])) ** 0.5 for m in (bounded, ~bounded)]
            if comm.rank == 0:
                print(f"    ||b|| = {np.hypot(*parts):.3f}: rows with a bound "
                      f"{parts[0]:.3f}, the others {parts[1]:.3f}")
        if k != outer or stop is None:
            return solve(self, qp, x, stop=stop, **kw)
        cells = dict(zip(stop.__code__.co_freevars,
                         (c.cell_contents for c in stop.__closure__), strict=True))
        D, M_k, it = cells["D"], cells["M_k"], [0]

        def st(gP, xv, g):
            dx = float(np.linalg.norm(D.mult(xv)))
            dec = stop(gP, xv, g)
            if comm.rank == 0:
                print(f"    outer {k} inner {it[0]:3d}: ||g^P|| {gP:.11e}  M||G lambda - e|| "
                      f"{M_k * dx:.6e}  stop {bool(dec)}")
            it[0] += 1
            return dec
        return solve(self, qp, x, stop=st, **kw)
    return run


tracing: list[int] = []  # [number of inner solves so far] while the traced solve runs
if args.trace is not None:
    MPGP = sys.modules["dolfinx_feti.qp.mpgp"].MPGP
    MPGP.solve = traced(MPGP.solve, args.trace)


largest_block = [0]  # the most entries in a row of Z in the last setup: its largest block
_init = precond._DualScaling.__init__


def _measured_init(self, *a, **kw) -> None:
    _init(self, *a, **kw)
    rows = np.diff(self.Z.getValuesCSR()[0])
    largest_block[0] = comm.allreduce(int(rows.max()) if rows.size else 0, op=MPI.MAX)


precond._DualScaling.__init__ = _measured_init


def pressures(rtol: float, pb: df.ContactProblem = problem) -> tuple[np.ndarray, df.Report]:
    """The nodal contact pressures (sorted by coordinates: rank-independent) and the report."""
    sol = df.solve(pb, comm=comm, rtol=rtol)
    c = sol.contact
    return c.pressure[np.lexsort(c.x.T[::-1])], sol.report


default = precond.MERGE_MAX
rtols = [float(r) for r in args.rtols.split(",")]
out: dict[str, dict] = {}
caps = [int(c) for c in args.caps.split(",")]
for cap in caps:
    precond.MERGE_MAX = cap
    ref, _ = pressures(1e-12)
    out[str(cap)] = {"1e-12": ref.tolist()}
    if comm.rank == 0:
        print(f"MERGE_MAX = {cap}{' (default)' if cap == default else ''}, {comm.size} rank(s); "
              f"the largest block of Z has {largest_block[0]} rows")
        print("  rtol   outer inner  peak error  max |p - p_ref| / max p_ref  precond setup [s]"
              "  solve [s]")
    for i, rtol in enumerate(rtols):
        if args.trace is not None and i == 0 and cap == caps[0]:
            tracing[:] = [0]  # the first run of the first cap
        p, rep = pressures(rtol)
        tracing.clear()
        out[str(cap)][f"{rtol:g}"] = p.tolist()
        if comm.rank == 0:
            print(f"  {rtol:5.0e} {rep.outer_iterations:5d} {rep.iterations:5d}  "
                  f"{abs(p.max() / ref.max() - 1):10.1e}  {abs(p - ref).max() / ref.max():27.1e}"
                  f"  {rep.timings['preconditioner']:17.3f}  {rep.timings['total']:9.2f}")
        if perturbed is not None:
            q, rq = pressures(rtol, perturbed)
            if comm.rank == 0:
                print(f"         load x (1 + {args.perturb:g}): {rq.outer_iterations} outer, "
                      f"{rq.iterations} inner; peak moved by {abs(q.max() / p.max() - 1):.1e}, "
                      f"max by {abs(q - p).max() / ref.max():.1e}")
precond.MERGE_MAX = default

if comm.rank == 0:
    folder = ROOT / "output" / "bench"
    folder.mkdir(parents=True, exist_ok=True)
    mine = folder / f"stop_accuracy_{comm.size}.json"
    mine.write_text(json.dumps({"h": args.h, "runs": out}))
    other = folder / f"stop_accuracy_{2 if comm.size == 1 else 1}.json"
    theirs = json.loads(other.read_text()) if other.exists() else {}
    if theirs.get("h") == args.h:  # the same mesh
        theirs = theirs["runs"]
        print(f"1 rank vs 2 ranks ({other.name}): peak difference / max difference, relative")
        for cap, runs in out.items():
            for key, p in runs.items():
                if key in theirs.get(cap, {}):
                    a, b = np.array(p), np.array(theirs[cap][key])
                    print(f"  MERGE_MAX {cap:>6}  rtol {key:>5}: {abs(a.max() / b.max() - 1):.1e}"
                          f" / {abs(a - b).max() / b.max():.1e}")
