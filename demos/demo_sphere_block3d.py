# # A sphere on a block (3D Hertz), meshed independently: mortar contact
#
# An elastic hemisphere of radius $R = 8$ is pressed by a force $F = 20$ onto an elastic block,
# both with $E = 200$, $\nu = 0.3$. The two bodies are meshed **on their own** by gmsh (OCC
# kernel, one `generate` call, different element sizes), so the nodes of the sphere do not
# meet the nodes of the block: this is what `df.Mortar` contact is for. Hertz's theory gives
# the contact radius, the peak pressure and the pressure profile
#
# $$ a = \left(\frac{3 F R}{4 E^*}\right)^{1/3}, \qquad p_0 = \frac{3F}{2\pi a^2}, \qquad
#    p(r) = p_0 \sqrt{1 - r^2/a^2}, \qquad
#    \frac{1}{E^*} = \frac{1-\nu_1^2}{E_1} + \frac{1-\nu_2^2}{E_2}. $$
#
# We solve the quarter model (symmetry about $x = 0$ and $y = 0$) with Total FETI and
# SMALBE/MPRGP, compare with Hertz, write the displacement and the contact pressure to XDMF
# and plot the pressure against $p(r)$.
#
# Run it with `python demos/demo_sphere_block3d.py` (or under `mpirun -n 2`); `--h` sets the
# element size at the contact, `--help` lists the options.

# +
import argparse
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.constraints.mortar import mortar_coupling
from dolfinx_feti.io import meshes_occ

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=float, default=0.1,
                    help="element size of the sphere at the contact")
parser.add_argument("--ratio", type=float, default=1.7,
                    help="element size of the block at the contact / that of the sphere")
parser.add_argument("--parts", type=int, default=2, help="subdomains per body")
parser.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance of the solver")
parser.add_argument("--out", type=Path, default=Path("output/sphere_block3d"),
                    help="output folder")
parser.add_argument("--json", type=Path, default=None,
                    help="write the solve report (with the Hertz comparison) here")
args, _ = parser.parse_known_args()  # leave -feti_* options to PETSc
comm = MPI.COMM_WORLD
# -

# ## The geometry
#
# `dolfinx_feti.io.meshes_occ.sphere_on_block` builds the lower half of the ball (cut to
# $x, y \ge 0$) and the block $[0, 8]^2 \times [-8, 0]$ as two OCC volumes that are *not*
# fragmented against each other, sizes the mesh near the contact point ($h$ on the sphere,
# `ratio` $\cdot h$ on the block, growing to 2 away from it) and meshes both with one
# `generate(3)`. Its physical groups name the bodies (`sphere`, `block`) and the boundary
# parts: `sphere_contact` is the whole spherical surface and `block_contact` the whole top of
# the block, far larger than the contact zone; the contact search finds the pairs of facets
# that can touch.

# +
R, F, E, nu = 8.0, 20.0, 200.0, 0.3
t0 = time.perf_counter()
mesh = df.build_mesh(meshes_occ.sphere_on_block, h_contact_sphere=args.h,
                     h_contact_block=args.ratio * args.h, R=R, comm=comm)
t_mesh = time.perf_counter() - t0
# -

# ## The problem
#
# The quarter of $F$ acts on the hemisphere's flat top $z = R$ as the traction
# $F / (\pi R^2)$; the block is clamped at the bottom, and both bodies have rollers on the
# symmetry planes. The sphere, with the finer mesh, is the slave side: one non-penetration
# row per slave node that the search couples to the block's surface, with the dual
# (biorthogonal) multipliers of the mortar method, so each row keeps a simple bound λ_j ≥ 0.

traction = F / (np.pi * R**2)
problem = df.ContactProblem(
    mesh,
    df.Elasticity(E, nu, tractions={"load": (0.0, 0.0, -traction)}),
    dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("sym_x", components=[0]),
               df.Dirichlet("sym_y", components=[1])],
    contact=[df.Mortar(slave="sphere_contact", master="block_contact")],
    decomposition=df.Parts(args.parts),
)

# ## The solve

solution = df.solve(problem, comm=comm, rtol=args.rtol)
report = solution.report
search = report.extra["mortar"][0]  # what the contact search found, and the post-solve check

# The search and the integration of the mortar rows run inside the solve's setup; timed here
# on their own for the summary.

t0 = time.perf_counter()
mortar_coupling(mesh.x, mesh.cells, mesh.facets("sphere_contact"), mesh.facets("block_contact"))
t_mortar = time.perf_counter() - t0

# ## Comparison with Hertz
#
# The load the discrete model carries is the traction times the *meshed* area of the flat
# top (a polygon inscribed in the quarter circle), slightly less than $F/4$; Hertz's values
# below are those of that load. The pressure at a slave node is its multiplier (the nodal
# force) divided by its lumped area. The computed contact radius lies between the farthest
# node in contact and the nearest node out of contact beyond it; on an unstructured mesh we
# report their mean.

