"""MPRGP on box-constrained QPs: agreement with references, KKT, feasibility, counts."""

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc
from qp_helpers import (
    COMM,
    MPI_COMM,
    counting,
    gather,
    kkt,
    laplacian_2d,
    make_mat,
    make_vec,
    random_spd,
    ref_active_set,
    ref_box,
)

from dolfinx_feti.qp import mprgp

EXPANSIONS = ["fixed", "optimal", "projcg"]


def box_problem(kind: str, seed: int = 0, n: int = 60):
    """Random strictly convex QP with bounds of the given kind; the unconstrained minimizer is
    infeasible in many entries so that a good share of bounds is active."""
    rng = np.random.default_rng(seed)
    A = random_spd(n, rng, cond=50.0)
    b = 2.0 * rng.standard_normal(n)
    l = np.full(n, -0.3)
    u = np.full(n, 0.4)
    if kind == "lower":
        u[:] = np.inf
    elif kind == "mixed":
        # Unbounded (the FETI gluing multipliers), lower only, upper only, box, and fixed.
        which = rng.integers(0, 5, n)
        l[which == 0], u[which == 0] = -np.inf, np.inf
        u[which == 1] = np.inf
        l[which == 2] = -np.inf
        u[which == 4] = l[which == 4]
    return A, b, l, u


class Feasibility:
    """Monitor that checks the iterate (read through the Vec MPRGP updates in place)."""

    def __init__(self, x: PETSc.Vec, l: np.ndarray, u: np.ndarray) -> None:
        lo, hi = x.getOwnershipRange()
        self.x, self.l, self.u = x, l[lo:hi], u[lo:hi]
        self.worst = 0.0
        self.kinds: list[str] = []

    def __call__(self, it: int, gP: float, kind: str) -> None:
        xa = self.x.array_r
        self.worst = max(self.worst, float(np.max(self.l - xa, initial=0.0)),
                         float(np.max(xa - self.u, initial=0.0)))
        self.kinds.append(kind)

    def violation(self) -> float:
        return MPI_COMM.allreduce(self.worst, op=MPI.MAX)


@pytest.mark.parametrize("expansion", EXPANSIONS)
@pytest.mark.parametrize("kind", ["lower", "box", "mixed"])
def test_random_box_qp(kind, expansion):
    A, b, l, u = box_problem(kind, seed=1)
    ref = ref_box(A, b, l, u)
    ref2 = ref_active_set(A, b, l, u, x0=np.clip(np.zeros_like(b), l, u))
    assert np.linalg.norm(ref - ref2) <= 1e-10 * np.linalg.norm(ref)
    x = make_vec(np.zeros_like(b))
    mon = Feasibility(x, l, u)
    res = mprgp(make_mat(A), make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=1e-11,
                expansion=expansion, monitor=mon)
    xs = gather(x)
    assert res.converged and res.reason == "rtol"
    assert mon.violation() == 0.0
    assert np.linalg.norm(xs - ref) <= 1e-8 * np.linalg.norm(ref)
    r = kkt(A, b, xs, l, u)
    assert r["infeas"] == 0.0
    assert r["gP"] <= 2e-11 * np.linalg.norm(b)
    assert r["comp"] <= 1e-9
    assert abs(res.gP_norm - r["gP"]) <= 1e-12 * np.linalg.norm(b)
    assert res.active_count == int(np.sum((xs <= l) | (xs >= u)))
    assert set(mon.kinds) <= {"init", "cg", "expansion", "proportioning"}
    assert res.counts["expansion"] > 0
    assert len(res.history) == res.iterations + 1
    f = 0.5 * xs @ A @ xs - b @ xs
    assert abs(res.objective - f) <= 1e-10 * abs(f)


