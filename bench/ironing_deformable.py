"""Ironing with a deformable die: Newton with Coulomb friction on mortar pairs (2D).

After Puso & Laursen (2004): a soft neo-Hookean block [0, 4] × [0, 1] (E = 1, ν = 0.3, plane
strain), clamped at its bottom, and a stiffer neo-Hookean die (E = 10, ν = 0.3) of width 1
and height 0.5 over a circular bottom of radius 1 (``slider_on_block`` of tests/support), the
two meshed apart (triangles of ``h_block`` and ``h_die``: no node of the die's bottom matches
one of the block's top). The die's top is moved down by ``press`` in ``press_steps`` steps,
then along x by ``slide`` in ``slide_steps`` steps, over several of the block's elements.
Mortar contact (slave: the die's bottom, master: the block's top), searched again on the
deformed surfaces at every Newton iterate, Coulomb 𝓕 = 0.3 on the slip of each slave node
relative to the master material it is paired with in each step (drivers/mortar_friction.py);
one subdomain per body (``ByTags``), FETI-DP.

Per step: the force on the die (the contact force on its bottom: N vertical, T horizontal),
T/N, Σ|q| / Σp in the contact frame (𝓕 exactly where every pressed node slips), the pressed
and the slipping slave nodes, the die's travel over the block's element size, Newton
iterations and seconds. Writes ``output/bench/ironing_deformable.json`` and
``output/bench/ironing_deformable.png`` (N, T and T/N against the travel); prints a Markdown
table. Run:

    OMP_NUM_THREADS=1 PYTHONPATH=$PWD python bench/ironing_deformable.py
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "support"))

from sliding_meshes import slider_on_block  # noqa: E402

import dolfinx_feti as df  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--h-block", type=float, default=0.1)
    ap.add_argument("--h-die", type=float, default=0.05)
    ap.add_argument("--press", type=float, default=0.15)
    ap.add_argument("--slide", type=float, default=1.5)
    ap.add_argument("--press-steps", type=int, default=3)
    ap.add_argument("--slide-steps", type=int, default=15)
    ap.add_argument("--coefficient", type=float, default=0.3)
    ap.add_argument("--rtol", type=float, default=1e-10)
    ap.add_argument("--newton-rtol", type=float, default=1e-9)
    args = ap.parse_args()
    comm = MPI.COMM_WORLD
    mesh = df.build_mesh(slider_on_block, length=4.0, height=1.0, x0=0.5, width=1.0,
                         slider_height=0.5, radius=1.0, h_block=args.h_block,
                         h_slider=args.h_die, gdim=2, comm=comm)
    material = df.NeoHookean({"block": 1.0, "slider": 10.0}, 0.3)
    n_press, n_slide = args.press_steps, args.slide_steps

    def problem(t: float) -> df.ContactProblem:
        travel = max(t - n_press, 0.0) / n_slide * args.slide
        return df.ContactProblem(
            mesh, material,
            dirichlet=[df.Dirichlet("bottom"),
                       df.Dirichlet("slider_top", (travel, -min(t, n_press) / n_press
                                                   * args.press))],
            contact=[df.Mortar("slider_bottom", "block_top", friction=df.Coulomb(
                args.coefficient, rtol=1e-10, max_steps=200))],
            decomposition=df.ByTags())

    times = np.arange(1, n_press + n_slide + 1, dtype=float)
    wall = time.perf_counter()
    sols = df.solve_path(problem, times, comm=comm, rtol=args.rtol,
                         newton_rtol=args.newton_rtol, newton_max_it=40, method="fetidp",
                         progress=False)
    wall = comm.allreduce(time.perf_counter() - wall, op=MPI.MAX)
    rows = []
    for t, s in zip(times, sols, strict=True):
        c = s.contact
        fx, fy = s.total_contact_force  # on the die
        pressed = c.force > 0
        hist = s.report.extra["newton"]
        rows.append({
            "time": float(t), "travel": max(t - n_press, 0.0) / n_slide * args.slide,
            "converged": bool(s.report.converged), "N": float(fy), "T": float(-fx),
            "T_over_N": float(-fx / fy),
            "ratio_contact": float(np.linalg.norm(c.tangential_force[pressed], axis=1).sum()
                                   / c.force[pressed].sum()),
            "pressed": int(pressed.sum()), "slip": int(np.count_nonzero(c.state[pressed] == 2)),
            "newton_iterations": len(hist),
            "seconds": float(sum(x["seconds"] for x in hist)),
            "fmults": int(sum(x["hessian_mults"] for x in hist)),
            "residuals": [x["residual"] for x in hist]})
    if comm.rank != 0:
        return
    out = ROOT / "output/bench"
    out.mkdir(parents=True, exist_ok=True)
    steady = [r for r in rows if r["travel"] >= 0.5 and r["slip"] == r["pressed"]]
    ratio = np.array([r["T_over_N"] for r in steady])
    summary = {"args": vars(args), "nodes": mesh.num_nodes, "ranks": comm.size, "wall": wall,
               "steps": rows,
               "steady_T_over_N": [float(ratio.min()), float(ratio.max())] if ratio.size
               else None}
    (out / "ironing_deformable.json").write_text(json.dumps(summary, indent=1))
    _plot(rows, args.coefficient, out / "ironing_deformable.png")
    print(f"mesh: {mesh.num_nodes} nodes, h block {args.h_block}, h die {args.h_die}, "
          f"{comm.size} rank(s); {times.size} steps in {wall:.1f} s, "
          f"{sum(r['fmults'] for r in rows)} F-multiplications; all converged: "
          f"{all(r['converged'] for r in rows)}; steady sliding (travel >= 0.5, every pressed "
          f"node slipping, {len(steady)} steps): T/N "
          + (f"{ratio.min():.4f} … {ratio.max():.4f}" if ratio.size else "none"))
    print("| step | travel | travel / h_block | N | T | T/N | Σ|q|/Σp | pressed | slipping "
          "| Newton its | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for k, r in enumerate(rows):
        print(f"| {k + 1} | {r['travel']:.2f} | {r['travel'] / args.h_block:.1f} | "
              f"{r['N']:.5f} | {r['T']:.5f} | {r['T_over_N']:.4f} | "
              f"{r['ratio_contact']:.8f} | {r['pressed']} | {r['slip']} | "
              f"{r['newton_iterations']} | {r['seconds']:.2f} |")


def _plot(rows: list[dict], coefficient: float, path: Path) -> None:
    """N and T on the die, and T/N, against the step (press, then travel)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    step = np.arange(1, len(rows) + 1)
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    a.plot(step, [r["N"] for r in rows], "o-", label="N (normal)")
    a.plot(step, [r["T"] for r in rows], "s-", label="T (tangential)")
    a.set_xlabel("load step (press, then slide)")
    a.set_ylabel("force on the die")
    a.legend()
    b.plot(step, [r["T_over_N"] for r in rows], "o-", label="T/N")
    b.axhline(coefficient, color="k", ls="--", label=f"friction coefficient {coefficient}")
    b.set_xlabel("load step (press, then slide)")
    b.set_ylim(0.0, 1.5 * coefficient)
    b.legend()
    fig.suptitle("ironing with a deformable die: mortar contact, Coulomb, Newton")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
