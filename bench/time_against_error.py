"""Run time against error: every method, method="auto", SNES VI and the linear floors (issue 24).

For each case — 2D Hertz H1–H3 (mortar contact, the library's dual-mortar rows), the 3D rigid
sphere S3/S4 of docs/peers.md, the graded DOLFINx box of bench/graded_box.py (a user's own
``create_box`` mesh through ``df.from_dolfinx``, a rigid sphere pressed in) at ``boxN`` = N
cells a side — one process runs back to back:

- the exact discrete reference: SNES VI (vinewtonrsls + MUMPS) at rtol 1e-10 on the same
  discrete constraint (the contact rows turned into bounds, bench/exact_discrete.py; an
  active-set method, exact once its set is right), with its KKT residuals;
- each FETI configuration (``tfeti``, ``feti1``, ``fetidp`` and ``auto`` = method="auto", all on
  the default decomposition ``df.Auto()``) at each rtol: the wall time of ``df.solve`` from the
  ContactProblem (decomposition, subdomain assembly, factorizations, iterations, recovery),
  the error in u and in the nodal contact forces against the reference (max norms, relative to
  the largest value), the F-multiplications;
- SNES VI at the same rtols (time from the assembled undecomposed matrices; the monolithic
  assembly is given separately);
- the floors: MUMPS Cholesky and CG + GAMG (rigid-body near-null space, rtol 1e-10) of the same
  system with the reference's active set fixed.

Each configuration runs ``--repeat`` times when one run takes less than ``--cheap`` seconds and
the median is reported (once otherwise). Under ``mpirun -n 2`` everything runs on the 2 ranks
(the PETSc solves on distributed matrices). Writes ``<out>.md``, ``<out>.json`` and
``<out>.png`` (time against error per case and method).

    python bench/time_against_error.py --cases H1 --rtols 1e-6            # smallest, ~1 min
    python bench/time_against_error.py --merge a.json,b.json --out output/bench/tae_all
    python bench/time_against_error.py --cases H1,H2,H3,S3,S4,box31
    mpirun -n 2 python bench/time_against_error.py --cases H1,S3 --out output/bench/tae_np2
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

import dolfinx_feti as df

HERE = Path(__file__).resolve().parent
for _p in (HERE, HERE / "peers"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))
import common as C  # noqa: E402  (bench/peers/common.py: meshes, tests/support/reference.py)
import exact_discrete as X  # noqa: E402
import graded_box as G  # noqa: E402

import problems as P  # noqa: E402

ROOT = HERE.parent
FETI = {"tfeti": {"method": "tfeti"}, "feti1": {"method": "feti1"},
        "fetidp": {"method": "fetidp"}, "auto": {"method": "auto"}}
FLOORS = ("mumps", "gamg")
HERTZ_E, HERTZ_NU, HERTZ_R, HERTZ_P = 200.0, 0.3, 8.0, 10.0
#: The reference: SNES VI at this rtol, accepted when its KKT residuals (relative, :func:`kkt`)
#: are at most REF_KKT whatever SNES's reason (on 2D Hertz rtol 1e-14 ends in a failed line
#: search, 1e-12 at its iteration limit on H2, both with the KKT residuals at round-off).
REF_RTOL, REF_KKT = 1e-10, 1e-10


class Case:
    """A FETI problem and the same discrete problem undecomposed (K, f, Dirichlet, rows)."""

    name: str
    problem: df.ContactProblem
    bounded: X.Bounded
    scale: np.ndarray  # physical force of row i = scale_i · λ_i (mortar rows are scaled)
    start_closed: bool = False
    t_assemble: float = 0.0

    @property
    def ndofs(self) -> int:
        return int(self.bounded.b.size)


def _obstacle_rows(mesh, group: str, obstacle) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """−n·u <= φ at every node of ``group`` (the linearized rows of df.RigidObstacle)."""
    nodes = np.unique(mesh.facet_groups[group])
    phi, n = obstacle.distance(mesh.x[nodes])
    m, bs = nodes.size, mesh.gdim
    B = sp.csr_matrix((-n.ravel(), (np.repeat(np.arange(m), bs),
                                    (bs * nodes[:, None] + np.arange(bs)).ravel())),
                      shape=(m, bs * mesh.num_nodes))
    return B, phi, nodes


def _elastic(mesh, E: float, nu: float, dirichlet, tractions=None):
    K, f = C.ref.assemble(mesh, mesh.gdim, C.ref.elasticity_forms(E, nu))
    for group, t in (tractions or {}).items():
        f = f + C.ref.traction_load(mesh, group, t)
    return K, f, C.ref.dirichlet_dofs(mesh, mesh.gdim, dirichlet)


SPHERE_BC = [("bottom", None), ("symmetry_x", [0]), ("symmetry_y", [1])]


def _feti_dirichlet(bc) -> list:
    return [df.Dirichlet(g) if c is None else df.Dirichlet(g, components=c) for g, c in bc]


def sphere_case(level: str) -> Case:
    c = Case()
    c.name = level
    t = time.perf_counter()
    mesh = C.sphere_mesh(level)
    obst = C.sphere_obstacle()
    c.problem = df.ContactProblem(mesh, df.Elasticity(C.SPHERE_E, C.SPHERE_NU),
                                  dirichlet=_feti_dirichlet(SPHERE_BC),
                                  contact=[df.RigidObstacle("top", obst)],
                                  decomposition=df.Auto())
    K, f, fixed = _elastic(mesh, C.SPHERE_E, C.SPHERE_NU, SPHERE_BC)
    B, g, nodes = _obstacle_rows(mesh, "top", obst)
    c.bounded = X.Bounded(K, f, fixed, B, g, nodes, 3, mesh.x)
    c.scale = np.ones(nodes.size)
    c.t_assemble = time.perf_counter() - t
    return c


def box_case(n: int) -> Case:
    c = Case()
    c.name = f"box{n}"
    t = time.perf_counter()
    c.problem = G.box_problem(n, decomposition=df.Auto())
    mesh = c.problem.mesh
    obst = df.Sphere(center=(0.0, 0.0, 1.0 + G.RADIUS - G.DEPTH), radius=G.RADIUS)
    K, f, fixed = _elastic(mesh, 10.0, 0.3, SPHERE_BC)
    B, g, nodes = _obstacle_rows(mesh, "top", obst)
    c.bounded = X.Bounded(K, f, fixed, B, g, nodes, 3, mesh.x)
    c.scale = np.ones(nodes.size)
    c.t_assemble = time.perf_counter() - t
    return c


def hertz_case(level: str) -> Case:
    from dolfinx_feti.constraints.mortar_rows import mortar_contact_rows

    c = Case()
    c.name = level
    t = time.perf_counter()
    mesh = P.hertz2d_mesh(*C.HERTZ_LEVELS[level])
    load = {"load": (0.0, -HERTZ_P / 2 / HERTZ_R)}
    bc = [("bottom", None), ("symmetry", [0])]
    spec = df.Mortar(slave="disk_contact", master="block_contact")
    c.problem = df.ContactProblem(mesh, df.Elasticity(HERTZ_E, HERTZ_NU, tractions=load),
                                  dirichlet=_feti_dirichlet(bc), contact=[spec],
                                  decomposition=df.Auto())
    K, f, fixed = _elastic(mesh, HERTZ_E, HERTZ_NU, bc, load)
    N = mesh.num_nodes
    rows, _ = mortar_contact_rows(mesh, spec, 0, np.arange(N + 1), np.zeros(N, np.int32), 2)
    B = sp.csr_matrix((rows.e_coef, (rows.e_row, 2 * rows.e_node + rows.e_comp)),
                      shape=(rows.size, 2 * N))
    c.bounded = X.Bounded(K, f, fixed, B, rows.rhs, rows.node, 2, mesh.x)
    c.scale = rows.scale
    c.start_closed = True  # the disk is held by the contact alone
    c.t_assemble = time.perf_counter() - t
    return c


def make_case(name: str) -> Case:
    if name in C.HERTZ_LEVELS:
        return hertz_case(name)
    if name in C.SPHERE_LEVELS:
        return sphere_case(name)
    if name.startswith("box"):
        return box_case(int(name[3:]))
    raise SystemExit(f"unknown case {name!r}: H1-H3, S1-S4 or boxN")


def kkt(case: Case, w: np.ndarray) -> dict:
    """The reference's KKT residuals in w: stationarity off the bounds, bounds, sign of λ.

    Relative to the largest load or contact force (stationarity, sign), to max |w| (bounds)
    and to their product (complementarity).
    """
    bp = case.bounded
    grad = bp.A @ w - bp.b
    free = np.ones(grad.size, dtype=bool)
    free[bp.zpos] = False
    gz = grad[bp.zpos]
    slack = w[bp.zpos] - bp.lower[bp.zpos]
    scale = max(np.abs(bp.b).max(), np.abs(gz).max())  # the load, or the contact forces
    return {"stationarity": float(np.abs(grad[free]).max() / scale),
            "feasibility": float(max(-slack.min(), 0.0) / np.abs(w).max()),
            "sign": float(max(-gz.min(), 0.0) / scale),
            "complementarity": float(np.abs(gz * slack).max() / (scale * np.abs(w).max()))}


def reference(case: Case, out: Path, comm) -> dict:
    path = out.parent / f"tae_ref_{case.name}.npz"
    if path.exists():
        z = np.load(path)
        return {"w": z["w"], "u": z["u"], "lam": z["lam"], "t": float(z["t"]),
                "its": int(z["its"]) if "its" in z.files else -1,
                "reason": int(z["reason"]) if "reason" in z.files else 0,
                "kkt": json.loads(str(z["kkt"]))}
    r = X.snes_vi(case.bounded, REF_RTOL, comm, case.start_closed)
    cert = kkt(case, r["w"])
    if max(cert.values()) > REF_KKT:
        raise RuntimeError(f"{case.name}: the reference SNES VI failed (reason {r['reason']}, "
                           f"KKT {cert})")
    if comm.rank == 0:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, w=r["w"], u=r["u"], lam=r["lam"], t=r["t"], its=r["its"],
                 reason=r["reason"], kkt=json.dumps(cert))
    return {**r, "kkt": cert}


def errors(case: Case, ref: dict, u: np.ndarray, node: np.ndarray, force: np.ndarray) -> dict:
    """Relative max-norm errors of u and of the nodal contact forces against the reference."""
    err_u = float(np.abs(u - ref["u"]).max() / np.abs(ref["u"]).max())
    f_ref = case.scale * ref["lam"]
    pos = -np.ones(int(case.bounded.pivot.max()) + 1, dtype=np.int64)
    pos[case.bounded.pivot] = np.arange(case.bounded.pivot.size)
    f = np.zeros(f_ref.size)
    if np.any(pos[node] < 0):
        raise RuntimeError(f"{case.name}: a FETI contact row at a node with no reference row")
    f[pos[node]] = force
    err_f = float(np.abs(f - f_ref).max() / np.abs(f_ref).max())
    return {"err_u": err_u, "err_f": err_f, "err": max(err_u, err_f)}


def timed(fn, repeat: int, cheap: float) -> tuple[dict, list[float]]:
    """fn() once, again up to ``repeat`` times if it took < ``cheap`` s; (last result, times)."""
    r = fn()
    times = [r["t"]]
    while len(times) < repeat and times[0] < cheap:
        r = fn()
        times.append(r["t"])
    return r, times


def run_feti(case: Case, rtol: float, comm, options: dict) -> dict:
    comm.Barrier()
    t0 = time.perf_counter()
    sol = df.solve(case.problem, comm=comm, rtol=rtol, **options)
    u = sol.nodal_values().ravel()
    ct = sol.contact
    t = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    rep = sol.report
    out = {"t": t, "u": u, "node": np.asarray(ct.node), "force": np.asarray(ct.force),
           "mults": int(rep.hessian_mults), "outer": int(rep.outer_iterations),
           "method_used": rep.method, "subdomains": rep.sizes.get("subdomains"),
           "converged": bool(rep.converged), "max_kkt": float(max(rep.kkt.values()))
           if getattr(rep, "kkt", None) else None}
    del sol
    return out


def run_case(name: str, configs: list[str], rtols: list[float], args, comm, log) -> dict:
    case = make_case(name)
    log(f"== {name}: {case.ndofs} free dofs, {case.bounded.m} contact rows, monolithic "
        f"assembly {case.t_assemble:.1f} s, load {os.getloadavg()[0]:.1f}")
    ref = reference(case, Path(args.out), comm)
    log(f"   reference (SNES VI, rtol {REF_RTOL:.0e}): {ref['t']:.1f} s, KKT {ref['kkt']}")
    rows = []
    floors = {}
    for cfg in configs:
        if cfg in FLOORS:
            r, times = timed(lambda cfg=cfg: X.floor(case.bounded, ref["w"], cfg, comm),
                             args.repeat, args.cheap)
            floors[cfg] = float(np.median(times))
            rows.append({"case": name, "config": cfg, "rtol": None, "t": floors[cfg],
                         "times": times, "its": r["its"], "dev": r["dev"],
                         "ndofs_floor": r["ndofs"]})
            log(f"   floor {cfg}: {floors[cfg]:.2f} s ({len(times)} runs), {r['its']} its")
            continue
        if cfg == "snes" and args.snes_ref:  # the reference run is the SNES VI row
            rows.append({"case": name, "config": cfg, "rtol": REF_RTOL, "t": float(ref["t"]),
                         "times": [float(ref["t"])], "err_u": 0.0, "err_f": 0.0, "err": 0.0,
                         "its": int(ref.get("its", -1)), "reason": int(ref.get("reason", 0))})
            continue
        for rtol in rtols:
            if cfg == "snes":
                r, times = timed(lambda rtol=rtol: X.snes_vi(case.bounded, rtol, comm,
                                                             case.start_closed),
                                 args.repeat, args.cheap)
                e = {"err_u": float(np.abs(r["u"] - ref["u"]).max() / np.abs(ref["u"]).max()),
                     "err_f": float(np.abs(r["lam"] - ref["lam"]).max()
                                    / np.abs(ref["lam"]).max())}
                e["err"] = max(e["err_u"], e["err_f"])
                extra = {"its": r["its"], "reason": r["reason"]}
            else:
                r, times = timed(lambda rtol=rtol, cfg=cfg: run_feti(case, rtol, comm,
                                                                     FETI[cfg]),
                                 args.repeat, args.cheap)
                e = errors(case, ref, r["u"], r["node"], r["force"])
                extra = {k: r[k] for k in ("mults", "outer", "method_used", "subdomains",
                                           "converged", "max_kkt")}
            row = {"case": name, "config": cfg, "rtol": rtol, "t": float(np.median(times)),
                   "times": times, **e, **extra}
            rows.append(row)
            log(f"   {cfg:6s} rtol {rtol:.0e}: {row['t']:.2f} s ({len(times)} runs), err u "
                f"{e['err_u']:.1e} f {e['err_f']:.1e}  {extra}")
    best = min(floors.values()) if floors else None
    for row in rows:
        row["x_floor"] = row["t"] / best if best else None
    return {"case": name, "ndofs": case.ndofs, "rows_contact": int(case.bounded.m),
            "t_assemble": case.t_assemble, "ref_t": float(ref["t"]), "ref_kkt": ref["kkt"],
            "floors": floors, "rows": rows}


def markdown(results: list[dict], ranks: int, load: list[float]) -> str:
    out = [f"{ranks} rank(s); load average (1 min) during the runs {min(load):.1f}–"
           f"{max(load):.1f}; time = median wall time [s] (runs), error = max(u, f) "
           "relative max-norm against SNES VI at rtol 1e-10 (KKT residuals at round-off)", "",
           "| case | free dofs | config | rtol | time [s] (runs) | ÷ best floor | error u | "
           "error f | F-mults | method / subdomains |", "|---|---|---|---|---|---|---|---|---|---|"]
    for res in results:
        for r in res["rows"]:
            rt = "–" if r["rtol"] is None else f"{r['rtol']:.0e}"
            xf = "–" if r["x_floor"] is None else f"{r['x_floor']:.1f}×"
            if r["rtol"] is None:
                eu = ef = "–"
            else:
                eu, ef = f"{r['err_u']:.1e}", f"{r['err_f']:.1e}"
            mult = r.get("mults", r.get("its", ""))
            how = (f"{r['method_used']} / {r['subdomains']}" if "method_used" in r else
                   ("Newton its" if r["config"] == "snes" else "CG its" if r["config"] == "gamg"
                    else ""))
            out.append(f"| {res['case']} | {res['ndofs']} | {r['config']} | {rt} | "
                       f"{r['t']:.2f} ({len(r['times'])}) | {xf} | {eu} | {ef} | {mult} | "
                       f"{how} |")
    return "\n".join(out)


def condensed(results: list[dict]) -> str:
    """One row per case and configuration: each rtol's time (÷ best floor), errors, counts."""
    rtols = sorted({r["rtol"] for res in results for r in res["rows"]
                    if r["rtol"] is not None and r["config"] != "snes"}, reverse=True)
    head = "| case | free dofs | floors MUMPS / GAMG [s] | config | " + " | ".join(
        f"rtol {t:.0e}: s (÷ floor), error u / f, F" for t in rtols) + " |"
    out = [head, "|---|---|---|---|" + "---|" * len(rtols)]
    for res in results:
        fl = " / ".join(f"{res['floors'][k]:.2f}" if k in res["floors"] else "–"
                        for k in FLOORS)
        for cfg in [c for c in (*FETI, "snes") if any(r["config"] == c for r in res["rows"])]:
            cells = []
            for t in rtols:
                if not any(r["rtol"] == t for r in res["rows"] if r["config"] in FETI):
                    cells.append("–")  # this rtol was not run on this case
                    continue
                rs = [r for r in res["rows"] if r["config"] == cfg and (
                    r["rtol"] == t or (cfg == "snes" and r["rtol"] is not None))]
                if cfg == "snes":
                    rs = sorted(rs, key=lambda r: abs(np.log(r["rtol"] / t)))[:1]
                if not rs:
                    cells.append("–")
                    continue
                r = rs[0]
                xf = f" ({r['x_floor']:.1f}×)" if r.get("x_floor") else ""
                cnt = (f"{r['its']} Newton" if cfg == "snes" else
                       f"{r['mults']} ({r['method_used']}, {r['subdomains']} sub.)")
                rt = f" [rtol {r['rtol']:.0e}]" if cfg == "snes" and r["rtol"] != t else ""
                cells.append(f"{r['t']:.2f}{xf}, {r['err_u']:.1e} / {r['err_f']:.1e}, "
                             f"{cnt}{rt}")
            out.append(f"| {res['case']} | {res['ndofs']} | {fl} | {cfg} | "
                       + " | ".join(cells) + " |")
    return "\n".join(out)


