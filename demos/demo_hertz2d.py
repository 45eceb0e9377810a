# # Hertz contact of a disk on a block (2D, plane strain)
#
# An elastic disk of radius $R = 8$ is pressed by a line load $P = 10$ (per unit thickness)
# onto an elastic block, both with $E = 200$, $\nu = 0.3$. Hertz's theory predicts a contact
# half-width and a peak pressure
#
# $$ a = 2\sqrt{\frac{R P}{\pi E^*}}, \qquad p_0 = \sqrt{\frac{P E^*}{\pi R}}, \qquad
#    \frac{1}{E^*} = \frac{1-\nu_1^2}{E_1} + \frac{1-\nu_2^2}{E_2}, $$
#
# and the pressure profile $p(x) = p_0 \sqrt{1 - x^2/a^2}$. The two bodies are meshed the way a
# gmsh user meshes them: each is its own OCC surface, one `generate` call, no matching nodes.
# Mortar contact couples the non-matching surfaces. We solve the half model (symmetry about
# $x = 0$) with Total FETI and SMALBE/MPRGP, compare with Hertz, write the displacement and the
# contact pressure to XDMF and plot the pressure.
#
# Run it with `python demos/demo_hertz2d.py` (or under `mpirun -n 2`); `--help` lists options.

# +
import argparse
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes_occ

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=float, default=0.05, help="disk's element size near the contact")
parser.add_argument("--h-block", type=float, default=None,
                    help="block's element size near the contact (default: the disk's)")
parser.add_argument("--parts", type=int, default=2, help="subdomains per body")
parser.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance of the solver")
parser.add_argument("--out", type=Path, default=Path("output/hertz2d"), help="output folder")
parser.add_argument("--json", type=Path, default=None, help="write the solve report here")
parser.add_argument("--mesh", type=Path, default=None,
                    help="read this gmsh file instead of building the mesh (the same mesh "
                    "whatever the installed gmsh; meshes/disk_on_block.msh is the one of --h 0.1)")
args, _ = parser.parse_known_args()  # -feti_* options: read by df.solve(options=sys.argv)
comm = MPI.COMM_WORLD
# -

# ## The geometry
#
# `dolfinx_feti.io.meshes_occ.disk_on_block` builds the quarter disk and the half block as two
# OCC surfaces, each with its own element size near the contact, and meshes them with one
# `generate` call: the nodes on the arc and on the block's top do not match. Physical groups
# name the bodies (`disk`, `block`) and the boundary parts (`disk_contact` = the whole arc,
# `block_contact` = the whole top of the block, `load`, `symmetry`, `bottom`). `build_mesh`
# runs the generator on rank 0; `--mesh FILE` reads a file instead (`read_gmsh`): gmsh
# versions mesh the geometry slightly differently, a file is the same mesh. With
# `replicate=False` the mesh stays on rank 0 (the other ranks know its names and sizes), and
# the solve hands every rank only its share: the cells, dof points and rows of its own
# subdomains. Nothing below reads the mesh's arrays, so no rank needs the whole mesh.

# +
R, P, E, nu = 8.0, 10.0, 200.0, 0.3
t0 = time.perf_counter()
if args.mesh is None:
    mesh = df.build_mesh(meshes_occ.disk_on_block, h_contact_disk=args.h,
                         h_contact_block=args.h_block or args.h, R=R, comm=comm,
                         replicate=False)
else:
    mesh = df.read_gmsh(args.mesh, comm=comm, replicate=False)
t_mesh = time.perf_counter() - t0
# -

# ## The problem
#
# The load acts on the flat top of the quarter disk: half of $P$ on the half model, spread over
# its length $R$. The block is clamped at the bottom; both bodies are symmetric about $x = 0$
# ($u_x = 0$ there). `df.Mortar` searches the pairs of facets that face each other on the two
# candidate surfaces (here the whole arc and the whole top of the block) and integrates the
# dual (biorthogonal) multiplier basis of the slave side (the disk) against the master's shape
# functions over their overlaps: one non-penetration row and one bound per slave node in
# reach, with the initial gap from the geometry. After the solve the report says how many slave
# nodes were out of reach, and warns if either surface penetrates the other.

problem = df.ContactProblem(
    mesh,
    df.Elasticity(E, nu, tractions={"load": (0.0, -P / 2 / R)}),
    dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
    contact=[df.Mortar(slave="disk_contact", master="block_contact")],
    decomposition=df.Parts(args.parts),
)

# ## The solve
#
# Every subdomain floats (Total FETI); the dual problem has bound constraints (contact) and
# equality constraints (the natural coarse space), so SMALBE-M with inner MPRGP is used.

solution = df.solve(problem, comm=comm, options=sys.argv, rtol=args.rtol)
report = solution.report

# ## Comparison with Hertz
#
# The mortar multiplier of a slave node is its contact pressure (the nodal force divided by
# the node's lumped length). The computed
# half-width is taken between the last node in contact and the first one out of contact.

# +
E_star = 1.0 / (2 * (1 - nu**2) / E)
a = 2 * np.sqrt(R * P / (np.pi * E_star))
p0 = np.sqrt(P * E_star / (np.pi * R))
c = solution.contact
order = np.argsort(c.x[:, 0])
x, p = c.x[order, 0], c.pressure[order]
in_contact = p > 1e-8 * p.max()
a_h = 0.5 * (x[in_contact].max() + x[~in_contact & (x > x[in_contact].max())].min())
peak_err = (p.max() - p0) / p0
force_err = abs(solution.total_contact_force[1] - P / 2) / (P / 2)
# -

# ## Output: XDMF for ParaView, a plot, a JSON report

# +
args.out.mkdir(parents=True, exist_ok=True) if comm.rank == 0 else None
solution.write_xdmf(args.out / "hertz2d.xdmf")
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xs = np.linspace(0, a, 200)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(xs, p0 * np.sqrt(1 - xs**2 / a**2), "k-", label="Hertz")
    ax.plot(x, p, "o", ms=3, label=f"TFETI + mortar, h = {args.h}")
    ax.set_xlim(0, min(2 * a, x.max()))
    ax.set_xlabel("x")
    ax.set_ylabel("contact pressure")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out / "hertz2d_pressure.png", dpi=120)
if args.json:
    report.save_json(args.json)
# -

# ## Summary

if comm.rank == 0:
    print(report.summary())
    print(f"Hertz: a = {a:.4f}, p0 = {p0:.4f}")
    print(f"computed: a_h = {a_h:.4f} (error {a_h - a:+.4f}, element {args.h}), "
          f"peak = {p.max():.4f} (error {100 * peak_err:+.2f} %)")
    print(f"total contact force error: {force_err:.1e} (relative)")
    m = report.extra["mortar"][0]
    print(f"mortar: {m['rows']} rows, {m['uncoupled_slave_nodes']} slave nodes out of reach, "
          f"{m['active_rows']} active, largest penetration {m['max_penetration']:.1e}")
    print(f"time: mesh {t_mesh:.2f} s, solve {report.timings['total']:.2f} s; "
          f"output in {args.out}/")
