"""Numerical scalability (BENCHMARKS.md B5): fixed H/h, growing number of H×H subdomains.

For each H/h and each H: primal and dual dofs, subdomains, SMALBE outer iterations,
F-multiplications to ||g^P|| <= 1e-6 ||b||, and the time (solve = preconditioner setup +
iterations, and total), with the default solver and with a second variant (by default the one
with the fewest F-multiplications in ``bench/solver_variants.py``). The target: the counts stay
bounded as H shrinks with H/h fixed.

Problems (``--problem``):

- ``b1`` (default): Dostál's two membranes (B1), the seed's table, whose counts are printed
  beside ours. The seed's dual dimension is FETI-1's (Dirichlet conditions eliminated); ours
  is Total FETI's and has n + 1 more rows (the Dirichlet rows on x = 0).
- ``elasticity``: the plane-elasticity analogue of B1 (``problems.squares2d``: the same squares,
  mesh and decomposition, B1's loads in-plane), 2 dofs per node.
- ``hertz``: the 2D Hertz half model on its graded mesh; level k has every element size
  divided by 2^k (h_contact = 0.05/2^k, h_far = 1/2^k) and Parts(4·4^k) per body, so the
  subdomains keep about the same number of elements (H/h about fixed; PT-Scotch parts by
  default, ``--parts-method rcb`` for coordinate bisection).

Writes ``output/bench/b5_scalability.md`` and ``.png`` (``b5_scalability_elasticity.*`` for
``--problem elasticity``).

For ``b1`` the *linear floor* is solved too (``--no-linear`` skips it): the same mesh, load and
subdomains with both contact surfaces clamped, so projected CG on the same ``P F P`` (without
and with the Dirichlet preconditioner) gives the cost of one linear FETI solve to compare with.

Run: ``python bench/b5_scalability.py`` (5–9 minutes on 2 cores, with the load: everything up to
2 130 048 primal dofs, i.e. H/h = 128 with H = 1/8; ``--max-primal 9e6`` adds H = 1/16 at
H/h = 128, 8.5 M dofs, see docs/benchmarks.md § 7 for its memory and time);
``python bench/b5_scalability.py --problem elasticity`` (about 7 minutes, up to 1.1 M dofs);
``python bench/b5_scalability.py --problem hertz`` (about 2 minutes).
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from fractions import Fraction
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solver_variants import parse_variant  # noqa: E402

import dolfinx_feti as df  # noqa: E402
import problems as P  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent

#: The seed's table (Dostál, Cortona 2006): (H/h, 1/H) → (primal, dual, CG iterations), with 2
#: outer SMALBE iterations each. FETI-1 dual dimensions (no Dirichlet rows); "10365" is the
#: seed's figure for 2·8²·9² = 10368.
SEED = {(8, 2): (648, 87, 20), (8, 4): (2592, 447, 23), (8, 8): (10365, 1983, 27),
        (32, 2): (8712, 327, 33), (32, 4): (34848, 1695, 30), (32, 8): (139392, 7551, 37),
        (128, 2): (133128, 1287, 59), (128, 4): (532512, 6687, 36),
        (128, 8): (2130048, 29823, 47)}

#: The variant compared with the default: the fewest F-multiplications in
#: bench/solver_variants.py (see docs/benchmarks_history.md § 2).
BEST = "rho=10+optimal+dirichlet"

#: The linear floor of a problem: the same mesh and decomposition without contact (projected CG).
LINEAR = {"b1": P.b1_linear}

BUILDERS = {
    "b1": (P.b1, P.membranes_mesh, 1, "B1 (two membranes, scalar)"),
    "elasticity": (P.squares2d, P.squares2d_mesh, 2,
                   "plane-elasticity analogue of B1 (problems.squares2d)"),
    "hertz": (P.hertz2d, P.hertz2d_mesh, 2,
              "2D Hertz, every element size halved and 4× the parts per level"),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", choices=list(BUILDERS), default="b1")
    parser.add_argument("--H", nargs="*", default=["1/2", "1/4", "1/8", "1/16"],
                        help="subdomain sizes (fractions 1/k)")
    parser.add_argument("--ratios", nargs="*", type=int, default=[8, 32, 128], help="H/h")
    parser.add_argument("--levels", nargs="*", type=int, default=[0, 1, 2, 3],
                        help="hertz: refinement levels k (h/2^k everywhere, Parts(4·4^k))")
    parser.add_argument("--parts-method", choices=["rcb", "ptscotch"], default="ptscotch",
                        help="hertz: the partitioner (rcb leaves 1-cell slivers on the graded "
                             "mesh, see docs/benchmarks_history.md § 3)")
    parser.add_argument("--max-primal", type=float, default=None,
                        help="skip larger cases (default 2.2e6 for b1, 1.2e6 for elasticity, "
                             "1e6 for hertz)")
    parser.add_argument("--variants", nargs="*", default=[BEST],
                        help="solvers besides the default: names of solver_variants.VARIANTS "
                             "or key=value,... (none given: the default only)")
    parser.add_argument("--linear", action=argparse.BooleanOptionalAction, default=True,
                        help="b1: also solve the linear floor (contact surfaces clamped, "
                             "projected CG, default and Dirichlet-preconditioned)")
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench")
    args, _ = parser.parse_known_args()
    build, mesh_cache, value_size, title = BUILDERS[args.problem]
    max_primal = args.max_primal or {"b1": 2.2e6, "elasticity": 1.2e6, "hertz": 1e6}[
        args.problem]
    solvers = {"default": {}}
    for v in args.variants:
        solvers[v] = parse_variant(v)
    t_start, code = time.perf_counter(), P.git_state()  # the code that runs

    # Cases: (group = one line of the plot / one row of the compact table, column, builder,
    # estimated primal dofs).
    cases = []
    if args.problem == "hertz":
        cols = [f"h0/{2 ** k}, Parts({4 * 4 ** k}, {args.parts_method})" for k in args.levels]
        for k, col in zip(args.levels, cols, strict=True):
            parts = df.Parts(4 * 4 ** k, method=args.parts_method)
            cases.append(("graded", col, functools.partial(
                build, h_contact=0.05 / 2 ** k, h_far=1.0 / 2 ** k, decomposition=parts),
                6000 * 4 ** k, None))
        groups = ["graded"]
        linear_solvers = {}
    else:
        cols = [Fraction(h) for h in args.H]
        for ratio in args.ratios:
            for H in cols:
                n = P.elements_per_unit(float(H), ratio)
                linear = (functools.partial(LINEAR[args.problem], n, float(H))
                          if args.linear and args.problem in LINEAR else None)
                cases.append((ratio, H, functools.partial(build, n, float(H)),
                              2 * (1 / H) ** 2 * (ratio + 1) ** 2 * value_size, linear))
        linear_solvers = {"linear": {}, "linear+dirichlet": {"preconditioner": "dirichlet"}}
        groups = list(args.ratios)

    rows = []  # (group, column, solver, record)
    skipped = []
    for group, col, make, primal, make_linear in cases:
        if primal > max_primal:
            skipped.append((group, col, int(primal)))
            continue
        t0 = time.perf_counter()
        problem = make()
        runs = [(name, problem, opts) for name, opts in solvers.items()]
        if make_linear is not None:
            linear = make_linear()
            runs += [(name, linear, opts) for name, opts in linear_solvers.items()]
        for name, prob, opts in runs:
            rec = P.solve_record(prob, rtol=args.rtol, **opts)
            rows.append((group, col, name, rec))
            if P.is_root():
                print(f"H/h={group!s:6s} H={col!s:18s} {name:26s} primal={rec['primal']:8d} "
                      f"dual={rec['dual']:6d} subs={rec['subdomains']:4d} "
                      f"outer={rec['outer']:3d} F={rec['mults']:4d} "
                      f"solve={rec['t_solve']:.2f}s total={rec['t_total']:.1f}s "
                      f"conv={rec['converged']} ({time.perf_counter() - t0:.0f} s)",
                      flush=True)
        del problem, runs
        mesh_cache.cache_clear()
    elapsed = time.perf_counter() - t_start
    if not P.is_root():
        return

    seed = args.problem == "b1"
    header = ["H/h", "H", "subdomains", "primal", "dual", "contact", "solver", "outer",
              "F-mults", "precond", "solve [s]", "total [s]", "converged"]
    if seed:
        header += ["seed primal/dual", "seed CG its"]
    table = []
    for ratio, H, name, r in rows:
        line = [ratio, str(H), r["subdomains"], r["primal"], r["dual"], r["inequality"], name,
                r["outer"], r["mults"], r["precond"], f"{r['t_solve']:.2f}",
                f"{r['t_total']:.1f}", r["converged"]]
        if seed:
            s = SEED.get((ratio, int(1 / H)))
            line += [f"{s[0]}/{s[1]}" if s else "", s[2] if s else ""]
        table.append(line)
    # The seed's layout: rows H/h, columns H, one cell per case.
    grid_header = ["H/h \\ H"] + [str(H) for H in cols]
    grid = []
    for ratio in groups:
        cells = [str(ratio)]
        for H in cols:
            recs = {name: r for q, h, name, r in rows if q == ratio and h == H}
            if not recs:
                cells.append("—")
                continue
            r0 = next(iter(recs.values()))
            parts = [f"{r0['primal']}/{r0['dual']}"]
            parts.append(" / ".join(f"{r['outer']}·{r['mults']}" for r in recs.values()))
            s = SEED.get((ratio, int(1 / H))) if seed else None
            if s:
                parts.append(f"seed 2·{s[2]}")
            cells.append("<br>".join(parts))
        grid.append(cells)

    md = [f"# B5 scalability: {title}", "",
          f"Machine: {P.machine()}. Code: {code}. rtol = {args.rtol:g}. "
          f"Run time {elapsed / 60:.1f} min.",
          f"Command: `{' '.join(['python'] + sys.argv)}`", "",
          "outer = SMALBE outer iterations, F-mults = F-multiplications in the QP solver, "
          "precond = preconditioner applications, solve = preconditioner setup + iterations, "
          "total = the whole df.solve (decomposition, assembly, factorization, coarse problem, "
          "iterations, recovery).", "",
          P.md_table(header, table), "",
          "Compact (the seed's layout): primal/dual, then outer·F-mults for "
          + " / ".join(dict.fromkeys(name for _, _, name, _ in rows))
          + (", then the seed's outer·CG iterations" if seed else "")
          + ". linear = the same mesh and subdomains with the contact surfaces clamped "
          "(projected CG, 0 outer iterations): the cost of one linear FETI solve.",
          "", P.md_table(grid_header, grid), ""]
    if skipped:
        md += ["Skipped (over --max-primal " f"{max_primal:.3g}): "
               + ", ".join(f"H/h={q} H={h} ({p} dofs)" for q, h, p in skipped), ""]
    args.out.mkdir(parents=True, exist_ok=True)
    stem = "b5_scalability" + ("" if args.problem == "b1" else "_" + args.problem)
    (args.out / f"{stem}.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    names = list(solvers) + ([n for n in linear_solvers] if any(c[4] for c in cases) else [])
    plot(rows, groups, names, seed, title, args.out / f"{stem}.png")


def plot(rows, ratios, solvers, seed, title, path) -> None:
    """F-multiplications against primal dofs, one line per H/h (log x)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    colors = plt.get_cmap("tab10")
    styles = ["-o", "--s", "-.^", (0, (1, 1)), (0, (3, 1, 1, 1))]
    for i, ratio in enumerate(ratios):
        for j, name in enumerate(solvers):
            pts = sorted((r["primal"], r["mults"]) for q, _, s, r in rows
                         if q == ratio and s == name)
            if pts:
                x, y = zip(*pts, strict=True)
                style = styles[j % len(styles)]
                kw = {"ls": style, "marker": "."} if isinstance(style, tuple) else {}
                ax.plot(x, y, *([] if kw else [style]), color=colors(i), ms=4,
                        label=f"H/h = {ratio}, {name}", **kw)
        pts = sorted((p, c) for (q, _), (p, _, c) in SEED.items() if q == ratio)
        if seed and pts:
            x, y = zip(*pts, strict=True)
            ax.plot(x, y, ":x", color=colors(i), alpha=0.6, label=f"H/h = {ratio}, seed (CG its)")
    ax.set_xscale("log")
    ax.set_xlabel("primal dofs")
    ax.set_ylabel("F-multiplications (rtol 1e-6)")
    ax.set_ylim(bottom=0)
    ax.set_title(f"B5: {title}", fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
