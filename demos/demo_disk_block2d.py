# # Hertz 2D on independent meshes: how the mortar solution converges
#
# The problem of `demo_hertz2d.py` — an elastic disk of radius $R = 8$ pressed by a line load
# $P = 10$ onto an elastic block, both with $E = 200$, $\nu = 0.3$, plane strain, each body
# meshed on its own (OCC) and coupled by `df.Mortar` — solved on three meshes whose element
# sizes at the contact halve from one to the next, the block's 1.7 times the disk's (so no
# node of the one surface meets a node of the other). Hertz's half-width, peak pressure and
# profile
#
# $$ a = 2\sqrt{\frac{R P}{\pi E^*}}, \qquad p_0 = \sqrt{\frac{P E^*}{\pi R}}, \qquad
#    p(x) = p_0 \sqrt{1 - x^2/a^2}, \qquad
#    \frac{1}{E^*} = \frac{1-\nu_1^2}{E_1} + \frac{1-\nu_2^2}{E_2} $$
#
# are the reference; the bodies are finite (a disk, a 20 × 20 block), so a few tenths of a
# per cent remain at h → 0.
#
# Run it with `python demos/demo_disk_block2d.py` (or under `mpirun -n 2`); `--h` lists the
# disk's element sizes, `--help` the other options.

# +
import argparse
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes_occ
from dolfinx_feti.results.postprocess import pressure_profile

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=float, nargs="+", default=[0.2, 0.1, 0.05],
                    help="element sizes of the disk at the contact, coarse to fine")
parser.add_argument("--ratio", type=float, default=1.7,
                    help="element size of the block at the contact / that of the disk")
parser.add_argument("--parts", type=int, default=2, help="subdomains per body")
parser.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance of the solver")
parser.add_argument("--out", type=Path, default=Path("output/disk_block2d"), help="output folder")
parser.add_argument("--json", type=Path, default=None,
                    help="write the finest solve's report (with the convergence table) here")
args, _ = parser.parse_known_args()  # leave -feti_* options to PETSc
comm = MPI.COMM_WORLD

R, P, E, nu = 8.0, 10.0, 200.0, 0.3
E_star = 1.0 / (2 * (1 - nu**2) / E)
a = 2 * np.sqrt(R * P / (np.pi * E_star))
p0 = np.sqrt(P * E_star / (np.pi * R))
# -

# ## One mesh, one solve
#
# `meshes_occ.disk_on_block` meshes the quarter disk and the half block with one `generate`
# call; the candidate contact surfaces are the whole arc and the whole top of the block. The
# disk (the finer mesh) is the slave side. The pressure at a slave node is its nodal force
# divided by its lumped length. Three estimates come out of the nodal pressures: the peak
# (the largest nodal value), the half-width (midway between the last node in contact and the
# next one out of contact) and a Hertz profile fitted to all nodes in contact ($p^2$ is
# linear in $x^2$), whose $a$ and $p_0$ use every node rather than one.


def solve(h: float) -> tuple[df.Solution, dict]:
    """Mesh at size h, solve, compare with Hertz."""
    t0 = time.perf_counter()
    mesh = df.build_mesh(meshes_occ.disk_on_block, h_contact_disk=h,
                         h_contact_block=args.ratio * h, R=R, comm=comm)
    problem = df.ContactProblem(
        mesh,
        df.Elasticity(E, nu, tractions={"load": (0.0, -P / 2 / R)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.Mortar(slave="disk_contact", master="block_contact")],
        decomposition=df.Parts(args.parts))
    solution = df.solve(problem, comm=comm, rtol=args.rtol)
    x, p = pressure_profile(solution, along="x")
    active = p > 1e-8 * p.max()
    x_in = x[active].max()
    a_h = 0.5 * (x_in + x[~active & (x > x_in)].min())
    slope, p0_sq = np.polyfit(x[active] ** 2, p[active] ** 2, 1)
    hertz_p = p0 * np.sqrt(np.maximum(1 - x**2 / a**2, 0.0))
    report = solution.report
    return solution, {
        "h_disk": h, "h_block": args.ratio * h, "dofs": report.sizes["primal"],
        "rows": report.extra["mortar"][0]["rows"], "peak": float(p.max()),
        "peak_error": float(p.max() / p0 - 1), "a_h": float(a_h), "a_h_error": float(a_h - a),
        "a_fit": float(np.sqrt(-p0_sq / slope)), "p0_fit": float(np.sqrt(p0_sq)),
        "rms_error": float(np.sqrt(np.mean((p - hertz_p)[active | (x < a)] ** 2)) / p0),
        "force_error": float(abs(solution.total_contact_force[1] - P / 2) / (P / 2)),
        "hessian_mults": report.hessian_mults, "time": time.perf_counter() - t0,
        "x": x, "p": p}


# ## Three meshes

results = [solve(h) for h in args.h]
solution, finest = results[-1]
table = [{k: v for k, v in r.items() if k not in ("x", "p")} for _, r in results]

# ## Output: the finest solution in XDMF, a plot of the three profiles, a JSON report

# +
if comm.rank == 0:
    args.out.mkdir(parents=True, exist_ok=True)
solution.write_xdmf(args.out / "disk_block2d.xdmf")
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xs = np.linspace(0, a, 200)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(xs, p0 * np.sqrt(1 - xs**2 / a**2), "k-", label="Hertz")
    for k, (_, r) in enumerate(results):
        ax.plot(r["x"], r["p"], "^so"[k % 3], ms=3,
                label=f"TFETI + mortar, h = {r['h_disk']:g} / {r['h_block']:g}")
    ax.set_xlim(0, 2 * a)
    ax.set_xlabel("x")
    ax.set_ylabel("contact pressure")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out / "disk_block2d_pressure.png", dpi=120)
solution.report.extra["hertz_convergence"] = {"a": a, "p0": p0, "meshes": table}
if args.json:
    solution.report.save_json(args.json)
# -

# ## Summary

if comm.rank == 0:
    print(solution.report.summary())
    print(f"Hertz: a = {a:.4f}, p0 = {p0:.4f}")
    print("| h disk / block | dofs | rows | peak p (error) | a_h (error) | fitted a, p0 "
          "(errors) | rms p - p_Hertz | F-mults | time [s] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in table:
        print(f"| {r['h_disk']:g} / {r['h_block']:g} | {r['dofs']} | {r['rows']} | "
              f"{r['peak']:.4f} ({100 * r['peak_error']:+.2f} %) | "
              f"{r['a_h']:.4f} ({r['a_h_error']:+.4f}) | {r['a_fit']:.4f}, {r['p0_fit']:.4f} "
              f"({100 * (r['a_fit'] / a - 1):+.2f} %, {100 * (r['p0_fit'] / p0 - 1):+.2f} %) | "
              f"{100 * r['rms_error']:.2f} % | {r['hessian_mults']} | {r['time']:.2f} |")
    print(f"total contact force vs the load, finest mesh: relative error "
          f"{finest['force_error']:.1e}; output in {args.out}/")