def merge(paths: list[str], out: Path) -> None:
    """The results of several runs (same rank count) as one table and one plot."""
    results, loads, ranks = [], [], set()
    for p in paths:
        data = json.loads(Path(p).read_text())
        results += data["results"]
        loads += data["meta"]["load"]
        ranks.add(data["meta"]["ranks"])
    text = (f"{'/'.join(map(str, sorted(ranks)))} rank(s), load average (1 min) "
            f"{min(loads):.1f}–{max(loads):.1f}\n\n" + condensed(results))
    out.with_suffix(".md").write_text(text + "\n")
    plot(results, out.with_suffix(".png"))
    print(text)


def plot(results: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(results)
    ncol = min(n, 4)
    nrow = -(-n // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.8 * nrow), squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    marks = {"tfeti": "o-", "feti1": "s-", "fetidp": "^-", "auto": "D-", "snes": "x"}
    for ax, res in zip(axes.ravel(), results, strict=False):
        for cfg, mk in marks.items():
            pts = [(r["err"], r["t"]) for r in res["rows"] if r["config"] == cfg]
            if pts:
                e, t = zip(*sorted(pts), strict=True)
                ax.loglog(np.maximum(e, 1e-14), t, mk, label=cfg)
        for cfg, ls in (("mumps", "--"), ("gamg", ":")):
            if cfg in res["floors"]:
                ax.axhline(res["floors"][cfg], ls=ls, color="k", label=f"{cfg} floor")
        ax.set_title(f"{res['case']} ({res['ndofs']} dofs)")
        ax.set_xlabel("error max(u, f)")
        ax.set_ylabel("wall time [s]")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="H1")
    ap.add_argument("--configs", default="tfeti,feti1,fetidp,auto,snes,mumps,gamg")
    ap.add_argument("--rtols", default="1e-6,1e-8")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cheap", type=float, default=20.0,
                    help="repeat a configuration only when one run takes less (s)")
    ap.add_argument("--snes-ref", action="store_true",
                    help="the SNES VI row is the reference's run (a large case: one SNES VI)")
    ap.add_argument("--out", default=str(ROOT / "output" / "bench" / "time_against_error"))
    ap.add_argument("--merge", default=None,
                    help="comma-separated JSON files of earlier runs: one table and plot")
    args = ap.parse_args()
    if args.merge:
        merge(args.merge.split(","), Path(args.out))
        return
    comm = MPI.COMM_WORLD
    out = Path(args.out)
    if comm.size > 1 and not args.out.endswith(f"_np{comm.size}"):
        out = out.with_name(out.name + f"_np{comm.size}")
        args.out = str(out)
    load = []

    def log(msg: str) -> None:
        load.append(os.getloadavg()[0])
        if comm.rank == 0:
            print(msg, flush=True)

    results = []
    for name in args.cases.split(","):
        results.append(run_case(name, args.configs.split(","),
                                [float(r) for r in args.rtols.split(",")], args, comm, log))
        if comm.rank == 0:  # after every case, so that a long sweep leaves what it measured
            out.parent.mkdir(parents=True, exist_ok=True)
            meta = {"ranks": comm.size, "load": load, "machine": P.machine(),
                    "code": P.git_state(), "args": vars(args)}
            out.with_suffix(".json").write_text(json.dumps({"meta": meta, "results": results},
                                                           indent=1, default=float))
            out.with_suffix(".md").write_text(markdown(results, comm.size, load) + "\n")
            plot(results, out.with_suffix(".png"))
    if comm.rank == 0:
        print(markdown(results, comm.size, load))


if __name__ == "__main__":
    main()
