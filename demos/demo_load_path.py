# # A load path with Coulomb friction: Cattaneo–Mindlin and the Mindlin–Deresiewicz hysteresis
#
# An elastic disk (radius $R = 8$) on an elastic block, both $E = 200$, $\nu = 0.3$ (plane
# strain, elastically similar: the normal and the tangential problems decouple), node-to-node
# contact with Coulomb friction $\mathcal{F} = 0.4$. The disk floats: only the contact holds it.
# Its flat top first carries a normal load $P$; then a tangential load $Q$ goes up to
# $Q^* = 0.6\,\mathcal{F}P$, down to $-Q^*$ and up to $Q^*$ again, in steps.
#
# With friction the answer depends on the path. `df.solve_path` solves the steps on one set-up
# (the factorizations, the coarse problem and the preconditioner are kept), each warm-started
# from the last, and lets the friction act on the **slip increment** of each step: a node that
# sticks keeps its tangential displacement. The theory (Johnson, *Contact Mechanics*, 1985,
# §7.1; Mindlin and Deresiewicz 1953): while $Q$ rises, the centre $|x| < c$ sticks,
# $c = a\sqrt{1 - Q/(\mathcal{F}P)}$, and the edges slip with $|q| = \mathcal{F}p$; after a
# reversal at $(Q_r, q_r)$ the traction is $q = q_r + 2\,q_{C}((Q - Q_r)/2)$ with $q_C$ the
# Cattaneo traction: the edges slip back, the centre keeps what it had. Back at $Q = 0$
# tractions stay locked in (zero net force), and the load–displacement curve is a loop.
#
# Run: `python demos/demo_load_path.py` (or under `mpirun -n 2`); `--help` lists options.

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
parser.add_argument("--h", type=float, default=0.1, help="node spacing in the contact zone")
parser.add_argument("--ratio", type=float, default=0.6, help="Q*/(F P)")
parser.add_argument("--steps", type=int, default=2, help="steps from 0 to Q*")
parser.add_argument("--rtol", type=float, default=1e-8, help="relative tolerance")
parser.add_argument("--out", type=Path, default=Path("output/load_path"), help="output folder")
parser.add_argument("--json", type=Path, default=None, help="write the last step's report here")
args, _ = parser.parse_known_args()  # -feti_* options: read by solve_path(options=sys.argv)
comm = MPI.COMM_WORLD
R, P, E, nu, F = 8.0, 10.0, 200.0, 0.3, 0.4
a = 2.0 * np.sqrt(R * P / (np.pi * E / (2.0 * (1.0 - nu**2))))  # Hertz half-width
p0 = 2.0 * P / (np.pi * a)  # Hertz peak pressure
# -

# ## The path
#
# Pseudo-time $t = 0, 1, \dots$; at each $t$ a problem on the same mesh and conditions. The
# traction on the disk's top is $(Q, -P)/(2R)$ plus a linear normal part that cancels the
# moment of $Q$ about the contact point (so the pressure stays Hertzian).

# +
mesh = df.build_mesh(meshes.hertz2d_full, h_contact=args.h, comm=comm)
n = args.steps
up = np.linspace(0.0, 1.0, n + 1)
ratios = np.concatenate([[0.0], up[1:], up[::-1][1:], -up[1:], -up[::-1][1:], up[1:]])
ratios *= args.ratio  # Q/(F P): 0 → Q* → 0 → −Q* → 0 → Q*


def problem_at(t: float) -> df.ContactProblem:
    q = ratios[int(t)] * F * P
    m = 3.0 * q / (2.0 * R**2)

    def traction(x):
        return ufl.as_vector((q / (2 * R), -P / (2 * R) + m * x[0]))

    return df.ContactProblem(
        mesh, df.Elasticity(E, nu, tractions={"load": traction}),
        dirichlet=[df.Dirichlet("bottom")],
        contact=[df.NodeToNode("disk_contact", "block_contact", friction=df.Coulomb(F))],
        decomposition=df.Parts(2))


if comm.rank == 0:
    args.out.mkdir(parents=True, exist_ok=True)
sols = df.solve_path(problem_at, range(ratios.size), comm=comm, options=sys.argv,
                     rtol=args.rtol, xdmf=args.out / "load_path.xdmf",
                     history=args.out / "history.json")