# +
load_facets = mesh.x[mesh.facets("load")]
load_area = 0.5 * np.linalg.norm(np.cross(load_facets[:, 1] - load_facets[:, 0],
                                          load_facets[:, 2] - load_facets[:, 0]), axis=1).sum()
F_h = 4 * traction * load_area  # the whole sphere's load
E_star = 1.0 / (2 * (1 - nu**2) / E)
a = (3 * F_h * R / (4 * E_star)) ** (1 / 3)
p0 = 3 * F_h / (2 * np.pi * a**2)

c = solution.contact
r, p = np.hypot(c.x[:, 0], c.x[:, 1]), c.pressure
active = p > 1e-8 * p.max()
r_in = r[active].max()
r_out = r[~active & (r > r_in)].min()
a_h = 0.5 * (r_in + r_out)
peak_err = (p.max() - p0) / p0
hertz_p = p0 * np.sqrt(np.maximum(1 - r**2 / a**2, 0.0))
rms_err = np.sqrt(np.mean((p - hertz_p)[active | (r < a)] ** 2)) / p0
# A Hertz profile fitted to the nodal pressures: p² = p0² − (p0/a)² r² is linear in r².
slope, p0_sq = np.polyfit(r[active] ** 2, p[active] ** 2, 1)
p0_fit, a_fit = np.sqrt(p0_sq), np.sqrt(-p0_sq / slope)
force = solution.total_contact_force
force_err = abs(force[2] - F_h / 4) / (F_h / 4)
h_block = args.ratio * args.h
# -

# ## Output: XDMF for ParaView, a plot, a JSON report

# +
if comm.rank == 0:
    args.out.mkdir(parents=True, exist_ok=True)
solution.write_xdmf(args.out / "sphere_block3d.xdmf")
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rs = np.linspace(0, a, 200)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(rs, p0 * np.sqrt(1 - rs**2 / a**2), "k-", label="Hertz")
    rf = np.linspace(0, a_fit, 200)
    ax.plot(rf, p0_fit * np.sqrt(1 - rf**2 / a_fit**2), "k--", lw=1,
            label="Hertz profile fitted to the nodal pressures")
    ax.plot(r, p, "o", ms=3, label=f"TFETI + mortar, h = {args.h:g} / {h_block:g}")
    ax.set_xlim(0, 2 * a)
    ax.set_xlabel("r")
    ax.set_ylabel("contact pressure")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out / "sphere_block3d_pressure.png", dpi=120)
report.extra["hertz"] = {
    "h_sphere": args.h, "h_block": h_block, "nodes": int(mesh.x.shape[0]),
    "load": F_h, "a": a, "p0": p0, "a_h": a_h, "r_in": r_in, "r_out": r_out,
    "peak": float(p.max()), "peak_error": peak_err, "rms_error": rms_err,
    "p0_fit": p0_fit, "a_fit": a_fit,
    "contact_force": float(force[2]), "force_error": force_err,
    "time_mesh": t_mesh, "time_mortar": t_mortar, "time_solve": report.timings["total"]}
if args.json:
    report.save_json(args.json)
# -

# ## Summary

if comm.rank == 0:
    print(report.summary())
    print(f"mesh: {mesh.x.shape[0]} nodes, h = {args.h:g} (sphere) / {h_block:g} (block) at the "
          f"contact; search: {search['rows']} rows, {search['facet_pairs']} facet pairs, "
          f"{search['uncoupled_slave_nodes']} slave nodes out of range, "
          f"{search['active_rows']} active")
    print(f"Hertz (load {F_h:.5f} = traction x meshed area): a = {a:.4f}, p0 = {p0:.4f}")
    print(f"computed: a_h = {a_h:.4f} (error {a_h - a:+.4f}; last node in contact at "
          f"{r_in:.4f}, next out at {r_out:.4f}), peak = {p.max():.4f} "
          f"(error {100 * peak_err:+.2f} %)")
    print(f"Hertz profile fitted to the nodal pressures: a = {a_fit:.4f} "
          f"(error {100 * (a_fit - a) / a:+.2f} %), p0 = {p0_fit:.4f} "
          f"(error {100 * (p0_fit - p0) / p0:+.2f} %); rms of p - p_Hertz: "
          f"{100 * rms_err:.2f} % of p0")
    print(f"total contact force {force[2]:.8f} vs applied load {F_h / 4:.8f} (quarter): "
          f"relative error {force_err:.1e}; largest penetration "
          f"{search['max_penetration']:.1e}")
    print(f"time: mesh {t_mesh:.2f} s, mortar search + integration {t_mortar:.3f} s, "
          f"solve {report.timings['total']:.2f} s; output in {args.out}/")
