"""Hessian-multiplication counts of MPRGP/MPGP on a fixed set of problems.

The figures of merit of the one MPGP loop (:mod:`dolfinx_feti.qp.mpgp`) that replaced the two
near-copies of MPRGP and MPGP: run it on two versions and compare the JSON files.

    python bench/mpgp_counts.py output/bench/mpgp_counts.json

Problems: random box QPs (every expansion variant of MPRGP, and MPGP on the same boxes), two
obstacle problems, random disc QPs (MPGP, both face rules), and FETI solves (B1, 2D Hertz, 2D
and 3D Tresca; Total FETI and FETI-DP; no and lumped preconditioner).
"""
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests/qp"))
for _d in ("support", "problems", "drivers"):
    sys.path.insert(0, str(ROOT / "tests" / _d))
import numpy as np  # noqa: E402
from qp_helpers import make_mat, make_vec, obstacle, random_spd  # noqa: E402
from test_qp_mpgp import disc_problem, local_discs  # noqa: E402

import dolfinx_feti as df  # noqa: E402
from dolfinx_feti.io import meshes  # noqa: E402
from dolfinx_feti.qp import mpgp, mprgp  # noqa: E402

out = {}
# box problems through mprgp, every variant
for seed in range(4):
    rng = np.random.default_rng(seed)
    n = 200
    A = random_spd(n, rng, cond=1e3)
    b = 3 * rng.standard_normal(n)
    l, u = np.full(n, -0.3), np.full(n, 0.4)
    for exp, alpha in (("fixed", "fixed"), ("optimal", "fixed"), ("projcg", "fixed"),
                       ("fixed", "bb")):
        x = make_vec(np.zeros(n))
        r = mprgp(make_mat(A), make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=1e-10,
                  expansion=exp, alpha=alpha)
        out[f"box{seed}-{exp}-{alpha}"] = r.hessian_mults
    # the same box through mpgp (intervals only)
    x = make_vec(np.zeros(n))
    r = mpgp(make_mat(A), make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=1e-10)
    out[f"box{seed}-mpgp"] = r.hessian_mults
# obstacle problems
for k in (10, 20):
    A, b, l, _ = obstacle(k)
    x = make_vec(np.zeros(b.size))
    r = mprgp(make_mat(A), make_vec(b), x, lb=make_vec(l), rtol=1e-10)
    out[f"obstacle{k}"] = r.hessian_mults
# disc problems
for seed in range(3):
    for mixed in (False, True):
        for face in ("tangent", "interior"):
            A, b, lb, ub, pairs, centre, radius = disc_problem(seed, mixed=mixed)
            Am, bv = make_mat(A), make_vec(b)
            x = bv.duplicate()
            x.set(0.0)
            r = mpgp(Am, bv, x, lb=make_vec(lb), ub=make_vec(ub),
                     discs=local_discs(x, pairs, centre, radius), rtol=1e-10, face=face)
            out[f"disc{seed}-{mixed}-{face}"] = r.hessian_mults
# the solver on FETI problems
import test_b1_membranes as tb  # noqa: E402
import test_friction as f2  # noqa: E402
import test_friction3d as f3  # noqa: E402
import test_hertz2d as h2  # noqa: E402

mesh = df.read_gmsh("meshes/membranes_16.msh")
mh = df.read_gmsh("meshes/hertz2d.msh")
mf = df.build_mesh(meshes.tresca2d, n=6)
mf3 = df.build_mesh(meshes.blocks3d, n=3)
cases = {"b1-grid4": tb.problem(mesh, tb.grid(0.25)),
         "hertz-p6": h2.problem(mh, df.Parts(6)),
         "tresca2d-p4": f2.b4(mf, df.Tresca(f2.G), df.Parts(4)),
         "tresca3d-p3": f3.blocks(mf3, df.Tresca(f3.G), df.Parts(3)),
         "tresca3d-p2": f3.blocks(mf3, df.Tresca(f3.G))}
for name, p in cases.items():
    for m in ("tfeti", "fetidp"):
        for pre in ("none", "lumped"):
            s = df.solve(p, rtol=1e-8, method=m, preconditioner=pre)
            out[f"{name}-{m}-{pre}"] = s.report.hessian_mults
Path(sys.argv[1]).parent.mkdir(parents=True, exist_ok=True)
Path(sys.argv[1]).write_text(json.dumps(out, indent=0))
print(len(out), "cases, total", sum(out.values()))