@pytest.mark.parametrize("expansion", EXPANSIONS)
def test_degenerate_sparse(expansion):
    """Solution built first: some bounds active with zero multiplier (degenerate)."""
    rng = np.random.default_rng(7)
    A = laplacian_2d(12)  # n = 144, sparse
    n = A.shape[0]
    l, u = np.full(n, -1.0), np.full(n, 1.0)
    l[::7] = -np.inf
    state = rng.integers(0, 5, n)  # 0 free, 1/2 lower (strict/degenerate), 3/4 upper
    state[np.isinf(l) & ((state == 1) | (state == 2))] = 0
    xstar = rng.uniform(-0.9, 0.9, n)
    g = np.zeros(n)
    xstar[(state == 1) | (state == 2)] = l[(state == 1) | (state == 2)]
    xstar[(state == 3) | (state == 4)] = u[(state == 3) | (state == 4)]
    g[state == 1] = rng.uniform(0.5, 2.0, np.sum(state == 1))
    g[state == 3] = -rng.uniform(0.5, 2.0, np.sum(state == 3))
    b = A @ xstar - g  # g = A x* - b vanishes on free and degenerate entries
    x = make_vec(rng.uniform(-2, 2, n))  # infeasible start: projected first
    mon = Feasibility(x, l, u)
    res = mprgp(make_mat(A), make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=1e-12,
                expansion=expansion, monitor=mon)
    xs = gather(x)
    assert res.converged
    assert mon.violation() == 0.0
    assert np.linalg.norm(xs - xstar) <= 1e-8 * np.linalg.norm(xstar)
    r = kkt(A.toarray(), b, xs, l, u)
    assert r["gP"] <= 2e-12 * np.linalg.norm(b) and r["comp"] <= 1e-9


def test_unbounded_entries_only_is_cg():
    """Without bounds MPRGP is CG: same solution, only CG steps."""
    A = laplacian_2d(8)
    b = np.random.default_rng(3).standard_normal(A.shape[0])
    x = make_vec(np.zeros_like(b))
    res = mprgp(make_mat(A), make_vec(b), x, rtol=1e-12, norm_A=8.1)
    assert res.converged
    assert res.counts == {"cg": res.iterations, "expansion": 0, "proportioning": 0, "norm": 0}
    ref = np.linalg.solve(A.toarray(), b)
    assert np.linalg.norm(gather(x) - ref) <= 1e-10 * np.linalg.norm(ref)


@pytest.mark.parametrize("expansion", EXPANSIONS)
def test_hessian_mult_count(expansion):
    A, b, l, u = box_problem("mixed", seed=2)
    Ac, ctx = counting(make_mat(A))
    x = make_vec(np.zeros_like(b))
    res = mprgp(Ac, make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=1e-8,
                expansion=expansion)  # norm estimated inside: counted too
    assert res.converged
    assert res.hessian_mults == ctx.calls
    c = res.counts
    assert c["norm"] > 0
    steps = 1 + c["norm"] + c["cg"] + c["proportioning"]
    if expansion == "fixed":
        assert res.hessian_mults == steps + 2 * c["expansion"]
    elif expansion == "projcg":  # a rejected projected CG step costs one more product
        assert res.hessian_mults == steps + 2 * c["expansion"] + c["rejected"]
    else:  # an expansion from a point with zero free gradient skips the second product
        assert steps + c["expansion"] <= res.hessian_mults <= steps + 2 * c["expansion"]
    # A supplied valid gradient saves the first multiplication.
    x2 = make_vec(gather(x))
    g = make_vec(A @ gather(x) - b)
    before = ctx.calls
    res2 = mprgp(Ac, make_vec(b), x2, lb=make_vec(l), ub=make_vec(u), rtol=1e-8, norm_A=60.0,
                 g=g, g_valid=True)
    assert res2.converged and res2.iterations == 0
    assert res2.hessian_mults == 0 == ctx.calls - before


def test_max_it_returns_iterate():
    A, b, l, u = box_problem("box", seed=4)
    x = make_vec(np.zeros_like(b))
    mon = Feasibility(x, l, u)
    res = mprgp(make_mat(A), make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=1e-12,
                max_it=3, monitor=mon, norm_A=51.0)
    assert not res.converged and res.reason == "max_it"
    assert res.iterations == 3 and len(res.history) == 4
    assert mon.violation() == 0.0
    assert np.isfinite(res.gP_norm) and res.gP_norm > 1e-12 * np.linalg.norm(b)


def test_stop_callback():
    A, b, l, u = box_problem("lower", seed=5)
    seen = []

    def stop(gP, x, g):
        seen.append(gP)
        return gP < 1e-3

    res = mprgp(make_mat(A), make_vec(b), make_vec(np.zeros_like(b)), lb=make_vec(l),
                rtol=0.0, stop=stop, norm_A=51.0)
    assert res.converged and res.reason == "stop"
    assert seen[-1] < 1e-3 and all(s >= 1e-3 for s in seen[:-1])


