# # A composite slab with stiff inclusions, meshed on their own: mortar ties and mortar contact
#
# A slab of a soft matrix ($E = 100$, $\nu = 0.3$) holds three round inclusions a thousand
# times stiffer ($E = 10^5$). It lies on a foundation block ($E = 100$) and is pressed by a
# traction $q = 1$ on part of its top (plane strain, half model, symmetric about $x = 0$).
# As a gmsh user builds such a composite without care for matching nodes, the holes are cut
# out of the matrix and each inclusion is a disk added afterwards (not fragmented), meshed
# finer than the matrix; the foundation is meshed on its own too. So the model has two kinds
# of non-matching interfaces:
#
# - the inclusions' boundaries and the matrix's holes, glued by `df.Tie` (mortar equality
#   rows with the soft matrix as the slave side; see the note on the choice below);
# - the slab's bottom and the foundation's top, in frictionless contact by `df.Mortar`: the
#   slab bends, and its far end may lift off.
#
# The check: the same geometry fragmented in gmsh (the inclusions share the nodes of their
# holes, so the ordinary gluing of subdomains holds them) solved on the same element size,
# and again on half of it, to see what the discretization error is.
#
# Run it with `python demos/demo_inclusions.py` (or under `mpirun -n 2`); `--h` sets the
# matrix's element size, `--help` lists the options.

# +
import argparse
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes_occ

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=float, default=0.05, help="element size of the matrix")
parser.add_argument("--ratio", type=float, default=0.6,
                    help="element size of the inclusions / that of the matrix")
parser.add_argument("--stiffness", type=float, default=1000.0,
                    help="Young's modulus of the inclusions / that of the matrix")
parser.add_argument("--slave", choices=["holes", "inclusions"], default="holes",
                    help="slave side of the ties: the matrix's holes or the inclusions")
parser.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance of the solver")
parser.add_argument("--no-reference", action="store_true",
                    help="skip the two conforming (fragmented) reference solves")
parser.add_argument("--out", type=Path, default=Path("output/inclusions"), help="output folder")
parser.add_argument("--json", type=Path, default=None,
                    help="write the solve report (with the comparison) here")
args, _ = parser.parse_known_args()  # leave -feti_* options to PETSc
comm = MPI.COMM_WORLD
# -

# ## The model
#
# `dolfinx_feti.io.meshes_occ.slab_with_inclusions` builds the slab $[0, 2] \times [0, 0.6]$
# with inclusions of radius 0.18 at $x = 0.4, 1.0, 1.6$ and the foundation
# $[0, 3] \times [-1, 0]$. Its physical groups: the bodies `matrix`, `inclusions` (the three
# disks), `foundation`; the boundaries `load` (the top on $x < 0.8$), `slab_bottom`,
# `foundation_top`, `symmetry`, `bottom`, and, unless `conforming=True`, `holes` and
# `inclusion_surface`.
#
# **Which side is the slave.** A tie row holds a slave node to the mortar-weighted point of
# the master surface, u_j = Σ_k w_jk u_k. On a curved interface meshed twice, that point is
# not the node itself (the two polygons inscribed in the circle differ by up to h²/8R), so
# a rotation of both sides does not satisfy the rows exactly; the misfit must be absorbed by
# a deformation of one side. Take the soft matrix as the slave: the stiff inclusions then
# rotate freely. With the stiff inclusions as the slave side — and here also the finer
# mesh — the ties lock: `--slave inclusions` gives an energy 3 % too small in magnitude and a
# displacement of the third inclusion off by two thirds, far beyond the discretization
# error, while the same choice with equal stiffnesses (`--stiffness 1`) is fine.

# +
E_m, nu, q, load_length = 100.0, 0.3, 1.0, 0.8
E = {"matrix": E_m, "inclusions": args.stiffness * E_m, "foundation": E_m}
surfaces = {"holes": "holes", "inclusions": "inclusion_surface"}
other = "inclusions" if args.slave == "holes" else "holes"
ties = [df.Tie(slave=surfaces[args.slave], master=surfaces[other])]


