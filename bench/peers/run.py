"""FETI against what users would use instead: run time against error (docs/peers.md).

    OMP_NUM_THREADS=1 .venv/bin/python bench/peers/run.py all      # every worker, then report
    OMP_NUM_THREADS=1 .venv/bin/python bench/peers/run.py worker sphere S2 snes
    OMP_NUM_THREADS=1 .venv/bin/python bench/peers/run.py all b1     # only the matching cells
    OMP_NUM_THREADS=1 .venv/bin/python bench/peers/run.py report   # tables + plots from JSON

Each worker is a fresh process (so its peak RSS is its own) that builds one mesh, assembles the
undecomposed problem, loads (or computes, the first time) the exact-constraint reference of that
mesh, times the floor (MUMPS Cholesky and CG+GAMG on the same mesh with the contact set fixed)
and then one family of methods over its tolerance / penalty sweep, each run repeated and the
minimum time kept. Results go to output/peers/raw/<problem>_<level>_<family>.json.
Problems: sphere (S1–S3), hertz (H1–H3), b1 (M1–M3); families in FAMILIES ("feti_tuned": the
setting FETI_TUNED chosen with bench/peers/feti_tuning.py).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import common as C  # noqa: E402
import methods as M  # noqa: E402

OUT = C.ROOT / "output" / "peers"
RAW = OUT / "raw"
REPEAT = int(os.environ.get("PEERS_REPEAT", "2"))  # PEERS_TOLS: e.g. "1e-6,1e-8" (S4)

FAMILIES = {"sphere": ["feti", "feti_tuned", "snes", "penalty", "by_method"],
            "hertz": ["feti", "feti_tuned", "feti_libdefault", "clarabel", "osqp", "penalty",
                      "by_method"],
            "b1": ["feti", "feti_libdefault", "clarabel", "penalty"]}
# "feti_libdefault": df.solve with the library's own default options (no preconditioner
# passed), FETI_PARTS decomposition.
TOLS = [float(t) for t in os.environ.get("PEERS_TOLS", "1e-4,1e-6,1e-8,1e-10").split(",")]
PENALTIES = [1e0, 1e2, 1e4, 1e6]  # × mean(diag K)
FETI_PARTS = {"sphere": {"S1": 4, "S2": 8, "S3": 16, "S4": 16},
              "hertz": {"H1": 4, "H2": 8, "H3": 16},
              "b1": {"M1": 32, "M2": 128, "M3": 512}}  # B1: H×H grid (C.B1_LEVELS)
#: "FETI" rows: no preconditioner, passed explicitly (the library's default up to 21741fa;
#: since be28a17 its default is lumped + stiffness scaling, the sphere's FETI_TUNED).
FETI_PRECOND = os.environ.get("PEERS_FETI_PRECOND", "none")
#: "FETI tuned": per problem, the options and Parts(k) per level chosen with
#: bench/peers/feti_tuning.py (docs/peers.md, "FETI options on the 3D sphere").
#: Sphere: the least time at S3 (output/bench/feti_tuning_S3_stiffness_21741fa.md), the same
#: setting on every level. Hertz: more, smaller subdomains without a preconditioner
#: (feti_tuning_H1_confirm.md; 16 and 32 parts tie on time, 32 needs fewer F-mults).
FETI_TUNED = {"sphere": {"preconditioner": "lumped", "preconditioner_scaling": "stiffness"},
              "hertz": {"preconditioner": "none"}}
FETI_TUNED_PARTS = {"sphere": {"S1": 4, "S2": 4, "S3": 4, "S4": 4}, "hertz": {"H1": 32}}
#: "by_method" (issue 15): every method of ``df.solve`` in one worker, beside SNES-VI (sphere,
#: Hertz) and the floor, each on Parts(k, balance="volume") (docs/benchmarks.md § 5: compact
#: subdomains on the graded meshes). "FETI-DP tuned": the options of docs/benchmarks.md § 14–15.
#: PEERS_METHODS (comma-separated labels) runs a subset.
BY_METHOD = {"TFETI": {"method": "tfeti"}, "FETI-1": {"method": "feti1"},
             "FETI-DP": {"method": "fetidp"},
             "FETI-DP tuned": {"method": "fetidp", "preconditioner": "dirichlet",
                               "mprgp_expansion": "projcg"}}
BY_METHOD_PARTS = {"sphere": 8, "hertz": 16}


def best_of(fn, repeat=REPEAT):
    """Run fn() repeat times; the result of the first with the minimum time."""
    out = None
    for _ in range(max(1, repeat)):
        r = fn()
        if out is None:
            out = r
        else:
            out["t"] = min(out["t"], r["t"])
    return out


# ------------------------------------------------------------------------------------------------
# References (exact-constraint monolithic solutions, cached per mesh)
# ------------------------------------------------------------------------------------------------


def reference(problem: str, level: str, mono, rot=None) -> dict:
    path = RAW / f"ref_{problem}_{level}.npz"
    if path.exists():
        z = np.load(path)
        return {k: z[k] for k in z.files}
    t = C.Clock()
    if problem == "sphere":
        r = M.run_snes_vi(mono, rot, rtol=1e-14)
        u, lam = r["u"], r["lam"]
    elif problem == "b1":
        C.ref.CERT_TOL = 1e-10  # M3 (132k dofs): stationarity 2.1e-12 after the SuperLU solve
        Pm = C.ref.MonolithicProblem(mono.mesh, 1, C.ref.poisson_forms(C.ref.membrane_source),
                                     dirichlet=[("dirichlet", None)],
                                     contact=("contact_left", "contact_right"), match_axes=(1,))
        assert np.array_equal(Pm.pairs.slave, mono.nodes)
        s = Pm.solve()
        u, lam = s.u.ravel(), s.lam
    else:
        # tests/support/reference.py certifies its PDAS solve to 1e-12; at 77k+ dofs the
        # stationarity of the SuperLU solve ends at ~1.2-1.7e-12: accept 1e-10 (printed below).
        C.ref.CERT_TOL = 1e-10
        Pm = C.ref.MonolithicProblem(mono.mesh, 2, C.ref.elasticity_forms(C.HERTZ_E, C.HERTZ_NU),
                                     tractions={"load": (0.0, -C.HERTZ_P / 2 / C.HERTZ_R)},
                                     dirichlet=[("bottom", None), ("symmetry", [0])],
                                     contact=("disk_contact", "block_contact"), match_axes=(0,),
                                     normal=(0.0, 1.0))
        assert np.array_equal(Pm.pairs.slave, mono.nodes)
        s = Pm.solve()
        u, lam = s.u.ravel(), s.lam
    cert = C.kkt(mono, u, lam)
    print(f"reference {problem} {level}: {t():.1f} s, KKT {cert}", flush=True)
    RAW.mkdir(parents=True, exist_ok=True)
    np.savez(path, u=u, lam=lam)
    return {"u": u, "lam": lam}


def metrics(problem: str, mono, ref: dict, u: np.ndarray, lam: np.ndarray) -> dict:
    umax = np.abs(ref["u"]).max()
    out = {"err_u": float(np.abs(u - ref["u"]).max() / umax)}
    if problem == "sphere":
        F, F_ref = 4 * float(np.sum(lam)), 4 * float(np.sum(ref["lam"]))
        out.update(F=F, F_ref=F_ref, err_F=abs(F - F_ref) / F_ref,
                   err_F_hertz=abs(F - C.SPHERE_F) / C.SPHERE_F)
    elif problem == "b1":
        F, F_ref = float(np.sum(lam)), float(np.sum(ref["lam"]))
        out.update(F=F, F_ref=F_ref, err_F=abs(F - F_ref) / F_ref)
    else:
        F, F_ref = 2 * float(np.sum(lam)), 2 * float(np.sum(ref["lam"]))
        out.update(F=F, F_ref=F_ref, err_F=abs(F - F_ref) / F_ref)
    out["err_lam"] = float(np.abs(lam - ref["lam"]).max() / np.abs(ref["lam"]).max())
    out["err"] = max(out["err_u"], out["err_lam"])
    return out


# ------------------------------------------------------------------------------------------------
# FETI
# ------------------------------------------------------------------------------------------------


def run_feti(problem: str, level: str, mono, rtol: float, parts: int, precond: str | None,
             balance: str = "cells", **options) -> dict:
    import dolfinx_feti as df

    if problem == "b1":
        prob = C.b1_problem(level)
    else:
        prob = (C.sphere_problem if problem == "sphere" else C.hertz_problem)(level, parts,
                                                                              balance)
    if precond is not None:
        options.setdefault("preconditioner", precond)
    t = C.Clock()
    sol = df.solve(prob, rtol=rtol, **options)
    elapsed = t()
    u = sol.nodal_values().ravel()
    ct = sol.contact
    lam = np.zeros(mono.nodes.size)
    pos = {int(n): i for i, n in enumerate(mono.nodes)}
    for n, fval in zip(ct.node, ct.force, strict=True):
        lam[pos[int(n)]] = fval
    r = sol.report
    out = {"t": elapsed, "its": r.iterations, "outer": r.outer_iterations,
           "mults": r.hessian_mults, "mults_total": r.hessian_mults_total,
           "converged": bool(r.converged), "timings": dict(r.timings), "u": u, "lam": lam,
           "parts": parts, "balance": balance, "method_used": r.method,
           "subdomains": r.sizes.get("subdomains"),
           "precond": options.get("preconditioner", "library default"),
           "options": options,
           "primal": r.sizes["primal"],
           "dual": r.sizes["dual"]}
    del sol
    return out


# ------------------------------------------------------------------------------------------------
# Worker
# ------------------------------------------------------------------------------------------------


def worker(problem: str, level: str, family: str) -> None:
    rss0 = C.maxrss_mib()
    t = C.Clock()
    if problem == "sphere":
        mono = C.sphere_monolithic(level)
        rot = M.Rotated(mono)
    elif problem == "b1":
        mono, rot = C.b1_monolithic(level), None
    else:
        mono = C.hertz_monolithic(level)
        rot = M.Relative(mono)
    t_assemble = t()
    ref = reference(problem, level, mono, rot)
    rss_base = C.maxrss_mib()
    rows = []

    def record(method, param, r):
        row = {"method": method, "param": param, "t": r["t"],
               **{k: v for k, v in r.items() if k not in ("u", "lam", "t")}}
        row.update(metrics(problem, mono, ref, r["u"], r["lam"]))
        row["rss_peak_mib"] = C.maxrss_mib()
        rows.append(row)
        print(f"{problem} {level} {method} {param}: t = {r['t']:.3f} s, err = {row['err']:.2e}, "
              f"err_F = {row['err_F']:.2e}", flush=True)

    if family == "feti":
        parts = FETI_PARTS[problem][level]
        for tol in TOLS:
            record("FETI", tol, best_of(lambda tol=tol: run_feti(problem, level, mono, tol, parts,
                                                         FETI_PRECOND)))
    elif family == "feti_libdefault":
        parts = FETI_PARTS[problem][level]
        for tol in TOLS:
            record("FETI lib default", tol, best_of(
                lambda tol=tol: run_feti(problem, level, mono, tol, parts, None)))
    elif family == "feti_tuned":
        parts, opts = FETI_TUNED_PARTS[problem][level], FETI_TUNED[problem]
        for tol in TOLS:
            record("FETI tuned", tol, best_of(lambda tol=tol: run_feti(
                problem, level, mono, tol, parts, opts["preconditioner"], **dict(opts))))
    elif family == "by_method":
        parts = BY_METHOD_PARTS[problem]
        labels = os.environ.get("PEERS_METHODS", ",".join(BY_METHOD)).split(",")
        for tol in TOLS:
            if rot is not None:
                record("SNES-VI", tol, best_of(lambda tol=tol: M.run_snes_vi(mono, rot, tol)))
            for label in labels:
                record(label, tol, best_of(lambda tol=tol, o=BY_METHOD[label]: run_feti(
                    problem, level, mono, tol, parts, None, "volume", **o)))
    elif family == "snes":
        for tol in TOLS:
            record("SNES-VI", tol, best_of(lambda tol=tol: M.run_snes_vi(mono, rot, tol)))
    elif family == "penalty":
        kbar = float(np.mean(mono.K.diagonal()))
        for p in PENALTIES:
            record("penalty", p, best_of(lambda p=p: M.run_penalty(mono, p * kbar), repeat=1))
    elif family == "clarabel":
        for tol in TOLS:
            record("Clarabel", tol, best_of(lambda tol=tol: M.run_clarabel(mono, tol)))
    elif family == "osqp":
        for tol in [1e-3, 1e-4, 1e-5]:
            record("OSQP", tol, best_of(lambda tol=tol: M.run_osqp(mono, tol), repeat=1))
    else:
        raise ValueError(family)
    rss_method = C.maxrss_mib()

    # The floor, after the method (so the method's peak RSS is its own), same process.
    floors = {}
    for how in ("mumps", "gamg"):
        def one(how=how):
            if problem == "sphere":
                active = ref["lam"] > 0
                r = M.floor_sphere(mono, ref["u"], active, how)
            else:
                r = M.floor_glued(mono, how)
            return r
        r = best_of(one)
        floors[how] = {k: v for k, v in r.items() if k != "u"}
    for row in rows:
        row["ratio_mumps"] = row["t"] / floors["mumps"]["t"]
        row["ratio_gamg"] = row["t"] / floors["gamg"]["t"]
    data = {"problem": problem, "level": level, "family": family, "ndofs": mono.ndofs,
            "ncontact": int(mono.nodes.size), "t_assemble": t_assemble, "rss_start": rss0,
            "rss_base": rss_base, "rss_method": rss_method, "floor": floors, "rows": rows,
            "machine": C.P.machine(), "code": C.code_state(),
            "feti_module": str(Path(sys.modules["dolfinx_feti"].__file__).parent)
            if "dolfinx_feti" in sys.modules else None}
    RAW.mkdir(parents=True, exist_ok=True)
    (RAW / f"{problem}_{level}_{family}.json").write_text(json.dumps(data, indent=1,
                                                                     default=float))
    print(f"floor: mumps {floors['mumps']['t']:.3f} s, gamg {floors['gamg']['t']:.3f} s "
          f"({floors['gamg']['its']} its); dofs {mono.ndofs}", flush=True)


def run_all(only: list[str]) -> None:
    env = dict(os.environ, OMP_NUM_THREADS="1")
    for problem, levels in (("sphere", C.SPHERE_LEVELS), ("hertz", C.HERTZ_LEVELS),
                            ("b1", C.B1_LEVELS)):
        for level in levels:
            for family in FAMILIES[problem]:
                tag = f"{problem}_{level}_{family}"
                if only and not any(o in tag for o in only):
                    continue
                print(f"== {tag}", flush=True)
                subprocess.run([sys.executable, __file__, "worker", problem, level, family],
                               env=env, check=False)


if __name__ == "__main__":
    cmd = sys.argv[1]
    if cmd == "worker":
        worker(*sys.argv[2:5])
    elif cmd == "all":
        run_all(sys.argv[2:])
        import report
        report.main()
    elif cmd == "report":
        import report
        report.main()