def test_unbounded_energy():
    """PSD A with b outside its range along an unconstrained null direction."""
    n = 20
    A = np.diag(np.r_[np.linspace(1.0, 2.0, n - 1), 0.0])
    b = np.ones(n)
    lb = np.full(n, -1.0)
    lb[-1] = -np.inf  # x[-1] may go to +inf: no bound stops the descent
    res = mprgp(make_mat(A), make_vec(b), make_vec(np.zeros(n)), lb=make_vec(lb), ub=None,
                rtol=1e-10, norm_A=2.0)
    assert not res.converged and res.reason == "unbounded"
    # An upper bound on that entry makes the problem well posed again.
    ub = np.full(n, np.inf)
    ub[-1] = 5.0
    x = make_vec(np.zeros(n))
    res = mprgp(make_mat(A), make_vec(b), x, lb=make_vec(lb), ub=make_vec(ub), rtol=1e-10,
                norm_A=2.0)
    assert res.converged and gather(x)[-1] == 5.0


def test_invalid_input_raises():
    A, b, l, u = box_problem("box", seed=6, n=10)
    Am, bv = make_mat(A), make_vec(b)
    with pytest.raises(ValueError, match="lb > ub"):
        mprgp(Am, bv, make_vec(np.zeros(10)), lb=make_vec(u), ub=make_vec(l), norm_A=51.0)
    bad = b.copy()
    bad[-1] = np.nan  # on the last rank only: every rank must still raise
    with pytest.raises(ValueError, match="non-finite"):
        mprgp(Am, make_vec(bad), make_vec(np.zeros(10)), norm_A=51.0)
    with pytest.raises(ValueError, match="expansion"):
        mprgp(Am, bv, make_vec(np.zeros(10)), expansion="nope", norm_A=51.0)
    with pytest.raises(ValueError, match="alpha_bar"):
        mprgp(Am, bv, make_vec(np.zeros(10)), alpha_bar=-1.0)


@pytest.mark.parametrize("expansion", EXPANSIONS)
def test_same_on_self_and_world(expansion):
    """The distributed run follows the serial one (same steps, same iterate to rounding)."""
    A, b, l, u = box_problem("mixed", seed=8, n=80)
    runs = []
    for comm in (PETSc.COMM_SELF, COMM):
        x = make_vec(np.zeros_like(b), comm)
        res = mprgp(make_mat(A, comm), make_vec(b, comm), x, lb=make_vec(l, comm),
                    ub=make_vec(u, comm), rtol=1e-10, expansion=expansion)
        runs.append((gather(x), res))
    (x1, r1), (x2, r2) = runs
    assert r1.converged and r2.converged
    assert abs(r1.iterations - r2.iterations) <= 2
    assert np.linalg.norm(x1 - x2) <= 1e-9 * np.linalg.norm(x1)


def test_to_dict_is_json():
    import json

    A, b, l, u = box_problem("box", seed=9, n=20)
    res = mprgp(make_mat(A), make_vec(b), make_vec(np.zeros(20)), lb=make_vec(l),
                ub=make_vec(u), rtol=1e-8)
    d = json.loads(json.dumps(res.to_dict()))
    assert d["converged"] and d["hessian_mults"] == res.hessian_mults
    assert "x" not in d and d["active_count"] == res.active_count


def test_projcg_rejected_step_falls_back():
    """An ill-conditioned box QP where some projected CG steps raise the energy."""
    rng = np.random.default_rng(0)
    n = 60
    A = random_spd(n, rng, cond=1e3)
    b = 3.0 * rng.standard_normal(n)
    l, u = np.full(n, -0.5), np.full(n, 0.5)
    Ac, ctx = counting(make_mat(A))
    x = make_vec(np.zeros(n))
    mon = Feasibility(x, l, u)
    res = mprgp(Ac, make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=1e-11,
                expansion="projcg", norm_A=float(np.linalg.eigvalsh(A).max()), monitor=mon)
    c = res.counts
    assert res.converged and c["rejected"] >= 1 and mon.violation() == 0.0
    assert res.hessian_mults == ctx.calls == (1 + c["cg"] + c["proportioning"]
                                              + 2 * c["expansion"] + c["rejected"])
    ref = ref_box(A, b, l, u)
    assert np.linalg.norm(gather(x) - ref) <= 1e-8 * np.linalg.norm(ref)