def solve(h: float, conforming: bool) -> tuple[df.MeshData, df.Solution, float]:
    """Mesh the model at size h (fragmented or not) and solve it."""
    t0 = time.perf_counter()
    mesh = df.build_mesh(meshes_occ.slab_with_inclusions, h_matrix=h,
                         h_inclusion=args.ratio * h, h_foundation=1.6 * h,
                         conforming=conforming, load_length=load_length, comm=comm)
    problem = df.ContactProblem(
        mesh,
        df.Elasticity(E, nu, tractions={"load": (0.0, -q)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.Mortar(slave="slab_bottom", master="foundation_top")],
        ties=[] if conforming else ties,
        # one subdomain per inclusion (each is a connected piece of the body "inclusions")
        decomposition=df.Parts({"matrix": 2, "inclusions": 1, "foundation": 2}))
    solution = df.solve(problem, comm=comm, rtol=args.rtol)
    return mesh, solution, time.perf_counter() - t0
# -

# ## The solve with ties, and the conforming references

mesh, solution, t_tied = solve(args.h, conforming=False)
report = solution.report
refs = [] if args.no_reference else [solve(args.h, True), solve(args.h / 2, True)]

# ## What is compared
#
# Quantities that do not depend on where the nodes are: the energy $\frac12 u^T K u - f^T u$,
# the deflection of the top at the symmetry line, the mean vertical displacement of each
# inclusion, the end of the contact zone and the largest contact pressure; and the total
# contact force, which must equal the load $q \cdot 0.8$ on any mesh (equilibrium). The
# deviation of the tied model from the conforming one of the same element size is set
# against the conforming model's own discretization error, estimated by its change from $h$
# to $h/2$ (displacements relative to the deflection of the top, the energy and the pressure
# relative to themselves).

# +
DISPLACEMENTS = ["u_top", "u_inclusion_0", "u_inclusion_1", "u_inclusion_2"]


def observables(mesh: df.MeshData, solution: df.Solution) -> dict:
    u = solution.nodal_values()
    top = np.argmin(np.linalg.norm(mesh.x - [0.0, 0.6], axis=1))
    c = solution.contact
    order = np.argsort(c.x[:, 0])
    x, p = c.x[order, 0], c.pressure[order]
    active = p > 1e-8 * p.max()
    x_in = x[active].max()
    beyond = x[~active & (x > x_in)]
    x_c = 0.5 * (x_in + beyond.min()) if beyond.size else x_in
    k = mesh.body_names.index("inclusions")
    # each inclusion: its cells' nodes, told apart by their x (centres 0.4, 1.0, 1.6)
    nodes = np.unique(mesh.cells[mesh.cell_body == k])
    which = np.rint((mesh.x[nodes, 0] - 0.4) / 0.6).astype(int)
    u_inc = [float(u[nodes[which == i], 1].mean()) for i in range(3)]
    return {"energy": solution.energy, "u_top": float(u[top, 1]),
            "u_inclusion_0": u_inc[0], "u_inclusion_1": u_inc[1], "u_inclusion_2": u_inc[2],
            "contact_end": float(x_c), "peak_pressure": float(p.max()),
            "contact_force": float(solution.total_contact_force[1])}


def deviation(a: dict, b: dict) -> dict:
    """Relative differences: displacements, energy, peak pressure; contact end in elements."""
    scale = abs(b["u_top"])
    return {"displacement": max(abs(a[k] - b[k]) for k in DISPLACEMENTS) / scale,
            "energy": abs(a["energy"] - b["energy"]) / abs(b["energy"]),
            "peak_pressure": abs(a["peak_pressure"] - b["peak_pressure"]) / b["peak_pressure"],
            "contact_end": abs(a["contact_end"] - b["contact_end"]) / args.h}


names = {"energy": "energy", "u_top": "u_y of the top at x = 0",
         "u_inclusion_0": "mean u_y, inclusion 1", "u_inclusion_1": "mean u_y, inclusion 2",
         "u_inclusion_2": "mean u_y, inclusion 3", "contact_end": "end of the contact zone",
         "peak_pressure": "peak contact pressure", "contact_force": "total contact force"}
tied = observables(mesh, solution)
ref = [observables(m, s) for m, s, _ in refs]
dev_tied = deviation(tied, ref[0]) if ref else None  # the tie's own error
dev_conf = deviation(ref[0], ref[1]) if ref else None  # the discretization error
load = q * load_length
force_err = abs(tied["contact_force"] - load) / load
ties_info = [m for m in report.extra["mortar"] if m["type"] == "tie"]
contact_info = [m for m in report.extra["mortar"] if m["type"] == "mortar"][0]
# -

# ## Output: XDMF for ParaView, a JSON report

# +
solution.write_xdmf(args.out / "inclusions.xdmf")
report.extra["inclusions"] = {
    "h": args.h, "nodes": int(mesh.x.shape[0]), "tied": tied,
    "conforming_h": ref[0] if ref else None, "conforming_h2": ref[1] if ref else None,
    "deviation_tied": dev_tied, "discretization_error": dev_conf, "slave": args.slave,
    "load": load, "force_error": force_err, "tie_rows": sum(m["rows"] for m in ties_info),
    "time_tied": t_tied, "time_conforming": [t for _, _, t in refs]}
if args.json:
    report.save_json(args.json)
# -

# ## Summary

if comm.rank == 0:
    print(report.summary())
    print(f"tied model: {mesh.x.shape[0]} nodes (matrix h = {args.h:g}, inclusions "
          f"{args.ratio * args.h:g}, E ratio {args.stiffness:g}), "
          f"{sum(m['rows'] for m in ties_info)} tie rows (slave: {args.slave}), contact: "
          f"{contact_info['rows']} rows, {contact_info['active_rows']} active")
    print(f"total contact force {tied['contact_force']:.8f} vs load {load:.8f}: relative "
          f"error {force_err:.1e}")
    if ref:
        print(f"{'':28s} {'tied (h)':>11s} {'conform. (h)':>12s} {'conform. (h/2)':>14s} "
              f"{'tied - conf(h)':>15s} {'conf(h) - conf(h/2)':>19s}")
        for key, label in names.items():
            a, b, c = tied[key], ref[0][key], ref[1][key]
            print(f"{label:28s} {a:11.6f} {b:12.6f} {c:14.6f} {a - b:+15.2e} {b - c:+19.2e}")
        print("tie vs conforming (h) | conforming h vs h/2, relative: " + ", ".join(
            f"{k} {dev_tied[k]:.1e} | {dev_conf[k]:.1e}" for k in dev_tied))
    print(f"time: tied {t_tied:.2f} s" + (f", conforming h {refs[0][2]:.2f} s, h/2 "
                                           f"{refs[1][2]:.2f} s" if refs else "")
          + f"; output in {args.out}/")
