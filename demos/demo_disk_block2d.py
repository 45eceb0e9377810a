# # A disk on a block (2D Hertz), meshed independently: mortar contact
#
# The problem of `demo_hertz2d.py` — an elastic disk of radius $R = 8$ pressed by a line load
# $P = 10$ onto an elastic block, both with $E = 200$, $\nu = 0.3$, plane strain — but built
# the way a gmsh user naturally builds it: the disk and the block are two OCC surfaces, each
# meshed on its own with its own element size, so no node of the disk meets a node of the
# block. `df.Mortar` couples them. Hertz's theory gives the half-width, the peak pressure and
# the profile
#
# $$ a = 2\sqrt{\frac{R P}{\pi E^*}}, \qquad p_0 = \sqrt{\frac{P E^*}{\pi R}}, \qquad
#    p(x) = p_0 \sqrt{1 - x^2/a^2}, \qquad
#    \frac{1}{E^*} = \frac{1-\nu_1^2}{E_1} + \frac{1-\nu_2^2}{E_2}. $$
#
# Run it with `python demos/demo_disk_block2d.py` (or under `mpirun -n 2`); `--h` sets the
# disk's element size at the contact, `--help` lists the options.

# +
import argparse
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti import meshes_occ

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=float, default=0.05, help="element size of the disk at the contact")
parser.add_argument("--ratio", type=float, default=1.7,
                    help="element size of the block at the contact / that of the disk")
parser.add_argument("--parts", type=int, default=2, help="subdomains per body")
parser.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance of the solver")
parser.add_argument("--out", type=Path, default=Path("output/disk_block2d"), help="output folder")
parser.add_argument("--json", type=Path, default=None,
                    help="write the solve report (with the Hertz comparison) here")
args, _ = parser.parse_known_args()  # leave -feti_* options to PETSc
comm = MPI.COMM_WORLD
# -

# ## The geometry
#
# `dolfinx_feti.meshes_occ.disk_on_block` cuts a quarter of the disk (the half model is
# symmetric about $x = 0$), adds the half block $[0, 10] \times [-20, 0]$ as a second OCC
# surface, not fragmented against the disk, sizes the mesh near the contact point ($h$ on
# the disk, `ratio` $\cdot h$ on the block) and meshes both with one `generate(2)`. The
# candidate contact surfaces are the whole arc of the disk (`disk_contact`) and the whole
# top of the block (`block_contact`).

# +
R, P, E, nu = 8.0, 10.0, 200.0, 0.3
t0 = time.perf_counter()
mesh = df.build_mesh(meshes_occ.disk_on_block, h_contact_disk=args.h,
                     h_contact_block=args.ratio * args.h, R=R, comm=comm)
t_mesh = time.perf_counter() - t0
# -

# ## The problem
#
# Half of $P$ acts on the flat top of the quarter disk (length $R$); the block is clamped at
# the bottom and both bodies are symmetric about $x = 0$. The disk, with the finer mesh, is
# the slave side of the mortar contact.

problem = df.ContactProblem(
    mesh,
    df.Elasticity(E, nu, tractions={"load": (0.0, -P / 2 / R)}),
    dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
    contact=[df.Mortar(slave="disk_contact", master="block_contact")],
    decomposition=df.Parts(args.parts),
)

# ## The solve

solution = df.solve(problem, comm=comm, rtol=args.rtol)
report = solution.report
search = report.extra["mortar"][0]  # what the contact search found, and the post-solve check

# ## Comparison with Hertz
#
# The pressure at a slave node is its nodal force divided by its lumped length. The computed
# half-width lies between the last node in contact and the first one out of contact; we
# report their mean. A Hertz profile fitted to the nodal pressures ($p^2$ is linear in $x^2$)
# gives a second estimate of $a$ and $p_0$ that uses every node in contact.

# +
E_star = 1.0 / (2 * (1 - nu**2) / E)
a = 2 * np.sqrt(R * P / (np.pi * E_star))
p0 = np.sqrt(P * E_star / (np.pi * R))
c = solution.contact
order = np.argsort(c.x[:, 0])
x, p = c.x[order, 0], c.pressure[order]
active = p > 1e-8 * p.max()
x_in = x[active].max()
x_out = x[~active & (x > x_in)].min()
a_h = 0.5 * (x_in + x_out)
peak_err = (p.max() - p0) / p0
hertz_p = p0 * np.sqrt(np.maximum(1 - x**2 / a**2, 0.0))
rms_err = np.sqrt(np.mean((p - hertz_p)[active | (x < a)] ** 2)) / p0
slope, p0_sq = np.polyfit(x[active] ** 2, p[active] ** 2, 1)
p0_fit, a_fit = np.sqrt(p0_sq), np.sqrt(-p0_sq / slope)
force = solution.total_contact_force
force_err = abs(force[1] - P / 2) / (P / 2)  # the load face is straight: no meshing error
h_block = args.ratio * args.h
# -

# ## Output: XDMF for ParaView, a plot, a JSON report

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
    ax.plot(x, p, "o", ms=3, label=f"TFETI + mortar, h = {args.h:g} / {h_block:g}")
    ax.set_xlim(0, 2 * a)
    ax.set_xlabel("x")
    ax.set_ylabel("contact pressure")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out / "disk_block2d_pressure.png", dpi=120)
report.extra["hertz"] = {
    "h_disk": args.h, "h_block": h_block, "nodes": int(mesh.x.shape[0]), "load": P,
    "a": a, "p0": p0, "a_h": a_h, "x_in": x_in, "x_out": x_out, "peak": float(p.max()),
    "peak_error": peak_err, "rms_error": rms_err, "p0_fit": p0_fit, "a_fit": a_fit,
    "contact_force": float(force[1]), "force_error": force_err, "time_mesh": t_mesh,
    "time_solve": report.timings["total"]}
if args.json:
    report.save_json(args.json)
# -

# ## Summary

if comm.rank == 0:
    print(report.summary())
    print(f"mesh: {mesh.x.shape[0]} nodes, h = {args.h:g} (disk) / {h_block:g} (block) at the "
          f"contact; search: {search['rows']} rows, {search['facet_pairs']} facet pairs, "
          f"{search['uncoupled_slave_nodes']} slave nodes out of range, "
          f"{search['active_rows']} active")
    print(f"Hertz: a = {a:.4f}, p0 = {p0:.4f}")
    print(f"computed: a_h = {a_h:.4f} (error {a_h - a:+.4f}; last node in contact at "
          f"{x_in:.4f}, next out at {x_out:.4f}), peak = {p.max():.4f} "
          f"(error {100 * peak_err:+.2f} %)")
    print(f"Hertz profile fitted to the nodal pressures: a = {a_fit:.4f} "
          f"(error {100 * (a_fit - a) / a:+.2f} %), p0 = {p0_fit:.4f} "
          f"(error {100 * (p0_fit - p0) / p0:+.2f} %); rms of p - p_Hertz: "
          f"{100 * rms_err:.2f} % of p0")
    print(f"total contact force {force[1]:.8f} vs applied load {P / 2:.8f} (half): relative "
          f"error {force_err:.1e}; largest penetration {search['max_penetration']:.1e}")
    print(f"time: mesh {t_mesh:.2f} s, solve {report.timings['total']:.2f} s; "
          f"output in {args.out}/")