# -

# ## Against the theory
#
# Per step the analytic traction: Cattaneo while $Q$ first rises, then the Mindlin–Deresiewicz
# superposition after each reversal. The RMS difference over the pressed nodes is in units of
# $\mathcal{F}p_0$; the stick zone's half-width against $c$ (or $c'$ after a reversal).


# +
def cattaneo(x, r):
    c = a * np.sqrt(1.0 - abs(r))
    return np.sign(r) * F * p0 * (np.sqrt(np.maximum(1 - x**2 / a**2, 0.0))
                                  - c / a * np.sqrt(np.maximum(1 - x**2 / c**2, 0.0)))


x = sols[0].contact.x[:, 0]
theory, turn = [], None
for k, r in enumerate(ratios):
    if k >= 2 and (r - ratios[k - 1]) * (ratios[k - 1] - ratios[k - 2]) < 0:
        turn = (ratios[k - 1], theory[-1])  # a reversal at the last step
    theory.append(cattaneo(x, r) if turn is None else turn[1] + 2 * cattaneo(x, (r - turn[0]) / 2))
rms = []
for sol, q in zip(sols, theory, strict=True):
    c = sol.contact
    err = -c.tangential_traction[:, 0] - q  # the friction on the disk opposes Q
    rms.append(float(np.sqrt(np.mean(err[c.force > 0] ** 2)) / (F * p0)))
top = np.unique(mesh.facet_groups["load"]) if comm.rank == 0 else None
values = [sol.nodal_values_on_root() for sol in sols]
shift = np.array([v[top, 0].mean() for v in values]) if comm.rank == 0 else None
Q = ratios * F * P
# -

# ## Output: the loop, the tractions at Q*, back at 0 and at −Q*; XDMF over time; JSON

# +
if comm.rank == 0:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    # the loop is slim next to the elastic compliance: show δ less its secant through ±Q*
    k_secant = (shift[n] - shift[3 * n]) / (2 * Q[n])
    ax1.plot(shift - shift[0] - k_secant * Q, Q, "o-", ms=3)
    ax1.set_xlabel("tangential displacement δ of the disk's top, less the secant's Q·δ*/Q*")
    ax1.set_ylabel("tangential load Q")
    ax1.set_title("hysteresis loop")
    o = np.argsort(x)
    for k, colour in ((n, "C0"), (2 * n, "C1"), (3 * n, "C2")):
        c = sols[k].contact
        ax2.plot(x[o], -c.tangential_traction[o, 0] / (F * p0), ".", color=colour,
                 label=f"step {k}: Q/(F P) = {ratios[k]:+.2f}")
        ax2.plot(x[o], theory[k][o] / (F * p0), "-", color=colour, lw=1)
    ax2.plot(x[o], np.sqrt(np.maximum(1 - x[o] ** 2 / a**2, 0)), "k:", lw=1, label="p / p0")
    ax2.set_xlim(-1.3 * a, 1.3 * a)
    ax2.set_xlabel("x")
    ax2.set_ylabel("q / (F p0)")
    ax2.set_title("tractions (dots) and Mindlin–Deresiewicz (lines)")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out / "load_path.png", dpi=120)
report = sols[-1].report
report.converged = all(s.report.converged for s in sols)
if args.json:
    report.save_json(args.json)
# -

# ## Summary

if comm.rank == 0:
    print(f"{ratios.size} steps, all converged: {report.converged}")
    print("F-multiplications per step:", [s.report.hessian_mults for s in sols])
    print("traction RMS error per step / (F p0):", " ".join(f"{e:.3f}" for e in rms))
    locked = sols[2 * n].contact
    print(f"back at Q = 0: net tangential force {locked.tangential_force[:, 0].sum():.2e}, "
          f"largest nodal tangential force {np.abs(locked.tangential_force[:, 0]).max():.3e}")
    loop = sum(0.5 * (Q[k] + Q[k + 1]) * (shift[k + 1] - shift[k])
               for k in range(n, ratios.size - 1))
    print(f"energy dissipated over the cycle Q* -> -Q* -> Q*: {loop:.4e}")
    print(f"output in {args.out}/")
