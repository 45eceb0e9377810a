# # Coulomb friction: a disk on a block with a tangential load (Cattaneo–Mindlin)
#
# An elastic disk of radius $R = 8$ presses on an elastic block (both $E = 200$, $\nu = 0.3$,
# plane strain) with a normal line load $P = 10$ and is pushed sideways by a tangential load
# $Q < \mathcal{F} P$, with Coulomb friction of coefficient $\mathcal{F} = 0.4$. For elastically
# similar bodies the pressure stays Hertzian,
# $p(x) = p_0 \sqrt{1 - x^2/a^2}$, $a = 2\sqrt{R P / (\pi E^*)}$, and the contact splits into a
# central stick zone $|x| < c$ and two slip zones with (Cattaneo 1938, Mindlin 1949)
#
# $$ c = a \sqrt{1 - \frac{Q}{\mathcal{F} P}}, \qquad
#    q(x) = \mathcal{F} p_0 \left(\sqrt{1 - x^2/a^2} - \frac{c}{a}\sqrt{1 - x^2/c^2}\right)
#    \ (|x| < c), \qquad q(x) = \mathcal{F} p(x)\ (c \le |x| \le a). $$
#
# Coulomb friction is solved by a fixed point on the slip bound, $g = \mathcal{F} \lambda_N$, each
# step a Tresca problem (Total FETI, SMALBE-M, MPRGP with box bounds) warm-started from the
# previous one; the report counts the steps.
#
# Run: `python demos/demo_coulomb_cylinders.py` (or under `mpirun -n 2`); `--help` for options.

# +
import argparse
import sys
from pathlib import Path

import numpy as np
import ufl
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import meshes

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("--h", type=float, default=0.05, help="node spacing in the contact zone")
parser.add_argument("--parts", type=int, default=2, help="subdomains per body")
parser.add_argument("--friction", type=float, default=0.4, help="Coulomb coefficient")
parser.add_argument("--ratio", type=float, default=0.5, help="Q / (F P), in [0, 1)")
parser.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance")
parser.add_argument("--out", type=Path, default=Path("output/coulomb_cylinders"))
parser.add_argument("--json", type=Path, default=None, help="write the solve report here")
args, _ = parser.parse_known_args()
comm = MPI.COMM_WORLD
R, P, E, nu, F = 8.0, 10.0, 200.0, 0.3, args.friction
Q = args.ratio * F * P
# -

# ## Geometry and load
#
# `meshes.hertz2d_full` is the full model (no symmetry line, which could not carry $Q$): the lower
# half of the disk on the block, with matching contact nodes at $x_k = \pm k h$. A tangential
# traction on the disk's flat top (at height $R$ above the contact) would tilt the disk with the
# moment $Q R$; a linear normal traction $m x$ with $m \cdot 2R^3/3 = Q R$ cancels it, so the
# load is the force $(Q, -P)$ with no moment about the contact point. The disk floats: only
# the contact and friction hold it.

# +
mesh = df.build_mesh(meshes.hertz2d_full, h_contact=args.h, R=R, comm=comm)
m = 3.0 * Q / (2.0 * R**2)


def top_traction(x):
    return ufl.as_vector((Q / (2 * R), -P / (2 * R) + m * x[0]))


problem = df.ContactProblem(
    mesh, df.Elasticity(E, nu, tractions={"load": top_traction}),
    dirichlet=[df.Dirichlet("bottom")],
    contact=[df.NodeToNode("disk_contact", "block_contact", friction=df.Coulomb(F))],
    decomposition=df.Parts(args.parts))
solution = df.solve(problem, comm=comm, options=sys.argv, rtol=args.rtol)
report = solution.report
# -

# ## Comparison with Cattaneo–Mindlin
#
# The stick zone is measured between the outermost sticking nodes, extended by half an element
# at each end (the midpoint to the first slipping node), the contact zone likewise.

# +
E_star = E / (2 * (1 - nu**2))
a = 2 * np.sqrt(R * P / (np.pi * E_star))
p0 = np.sqrt(P * E_star / (np.pi * R))
c_theory = a * np.sqrt(1 - Q / (F * P))
con = solution.contact
order = np.argsort(con.x[:, 0])
x = con.x[order, 0]
p = con.pressure[order]
q = -con.tangential_traction[order, 0]  # the traction the block exerts on the disk, against Q
stick = con.state[order] == df.ContactData.STICK
pressed = p > 1e-8 * p.max()
a_h = 0.5 * (x[pressed].max() - x[pressed].min()) + 0.5 * args.h
c_h = 0.5 * (x[stick].max() - x[stick].min()) + 0.5 * args.h


def q_theory(xs):
    out = F * p0 * np.sqrt(np.maximum(1 - xs**2 / a**2, 0))
    inner = np.abs(xs) < c_theory
    out[inner] -= F * p0 * (c_theory / a) * np.sqrt(1 - xs[inner] ** 2 / c_theory**2)
    return out


info = report.extra["friction"]
# -

# ## Output

# +
if comm.rank == 0:
    args.out.mkdir(parents=True, exist_ok=True)
solution.write_xdmf(args.out / "coulomb_cylinders.xdmf")
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xs = np.linspace(-1.2 * a, 1.2 * a, 400)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.axvspan(-c_theory, c_theory, color="0.92", lw=0, label="stick zone (theory)")
    ax.plot(xs, p0 * np.sqrt(np.maximum(1 - xs**2 / a**2, 0)), "k-", lw=1, label="Hertz $p$")
    ax.plot(xs, F * p0 * np.sqrt(np.maximum(1 - xs**2 / a**2, 0)), "k--", lw=1,
            label=r"$\mathcal{F} p$")
    ax.plot(xs, q_theory(xs), "C0-", lw=1, label="Cattaneo–Mindlin $q$")
    ax.plot(x, p, "ko", ms=3, label="TFETI pressure")
    ax.plot(x[stick], q[stick], "s", color="C0", ms=4, label="TFETI $q$, stick")
    ax.plot(x[~stick], q[~stick], "^", color="C3", ms=4, label="TFETI $q$, slip")
    ax.set_xlim(-1.3 * a, 1.3 * a)
    ax.set_xlabel("x")
    ax.set_ylabel("traction")
    ax.set_title(f"Q/(F P) = {args.ratio}: c = {c_theory:.4f} (theory), {c_h:.4f} (TFETI)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out / "coulomb_cylinders.png", dpi=120)
if args.json:
    report.save_json(args.json)
# -

# ## Summary

if comm.rank == 0:
    print(report.summary())
    print(f"Coulomb fixed point: {info['fixed_point_steps']} steps, converged "
          f"{info['fixed_point_converged']}; changes "
          + ", ".join(f"{s['change']:.1e}" for s in info["steps"]))
    print(f"Hertz a = {a:.4f}, computed {a_h:.4f}; Cattaneo–Mindlin c = {c_theory:.4f}, "
          f"computed {c_h:.4f} (error {c_h - c_theory:+.4f}, element {args.h})")
    print(f"total contact force on the disk {solution.total_contact_force.round(8)} "
          f"(load ({Q}, {-P}))")
