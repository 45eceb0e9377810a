"""Where the first warm step of a 3D load path spends its F-multiplications (issue 22).

The pushed block of ``bench/load_path.py`` (``--case pushed3d``: the sphere held, the block's
bottom pushed up; FETI-DP, MPRGP alone on F): set up and solve at load 1, ``update`` to 1.1,
and solve the second case warm in several variants, each from the same saved state (the
multipliers, the predictor's data and the recycled store of the first solve). Per variant:
the F-multiplications, the step counts, and for every iterate of the warm solve

- the KKT stop's in-iteration bound (the weighted projected gradient against its tolerance)
  and the exact physical check of the recovered solution at that iterate (made afterwards,
  so the counts are the solve's own): the first iterate at which the check would pass;
- ``‖gᴾ‖ / ‖b‖`` and the step's kind (the faces: restarts after expansions);
- the error against the solution of the second case (solved to rtol 1e-10) in the F-energy
  norm, on the gluing rows and on the contact rows.

Variants (``--variants``): ``base`` (today's warm solve); ``last:N`` (the store cut to the
directions of the first solve's last N faces); ``first:N`` (without its last N faces);
``empty`` (no recycled directions); ``fit`` (the start's Galerkin fit over span{λ_last, W}:
the last solution enters the store as one more column, its product counted once). Flags
joined by ``+`` (``base+own``): ``own`` (this solve's CG directions join the store at each new
face), ``gamma=G`` (MPRGP's Γ for the warm solve), ``noratio`` (the KKT bound's force part
against the QP's rows alone, as before the calibration), ``nogradient`` (MPRGP's first
product its own gradient, as before the warm start handed it over); the prototypes of history
§ 39: ``pprop`` (MPRGP's proportioning step along the lumped preconditioner's M⁻¹β instead of
β; ``pprop=g``: along M⁻¹gᴾ; ``--pprop b|g`` in every solve, the first one too), ``ring1`` /
``ring2`` (the warm solve's first step a projected Galerkin fit over the store and the start's
chopped gradient β, and M⁻¹β, each column's product counted).

``--record-steps``: every solve also stores the moves of its expansions and proportioning
steps with their products (the difference of the gradients: no product), ``--room K`` the
store's room for the first solve, ``--preconditioner`` the FETI preconditioner of every
solve. ``--load-path ARGS`` runs ``bench/load_path.py ARGS`` with
the prototypes of ``--pprop`` (``--warm-only``: in warm solves alone) and ``--record-steps``
patched in.

Run (one process, a few minutes): ``python bench/first_warm.py``; writes
``output/bench/first_warm.json`` and prints the tables.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.drivers import kkt_stop, qp_solve
from dolfinx_feti.qp import mpgp_steps

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "peers"))
import common as C  # noqa: E402
from load_path import pushed3d  # noqa: E402
from reuse import sphere3d  # noqa: E402

ROOT = HERE.parent

# --- recorders ------------------------------------------------------------------------------
REC: dict = {"tests": [], "runs": []}
_make_test = kkt_stop.KKTStop.make_test
_init = kkt_stop.KKTStop.__init__
_run = mpgp_steps.MPGPSolve.run


def _init_rec(self, qp, rtol, *args, **kwargs):
    _init(self, qp, rtol, *args, **kwargs)
    self._qp = qp


def _make_test_rec(self, loosen=1.0):
    test = _make_test(self, loosen)
    feti, stop = self._qp.feti, self

    class Rec:
        def __call__(self_, gP, x=None):
            ok = test(gP, x)
            REC["tests"].append({"mults": feti.hessian_mults, "x": x.array_r.copy(),
                                 "bound": test.last, "tol": test.tol, "ok": bool(ok),
                                 "length": getattr(test, "length", None),
                                 "force": getattr(test, "force", None), "U": stop.U})
            return ok

        def __getattr__(self_, name):
            return getattr(test, name)
    return Rec()


def _run_rec(self):
    res = _run(self)
    REC["runs"].append({"history": [dict(h) for h in self.history], "counts": dict(self.counts)})
    return res


_galerkin = mpgp_steps.MPGPSolve.galerkin
FLAGS = {"own": False}


def _galerkin_own(self, active, basis=None):
    # prototype: the directions this solve recorded so far join the store at each new face
    if FLAGS["own"] and basis is None and self.recycle._pending:
        self.recycle.commit(self.comm)
    return _galerkin(self, active, basis)


mpgp_steps.MPGPSolve.galerkin = _galerkin_own

# prototypes of history § 39 (issue 22): a proportioning step along the preconditioned chopped
# gradient, and a start that puts forces on the new ring (a Galerkin fit with ring columns)
FLAGS.update(pprop=None, ring=0, all_pprop=None, warm_only=False)
_proportioning = mpgp_steps.MPGPSolve.proportioning
_face_step = mpgp_steps.MPGPSolve.face_step


def _proportioning_pre(self, beta2):
    """MPRGP's line search along z = M⁻¹β (``pprop``) or M⁻¹gᴾ (``pprop=g``) instead of β.

    z is zero on the rows at the bound with β = 0 and on those at the bound it would push
    out of the set; the exact line search along z is cut at the boundary. Falls back to β
    where z is no descent direction. ``FLAGS['warm_only']``: only in solves that start with
    recycled directions (warm ones; the load paths of history § 39 run with it through
    :func:`load_path`).
    """
    if FLAGS["pprop"] is None or self.prec is None or self.stop is not None or \
            not self.line_search or (FLAGS["warm_only"] and not len(self.recycle or ())):
        return _proportioning(self, beta2)
    x, g, S, z = self.x, self.g, self.S, self.p
    xa = x.array_r
    phi_a, beta_a, active = S.split(xa, g.array_r)
    r = x.duplicate()
    r.array[:] = phi_a + beta_a if FLAGS["pprop"] == "g" else beta_a
    self.prec.apply(r, z)
    r.destroy()
    za = z.array_r.copy()
    za[active & (beta_a == 0.0)] = 0.0
    za[active & (za > 0.0)] = 0.0
    z.array[:] = za
    gz = g.dot(z)
    if not gz > 0.0:
        return _proportioning(self, beta2)
    self.mult(z, self.Ap)
    t = min(gz / z.dot(self.Ap), S.max_step(xa, za))
    x.array[:] = S.step(xa, za, t)
    g.axpy(-t, self.Ap)
    return "proportioning"


def _face_step_ring(self, active, phi2):
    """At a warm solve's first step: the projected Galerkin fit over W and ring columns.

    The ring: the rows at the bound whose gradient pushes them into the set (β ≠ 0) at the
    start, the rows the first solve's directions all vanish on. Columns β (``ring=1``) and
    also M⁻¹β on the free rows and the ring (``ring=2``), each with its product, join the
    store; the Galerkin step over the columns that vanish on the other active rows, projected
    onto the set, with a fresh gradient; kept if the energy fell.
    """
    if not FLAGS["ring"] or self.it != 1 or self.recycle is None or self.stop is not None:
        return _face_step(self, active, phi2)
    FLAGS["ring"], n = 0, FLAGS["ring"]  # once, at the warm solve's start
    ring = self.beta.array_r != 0.0
    if not self.comm.allreduce(bool(ring.any()), op=MPI.LOR):
        return _face_step(self, active, phi2)
    self.p.array[:] = self.beta.array_r
    self.mult(self.p, self.Ap)
    self.recycle.record(self.p.array_r, self.Ap.array_r)
    if n > 1 and self.prec is not None:
        w = self.beta.duplicate()
        self.prec.apply(self.beta, w)
        wa = w.array_r.copy()
        wa[active & ~ring] = 0.0
        w.destroy()
        self.p.array[:] = wa
        self.mult(self.p, self.Ap)
        self.recycle.record(self.p.array_r, self.Ap.array_r)
    self.recycle.commit(self.comm)
    basis = self.recycle.basis(active & ~ring, self.comm)
    dAd = None if basis is None else basis.galerkin(self.g.array_r)
    if dAd is not None:
        d, Ad = dAd
        gd, dad = self.comm.allreduce(np.array([float(self.g.array_r @ d), float(d @ Ad)]))
        if dad > 0.0 and gd < 0.0:
            f0 = self.energy()
            x0, g0 = self.x.array_r.copy(), self.g.copy()
            self.x.array[:] = self.S.project(x0 - gd / dad * d)
            self.fresh_gradient()
            REC["ring"] = {"rows": self.comm.allreduce(int(ring.sum())), "f0": f0,
                           "f": self.energy()}
            if self.energy() < f0:
                g0.destroy()
                return "recycle"
            self.x.array[:] = x0
            g0.copy(self.g)
            g0.destroy()
    return _face_step(self, active, phi2)




def _recording(step):
    """Also record the moves of the expansions and proportioning steps with their A-products.

    ``g_after − g_before = A (x_after − x_before)`` exactly where the gradient is kept exact
    (flat sets): the pair costs no product (``FLAGS['steps']``).
    """
    def wrapped(self, *args):
        if not FLAGS["steps"] or self.recycle is None:
            return step(self, *args)
        x0, g0 = self.x.array_r.copy(), self.g.array_r.copy()
        kind = step(self, *args)
        if kind in ("expansion", "proportioning"):
            self.recycle.record(self.x.array_r - x0, self.g.array_r - g0)
        return kind
    return wrapped


FLAGS["steps"] = False
mpgp_steps.MPGPSolve.proportioning = _recording(_proportioning_pre)
mpgp_steps.MPGPSolve.face_step = _recording(_face_step_ring)
kkt_stop.KKTStop.__init__ = _init_rec
qp_solve.KKTStop.__init__ = _init_rec
kkt_stop.KKTStop.make_test = _make_test_rec
mpgp_steps.MPGPSolve.run = _run_rec


# --- the solver's state ---------------------------------------------------------------------
def save(solver) -> dict:
    r = solver.recycle
    st = {k: copy.deepcopy(getattr(r, k)) for k in
          ("k", "base_k", "_W", "_AW", "_C", "_filled", "_next", "_carry", "_old", "checked",
           "change", "stats")}
    st["_key"] = r._key
    st["lam"] = solver._lam.copy()
    st["d_last"] = solver._d_last.copy()
    st["before"] = None if solver._before is None else \
        (solver._before[0].copy(), solver._before[1].copy(), solver._before[2])
    for k in ("_new_case", "_M", "_mu", "_force_ratio"):
        st[k] = copy.deepcopy(getattr(solver, k))
    return st


def restore(solver, st: dict) -> None:
    r = solver.recycle
    for k in ("k", "base_k", "_W", "_AW", "_C", "_filled", "_next", "_carry", "_old", "checked",
              "change", "stats"):
        setattr(r, k, copy.deepcopy(st[k]))
    r._key = st["_key"]
    r._pending = []
    solver._lam = st["lam"].copy()
    solver._d_last = st["d_last"].copy()
    solver._before = None if st["before"] is None else \
        (st["before"][0].copy(), st["before"][1].copy(), st["before"][2])
    for k in ("_new_case", "_M", "_mu", "_force_ratio"):
        setattr(solver, k, copy.deepcopy(st[k]))


def keep_columns(r, cols: np.ndarray) -> None:
    """Cut the store to the columns ``cols`` (in their order)."""
    cols = np.asarray(cols, dtype=int)
    n = cols.size
    W, AW = np.zeros_like(r._W), np.zeros_like(r._AW)
    W[:, :n], AW[:, :n] = r._W[:, cols], r._AW[:, cols]
    Cm = np.zeros_like(r._C)
    Cm[:n, :n] = r._C[np.ix_(cols, cols)]
    old = np.zeros_like(r._old)
    old[:n] = r._old[cols]
    r._W, r._AW, r._C, r._old = W, AW, Cm, old
    r._filled, r._next = n, n % r.k


def faces_of(history: list[dict]) -> list[int]:
    """Per stored direction of a run (the CG and expansion steps, in order), its face."""
    face, out = 0, []
    for h in history[1:]:
        kind = h["kind"]
        if kind in ("cg", "expansion", "galerkin"):
            out.append(face)
        if kind in ("expansion", "proportioning", "galerkin"):
            face += 1
    return out


# --- the measures ---------------------------------------------------------------------------
def physical_check(qp, x, rtol):
    """(primal, equilibrium) of the solution recovered from the QP iterate ``x``."""
    xv = qp.b.duplicate()
    xv.array[:] = x
    lb = qp.lb.array_r
    res = SimpleNamespace(active=np.isfinite(lb) & (x <= lb), multiplier=None)
    u, lam_all, _, _ = qp_solve._recover(qp, res, xv, None)
    scale, kind, ineq = kkt_stop.row_data(qp)
    kkt, _ = kkt_stop.kkt_residuals(qp.system, scale, kind, ineq, u, lam_all)
    primal = max(v for k, v in kkt.items() if k in kkt_stop.KEYS and k != "equilibrium")
    REC["last_kkt"] = dict(kkt, u_max=u.norm(3),
                           lam_max=float(np.abs(lam_all.array_r * scale).max()),
                           lam_qp_max=float(np.abs(x * scale[qp.row_index]).max()))
    worst = max(kkt, key=lambda k: kkt[k] if k in kkt_stop.KEYS else -1)
    for v in (xv, u, lam_all):
        v.destroy()
    return primal, kkt.get("equilibrium", 0.0), worst


def energy_errors(qp, x, xs):
    """‖x − x*‖_F on all rows, the gluing rows, the contact rows, relative to ‖x*‖_F."""
    A = qp.A
    ineq = qp.ineq

    def an(v):
        a, y = qp.b.duplicate(), qp.b.duplicate()
        a.array[:] = v
        A.mult(a, y)
        val = math.sqrt(max(float(a.dot(y)), 0.0))
        a.destroy()
        y.destroy()
        return val
    e = x - xs
    ref = an(xs)
    return an(e) / ref, an(np.where(ineq, 0.0, e)) / ref, an(np.where(ineq, e, 0.0)) / ref


def solve_variant(solver, st, name, rtol, b_norm):
    restore(solver, st)
    r = solver.recycle
    extra = 0
    FLAGS["own"] = "own" in name.split("+")
    FLAGS["pprop"] = FLAGS["all_pprop"]
    FLAGS["ring"] = 0
    full, name = name, name.split("+")[0]
    if name.startswith(("last:", "first:")):
        n = int(name.split(":")[1])
        f = np.array(st["faces"])
        last = f.max()
        cols = np.flatnonzero(f > last - n) if name.startswith("last:") else \
            np.flatnonzero(f <= last - n)
        keep_columns(r, cols)
    elif name == "empty":
        keep_columns(r, np.array([], dtype=int))
    elif name == "fit":
        lam = solver._lam
        Alam = lam.duplicate()
        solver.qp.A.mult(lam, Alam)
        extra = 1
        r.record(lam.array_r, Alam.array_r)
        r.commit(MPI.COMM_WORLD)
        Alam.destroy()
    REC["tests"].clear()
    REC["runs"].clear()
    opts = solver.options
    start = solver._start
    for flag in full.split("+")[1:]:
        if flag.startswith("gamma="):
            solver.options = opts.replace(mprgp_gamma=float(flag[6:]))
        elif flag == "noratio":  # the bound's force part against the QP's rows alone
            solver._force_ratio = 1.0
        elif flag in ("pprop", "pprop=g"):
            FLAGS["pprop"] = flag[6:] or "b"
        elif flag.startswith("ring"):
            FLAGS["ring"] = int(flag[4:] or 1)
        elif flag == "nogradient":  # MPRGP's first product its own gradient
            def _start_without(x0, start=start):
                x, scale, omega, g = start(x0)
                if g is not None:
                    g.destroy()
                return x, scale, omega, None
            solver._start = _start_without
    m0 = solver.qp.feti.hessian_mults
    sol = solver.solve()
    FLAGS["pprop"], FLAGS["ring"] = FLAGS["all_pprop"], 0
    solver.options = opts
    solver._start = start
    tests = list(REC["tests"])
    runs = list(REC["runs"])
    hist = [h for run in runs for h in run["history"]]
    out = {"variant": full, "mults": sol.report.hessian_mults + extra,
           "counts": sol.report.counts, "checks": sol.report.stopping["checks"],
           "m0": m0, "tests": tests, "history": hist}
    return sol, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=("pushed3d", "sphere3d"), default="pushed3d")
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--variants", nargs="*", default=["base"])
    ap.add_argument("--diagnose", action="store_true",
                    help="the per-iterate physical checks and errors of each variant")
    ap.add_argument("--pprop", choices=("b", "g"), default=None,
                    help="the prototype proportioning step (flag pprop) in every solve, the "
                    "first and the reference one too")
    ap.add_argument("--warm-only", action="store_true",
                    help="with --pprop: only in solves that start with recycled directions")
    ap.add_argument("--load-path", nargs=argparse.REMAINDER, default=None,
                    help="run bench/load_path.py with these arguments under --pprop instead")
    ap.add_argument("--preconditioner", choices=("lumped", "dirichlet", "none"),
                    default="lumped", help="the FETI preconditioner (every solve)")
    ap.add_argument("--record-steps", action="store_true",
                    help="every solve also stores its expansions' and proportioning steps' "
                    "moves (with --room 160: the first solve's all kept)")
    ap.add_argument("--room", type=int, default=None,
                    help="the store's room before the first solve (default: the solver's)")
    args = ap.parse_args()
    FLAGS["all_pprop"] = FLAGS["pprop"] = args.pprop
    FLAGS["steps"] = args.record_steps
    FLAGS["warm_only"] = args.warm_only
    if args.load_path is not None:
        import load_path
        sys.argv = ["load_path.py", *args.load_path]
        load_path.main()
        return
    comm = MPI.COMM_WORLD
    mesh = C.sphere_mesh("S3")
    case = pushed3d if args.case == "pushed3d" else sphere3d

    def make(s):
        return case(mesh, s, 8)
    solver = df.FetiSolver(make(1.0), comm=comm, rtol=args.rtol, method="auto",
                           preconditioner=args.preconditioner)
    if args.room:  # the first bind clears the store back to base_k
        solver.recycle.base_k = args.room
        solver.recycle.grow(args.room)
    REC["runs"].clear()
    sol0 = solver.solve()
    first_hist = [h for run in REC["runs"] for h in run["history"]]
    faces = faces_of(first_hist)
    print(f"first solve: {sol0.report.hessian_mults} F-mults, counts {sol0.report.counts}, "
          f"{len(solver.recycle)} stored directions, faces {max(faces) + 1}; directions per "
          f"face {np.bincount(faces).tolist()}")
    solver.update(make(1.1))
    st = save(solver)
    st["faces"] = faces[-len(solver.recycle):] if len(faces) >= len(solver.recycle) else \
        [0] * (len(solver.recycle) - len(faces)) + faces
    qp = solver.qp
    # the solution of the second case, to rtol 1e-10 (from the warm start)
    opts = solver.options
    solver.options = opts.replace(rtol=1e-10)
    restore(solver, st)
    solver.solve()
    xs = solver._lam.array_r.copy() - qp.lam_hat.array_r
    solver.options = opts
    b_norm = qp.b.norm()
    results = []
    for name in args.variants:
        sol, out = solve_variant(solver, st, name, args.rtol, b_norm)
        xw = solver._lam.array_r - qp.lam_hat.array_r
        print(f"\n== {name}: {out['mults']} F-mults, counts {out['counts']}, checks "
              f"{out['checks']}; final error {energy_errors(qp, xw, xs)[0]:.2e}")
        row = {k: v for k, v in out.items() if k not in ("tests", "x")}
        if args.diagnose:
            table = []
            first_pass = None
            hist = out["history"]
            for i, t in enumerate(out["tests"]):
                primal, equil, worst = physical_check(qp, t["x"], args.rtol)
                err = energy_errors(qp, t["x"], xs)
                kind = hist[i]["kind"] if i < len(hist) else "?"
                gP = hist[i]["gP"] / b_norm if i < len(hist) else float("nan")
                ok = primal <= args.rtol and equil <= args.rtol
                if ok and first_pass is None:
                    first_pass = i
                table.append({"i": i, "mults": t["mults"] - out["m0"], "kind": kind, "gP": gP,
                              "bound/tol": t["bound"] / t["tol"], "primal": primal,
                              "equil": equil, "worst": worst, "pass": ok,
                              "err": err[0], "err_glue": err[1], "err_contact": err[2],
                              "proxy": {k: t[k] for k in ("length", "force", "U", "tol")},
                              "kkt": REC["last_kkt"]})
            print("| it | mults | kind | gP/b | bound/tol | primal/rtol | equil/rtol | worst | "
                  "err_F | glue | contact |")
            print("|---|---|---|---|---|---|---|---|---|---|---|")
            for t in table:
                print(f"| {t['i']} | {t['mults']} | {t['kind']} | {t['gP']:.1e} | "
                      f"{t['bound/tol']:.2g} | {t['primal'] / args.rtol:.2g} | "
                      f"{t['equil'] / args.rtol:.2g} | {t['worst']} | {t['err']:.1e} | "
                      f"{t['err_glue']:.1e} | {t['err_contact']:.1e} |")
            print(f"first iterate passing the physical check: {first_pass}; the stop at "
                  f"{len(out['tests']) - 1}")
            row["table"] = table
            row["first_pass"] = first_pass
        results.append(row)
    if comm.rank == 0:
        o = ROOT / "output/bench"
        o.mkdir(parents=True, exist_ok=True)
        (o / f"first_warm_{args.case}.json").write_text(json.dumps(
            {"first": {"mults": sol0.report.hessian_mults, "counts": sol0.report.counts,
                       "faces": faces, "history": first_hist}, "variants": results},
            indent=1, default=float))


if __name__ == "__main__":
    main()
