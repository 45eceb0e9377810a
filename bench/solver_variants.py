"""The solver variants side by side: MPRGP expansion and step length, preconditioners, SMALBE ρ.

For each problem and each variant: F-multiplications in the QP solver, preconditioner
applications, outer (SMALBE) iterations, whether it converged, and the time to
||g^P|| <= rtol ||b|| (rtol = 1e-6): "solve" = preconditioner setup + iterations (the part that
depends on the variant; minimum over --repeat runs), and the total. Also the measured cost of
one F-multiplication and of one application of each preconditioner, per problem.

Writes ``output/bench/solver_variants.md`` and ``output/bench/solver_variants.png``.

Run: ``python bench/solver_variants.py`` (7–9 minutes on 2 cores; ``--quick`` for the small
problems only, ``--problems`` to choose, ``--repeat`` for the timing repeats).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from mpi4py import MPI

sys.path.insert(0, str(Path(__file__).resolve().parent))
import dolfinx_feti as df  # noqa: E402
import problems as P  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent

#: name → keyword arguments of df.solve (on top of the defaults).
VARIANTS: dict[str, dict] = {
    "default": {},
    "plain": {"smalbe_acceleration": "none"},
    "lumped+stiffness": {"preconditioner": "lumped", "preconditioner_scaling": "stiffness"},
    "dirichlet+stiffness": {"preconditioner": "dirichlet",
                            "preconditioner_scaling": "stiffness"},
    "expansion=optimal": {"mprgp_expansion": "optimal"},
    "expansion=projcg": {"mprgp_expansion": "projcg"},
    "alpha=bb": {"mprgp_alpha": "bb"},
    "precond=lumped": {"preconditioner": "lumped"},
    "precond=dirichlet": {"preconditioner": "dirichlet"},
    "optimal+lumped": {"mprgp_expansion": "optimal", "preconditioner": "lumped"},
    "optimal+dirichlet": {"mprgp_expansion": "optimal", "preconditioner": "dirichlet"},
    "projcg+dirichlet": {"mprgp_expansion": "projcg", "preconditioner": "dirichlet"},
    "bb+lumped": {"mprgp_alpha": "bb", "preconditioner": "lumped"},
    "bb+dirichlet": {"mprgp_alpha": "bb", "preconditioner": "dirichlet"},
    "rho=10": {"smalbe_rho": 10.0},
    "rho=10+dirichlet": {"smalbe_rho": 10.0, "preconditioner": "dirichlet"},
    "rho=10+optimal+dirichlet": {"smalbe_rho": 10.0, "mprgp_expansion": "optimal",
                                 "preconditioner": "dirichlet"},
}

#: name → (builder, small?). The small ones are the brief's; the others give times that are
#: not dominated by overheads.
PROBLEMS = {
    "B1 n=64 H=1/8": (lambda: P.b1(64, 1 / 8), True),
    "B1 n=256 H=1/8": (lambda: P.b1(256, 1 / 8), False),
    "elast. B1 n=64 H=1/8": (lambda: P.squares2d(64, 1 / 8), True),
    "Hertz 2D Parts(4)": (lambda: P.hertz2d(4), True),
    "Hertz 2D h/4 Parts(16)": (lambda: P.hertz2d(16, h_contact=0.0125, h_far=0.25), False),
    "3D blocks n=8 Parts(2)": (lambda: P.blocks3d(8, 2), True),
    "3D blocks n=16 Parts(4)": (lambda: P.blocks3d(16, 4), False),
}


def parse_variant(spec: str) -> dict:
    """A variant by name, or ``key=value,key=value`` of SolverOptions fields."""
    if spec in VARIANTS:
        return dict(VARIANTS[spec])
    out = {}
    for item in spec.split(","):
        key, value = item.split("=")
        try:
            out[key] = float(value)
        except ValueError:
            out[key] = value
    return out


def application_costs(problem: df.ContactProblem, repeat: int = 20) -> dict:
    """Milliseconds per F-multiplication and per preconditioner application (max over ranks)."""
    from dolfinx_feti.feti.preconditioner import make_preconditioner

    comm = MPI.COMM_WORLD
    qp = df.dual_qp(problem, comm)
    feti = qp.feti
    x = feti.d.duplicate()
    x.setRandom()
    y = x.duplicate()
    out = {}

    def timed(fn) -> float:
        fn(x, y)  # warm-up
        comm.Barrier()
        t0 = time.perf_counter()
        for _ in range(repeat):
            fn(x, y)
        return comm.allreduce(1e3 * (time.perf_counter() - t0) / repeat, op=MPI.MAX)

    out["F"] = timed(feti.F.mult)
    for kind in ("lumped", "dirichlet"):
        t0 = time.perf_counter()
        prec = make_preconditioner(kind, qp.primal)  # the default factor package
        setup = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        out[kind] = timed(prec.mult)
        out[kind + "_setup"] = setup
        prec.destroy()
    for v in (x, y):
        v.destroy()
    return out


def geomean(values) -> float:
    values = [v for v in values if v > 0 and math.isfinite(v)]
    return float(np.exp(np.mean(np.log(values)))) if values else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="*", default=None,
                        help=f"subset of {list(PROBLEMS)} (default: all)")
    parser.add_argument("--quick", action="store_true", help="only the small problems")
    parser.add_argument("--variants", nargs="*", default=None,
                        help=f"subset of {list(VARIANTS)} (default: all)")
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--repeat", type=int, default=2,
                        help="timing repeats of the small problems (min is kept)")
    parser.add_argument("--repeat-large", type=int, default=1,
                        help="timing repeats of the larger problems")
    parser.add_argument("--from-json", type=Path, default=None,
                        help="rewrite the report from a previous run's solver_variants.json")
    parser.add_argument("--out", type=Path, default=ROOT / "output/bench")
    args, _ = parser.parse_known_args()
    if args.from_json:
        data = json.loads(args.from_json.read_text())
        if P.is_root():
            report(data, args.out)
        return
    names = args.problems or [k for k, (_, small) in PROBLEMS.items()
                              if small or not args.quick]
    variants = args.variants or list(VARIANTS)
    t_start, code = time.perf_counter(), P.git_state()  # the code that runs

    results: dict[str, dict[str, dict]] = {}
    costs: dict[str, dict] = {}
    for name in names:
        problem = PROBLEMS[name][0]()
        costs[name] = application_costs(problem)
        results[name] = {}
        for v in variants:
            repeat = args.repeat if PROBLEMS[name][1] else args.repeat_large
            row = P.solve_record(problem, repeat=repeat, rtol=args.rtol,
                                 **parse_variant(v))
            results[name][v] = row
            if P.is_root():
                print(f"{name:26s} {v:26s} conv={row['converged']!s:5s} outer={row['outer']:3d} "
                      f"F={row['mults']:4d} M={row['precond']:4d} solve={row['t_solve']:.3f}s "
                      f"total={row['t_total']:.2f}s", flush=True)
    if not P.is_root():
        return
    data = {"results": results, "costs": costs, "variants": variants,
            "small": {n: PROBLEMS[n][1] for n in names}, "rtol": args.rtol,
            "repeat": [args.repeat, args.repeat_large],
            "elapsed": time.perf_counter() - t_start, "machine": P.machine(),
            "code": code, "command": " ".join(["python"] + sys.argv)}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "solver_variants.json").write_text(json.dumps(data, indent=1, default=float))
    report(data, args.out)


def modelled(r: dict, cost: dict, variant: str) -> float:
    """Seconds spent in F-multiplications and preconditioner applications (a model).

    From the measured cost of one application: insensitive to the load of a shared machine.
    """
    kind = parse_variant(variant).get("preconditioner", "none")
    t = r["mults"] * cost["F"] + (r["precond"] * cost[kind] if kind != "none" else 0.0)
    return 1e-3 * t


def report(data: dict, out: Path) -> None:
    """Write the markdown and the figure."""
    results, costs, variants = data["results"], data["costs"], data["variants"]
    small = data["small"]
    md = [f"# Solver variants (rtol = {data['rtol']:g})", "",
          f"Machine: {data['machine']}. Code: {data['code']}. Run time "
          f"{data['elapsed'] / 60:.1f} min.",
          f"Command: `{data['command']}`", "",
          "F = F-multiplications in the QP solver (the figure of merit), M = preconditioner "
          "applications, outer = SMALBE iterations; solve = preconditioner setup + iterations "
          f"[s] (min of {data['repeat'][0]} runs for the small problems, {data['repeat'][1]} "
          "for the larger ones), total = the whole df.solve [s]; model = F × (ms per F-mult) + "
          "M × (ms per application), from the costs measured alone (table below): the "
          "solver's own vector work and the load of the machine are left out.", ""]
    sizes = [[n, r["default"]["primal"], r["default"]["dual"], r["default"]["inequality"],
              r["default"]["subdomains"], f"{costs[n]['F']:.2f}", f"{costs[n]['lumped']:.2f}",
              f"{costs[n]['dirichlet']:.2f}", f"{costs[n]['dirichlet'] / costs[n]['F']:.2f}",
              f"{costs[n]['dirichlet_setup']:.2f}"]
             for n, r in results.items() if "default" in r]
    md += ["## Problems and the cost of one application", "",
           "(milliseconds, mean of 20 applications on a random vector, right after the "
           "solve)", "",
           P.md_table(["problem", "primal", "dual", "contact", "subdomains", "ms / F-mult",
                       "ms / lumped", "ms / Dirichlet", "Dirichlet / F", "Dirichlet setup [s]"],
                      sizes), ""]
    names = [n for n in results if "default" in results[n]]
    md += ["## All problems at a glance: F-mults · preconditioner applications · outer "
           "iterations (✗ = not converged)", "",
           P.md_table(["variant"] + names,
                      [[v] + [f"{results[n][v]['mults']} · {results[n][v]['precond']} · "
                              f"{results[n][v]['outer']}"
                              + ("" if results[n][v]["converged"] else " ✗") for n in names]
                       for v in variants]), "",
           "Measured solve time [s] (preconditioner setup + iterations):", "",
           P.md_table(["variant"] + names,
                      [[v] + [f"{results[n][v]['t_solve']:.3f}" for n in names]
                       for v in variants]), ""]
    for name, rows in results.items():
        md += [f"## {name}", "",
               P.md_table(["variant", "F-mults", "precond", "outer", "converged", "solve [s]",
                           "model [s]", "total [s]", "solve ms / F-mult"],
                          [[v, r["mults"], r["precond"], r["outer"], r["converged"],
                            f"{r['t_solve']:.3f}", f"{modelled(r, costs[name], v):.3f}",
                            f"{r['t_total']:.2f}",
                            f"{1e3 * r['t_solve'] / max(r['mults'], 1):.2f}"]
                           for v, r in rows.items()]), ""]
    if not all("default" in rows for rows in results.values()):
        (out / "solver_variants.md").write_text("\n".join(md) + "\n")
        return
    # Ranking: geometric mean over the problems of the ratio to the default.
    big = [n for n in results if not small[n]]
    rank = []
    for v in variants:
        res = {n: results[n][v] for n in results}
        ref = {n: results[n]["default"] for n in results}
        rank.append({
            "variant": v, "ok": all(r["converged"] for r in res.values()),
            "F": geomean([res[n]["mults"] / ref[n]["mults"] for n in results]),
            "solve": geomean([res[n]["t_solve"] / ref[n]["t_solve"] for n in results]),
            "solve_big": geomean([res[n]["t_solve"] / ref[n]["t_solve"] for n in big]),
            "model": geomean([modelled(res[n], costs[n], v)
                              / modelled(ref[n], costs[n], "default") for n in results]),
            "sum": sum(r["mults"] for r in res.values())})
    md += ["## Summary: geometric mean over the problems of the ratio to the default", "",
           "(< 1 is better; \"larger\" = the problems left out by --quick, whose solve times "
           "are not dominated by the solver's per-iteration overhead)", "",
           P.md_table(["variant", "all converged", "F-mults", "model time", "solve time",
                       "solve time, larger", "Σ F-mults"],
                      [[t["variant"], t["ok"], f"{t['F']:.2f}", f"{t['model']:.2f}",
                        f"{t['solve']:.2f}", f"{t['solve_big']:.2f}", t["sum"]]
                       for t in sorted(rank, key=lambda t: t["F"])]), ""]
    good = [t for t in rank if t["ok"]]
    best_f = min(good, key=lambda t: t["F"])
    best_m = min(good, key=lambda t: t["model"])
    best_t = min(good, key=lambda t: t["solve_big"] if big else t["solve"])
    md += [f"Fewest F-multiplications: **{best_f['variant']}** ({best_f['F']:.2f} × default). "
           f"Least modelled time: **{best_m['variant']}** ({best_m['model']:.2f}). Least "
           f"measured solve time: **{best_t['variant']}** ({best_t['solve']:.2f} over all "
           f"problems, {best_t['solve_big']:.2f} over the larger ones).", ""]
    out.mkdir(parents=True, exist_ok=True)
    (out / "solver_variants.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    plot(results, costs, variants, out / "solver_variants.png")


def plot(results: dict, costs: dict, variants: list[str], path: Path) -> None:
    """Grouped bars per problem, relative to the default: F-mults, modelled and measured time."""
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in results if "default" in results[n]]
    panels = (("F-multiplications / default", lambda r, n, v: r["mults"]),
              ("modelled time / default", lambda r, n, v: modelled(r, costs[n], v)),
              ("measured solve time / default", lambda r, n, v: r["t_solve"]))
    fig, axes = plt.subplots(len(panels), 1, figsize=(14, 10), sharex=True)
    width = 0.85 / len(variants)
    cmap = plt.get_cmap("tab20")
    for ax, (label, value) in zip(axes, panels, strict=True):
        for j, v in enumerate(variants):
            vals = [value(results[n][v], n, v) / value(results[n]["default"], n, "default")
                    for n in names]
            xs = np.arange(len(names)) + (j - (len(variants) - 1) / 2) * width
            bars = ax.bar(xs, vals, width, label=v, color=cmap(j % 20))
            for b, n in zip(bars, names, strict=True):
                if not results[n][v]["converged"]:
                    b.set_hatch("xx")
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_ylabel(label, fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    axes[-1].set_xticks(np.arange(len(names)))
    axes[-1].set_xticklabels(names, rotation=12, ha="right")
    axes[0].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    absolute = "; ".join(f"{n}: {results[n]['default']['mults']}" for n in names)
    fig.suptitle("\n".join(textwrap.wrap("F-multiplications of the default: " + absolute, 150)),
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
