"""Preconditioned CG / MPRGP / SMALBE and MPRGP's adaptive (Barzilai-Borwein) expansion length."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from petsc4py import PETSc
from qp_helpers import (
    COMM,
    Diagonal,
    GlobalSolve,
    counting,
    gather,
    make_mat,
    make_vec,
    obstacle,
    random_spd,
    ref_active_set,
    ref_box,
    row_block_constraint,
    scaled,
)
from test_qp_mprgp import Feasibility, box_problem
from test_qp_smalbe import feti_like, solve_feti_like

from dolfinx_feti.qp import (
    ProjectedPreconditioner,
    Projector,
    cg,
    mprgp,
    orthonormalize,
    penalized_operator,
    projected_operator,
    smalbe,
)


def jacobi_pc(A: PETSc.Mat) -> PETSc.PC:
    pc = PETSc.PC().create(comm=A.getComm())
    pc.setOperators(A)
    pc.setType("jacobi")
    pc.setUp()
    return pc


def rel(a, b) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# ------------------------------------------------------------------------------------------ CG

def test_cg_exact_inverse_converges_at_once():
    rng = np.random.default_rng(20)
    A = random_spd(50, rng, cond=1e4)
    b = rng.standard_normal(50)
    x0 = make_vec(np.zeros(50))
    plain = cg(make_mat(A), make_vec(b), x0, rtol=1e-12, max_it=500)
    x = make_vec(np.zeros(50))
    res = cg(make_mat(A), make_vec(b), x, rtol=1e-12, preconditioner=make_mat(np.linalg.inv(A)))
    assert plain.converged and res.converged
    assert res.iterations <= 2 < plain.iterations
    assert res.counts == {"cg": res.iterations, "precond": res.iterations}
    assert res.hessian_mults == res.iterations + 1
    assert rel(gather(x), gather(x0)) <= 1e-8


@pytest.mark.parametrize("form", ["object", "callable", "pc"])
def test_cg_jacobi_on_badly_scaled(form):
    """Jacobi in the three accepted forms: same iterates, far fewer products."""
    rng = np.random.default_rng(21)
    A = scaled(random_spd(60, rng, cond=20.0), rng, decades=3.0)
    b = rng.standard_normal(60)
    Am = make_mat(A)
    x0 = make_vec(np.zeros(60))
    plain = cg(Am, make_vec(b), x0, rtol=1e-10, max_it=2000)
    x = make_vec(np.zeros(60))
    diag = Diagonal(1.0 / np.diag(A), x)
    M = {"object": diag, "callable": diag.mult, "pc": jacobi_pc(Am)}[form]
    res = cg(Am, make_vec(b), x, rtol=1e-10, preconditioner=M)
    assert plain.converged and res.converged
    assert res.hessian_mults < plain.hessian_mults / 3
    assert res.counts["precond"] == res.iterations
    if form != "pc":
        assert diag.calls == res.iterations
    assert rel(gather(x), gather(x0)) <= 1e-8


def test_cg_projected_preconditioner():
    """z = P M^{-1} P r on a FETI-like projected problem, against the KKT solution."""
    rng = np.random.default_rng(22)
    n, m = 60, 6
    F = scaled(random_spd(n, rng, cond=20.0), rng, decades=2.0)
    G = rng.standard_normal((m, n))
    con = orthonormalize(row_block_constraint(G))
    b = rng.standard_normal(n)
    K = np.block([[F, G.T], [G, np.zeros((m, m))]])
    ref = np.linalg.solve(K, np.r_[b, np.zeros(m)])[:n]
    runs = {}
    for name in ("none", "jacobi"):
        Fc, ctx = counting(make_mat(F))
        x = make_vec(np.zeros(n))
        M = None if name == "none" else Diagonal(1.0 / np.diag(F), x)
        res = cg(projected_operator(Fc, con), make_vec(b), x, projector=Projector(con),
                 rtol=1e-12, max_it=1000, preconditioner=M)
        assert res.converged and res.hessian_mults == ctx.calls
        xs = gather(x)
        assert rel(xs, ref) <= 1e-9
        assert np.linalg.norm(G @ xs) <= 1e-11 * np.linalg.norm(xs)
        runs[name] = res
    assert runs["jacobi"].hessian_mults < 0.75 * runs["none"].hessian_mults


def test_cg_indefinite_preconditioner_breaks_down():
    A = random_spd(20, np.random.default_rng(23))
    x = make_vec(np.zeros(20))
    res = cg(make_mat(A), make_vec(np.ones(20)), x, rtol=1e-10,
             preconditioner=Diagonal(-np.ones(20), x))
    assert not res.converged and res.reason == "breakdown"


# ------------------------------------------------------------------------------ MPRGP, in face

@pytest.mark.parametrize("expansion", ["fixed", "optimal", "projcg"])
@pytest.mark.parametrize("kind", ["lower", "box", "mixed"])
def test_mprgp_jacobi_in_face(kind, expansion):
    """Badly scaled box QPs: same solution, feasible iterates, far fewer Hessian products."""
    A, b, l, u = box_problem(kind, seed=1)
    A = scaled(A, np.random.default_rng(3))
    ref = ref_box(A, b, l, u)
    norm_A = float(np.linalg.eigvalsh(A).max())
    mults = {}
    for name in ("none", "jacobi"):
        Ac, ctx = counting(make_mat(A))
        x = make_vec(np.zeros_like(b))
        mon = Feasibility(x, l, u)
        M = None if name == "none" else Diagonal(1.0 / np.diag(A), x)
        res = mprgp(Ac, make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=1e-10,
                    norm_A=norm_A, expansion=expansion, preconditioner=M, monitor=mon)
        assert res.converged and mon.violation() == 0.0
        assert rel(gather(x), ref) <= 1e-8
        c = res.counts
        assert res.hessian_mults == ctx.calls
        if expansion == "fixed":
            assert ctx.calls == 1 + c["cg"] + c["proportioning"] + 2 * c["expansion"]
        if M is not None:
            # One application per iteration that passed the proportioning test.
            assert c["precond"] == M.calls == c["cg"] + c["expansion"]
        else:
            assert "precond" not in c
        mults[name] = res.hessian_mults
    assert mults["jacobi"] < mults["none"] / 2


def test_mprgp_exact_inverse_without_bounds():
    """No bounds: one preconditioned CG step with M^{-1} = A^{-1}."""
    rng = np.random.default_rng(24)
    A = random_spd(40, rng, cond=1e3)
    b = rng.standard_normal(40)
    x = make_vec(np.zeros(40))
    res = mprgp(make_mat(A), make_vec(b), x, rtol=1e-11, norm_A=1e3,
                preconditioner=make_mat(np.linalg.inv(A)))
    assert res.converged and res.counts["cg"] <= 2 and res.counts["precond"] <= 2
    assert rel(gather(x), np.linalg.solve(A, b)) <= 1e-9


def test_mprgp_nearby_inverse_on_obstacle():
    """M^{-1} = inverse of the unconstrained Laplacian (a callable, gathered solve)."""
    A, b, l, u = obstacle(20)
    ref = ref_box(A.toarray(), b, l, u)
    lu = spla.splu((A * 1.1).tocsc())  # nearby, not exact
    norm_A = 8.0 * 21**2
    mults = {}
    for name in ("none", "lu"):
        x = make_vec(np.maximum(0.0, l))
        mon = Feasibility(x, l, u)
        M = None if name == "none" else GlobalSolve(lu.solve)
        res = mprgp(make_mat(A), make_vec(b), x, lb=make_vec(l), rtol=1e-10, norm_A=norm_A,
                    preconditioner=M, alpha="bb", monitor=mon)
        assert res.converged and mon.violation() == 0.0
        assert rel(gather(x), ref) <= 1e-8
        mults[name] = res.hessian_mults
    assert mults["lu"] < mults["none"]


def test_mprgp_singular_preconditioner_falls_back_to_phi():
    """M^{-1} = 0 gives z = 0, no descent: every step uses phi, as without a preconditioner."""
    A, b, l, u = box_problem("box", seed=2)
    runs = []
    for M in (None, Diagonal(np.zeros(len(b)), make_vec(b))):
        x = make_vec(np.zeros_like(b))
        res = mprgp(make_mat(A), make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=1e-10,
                    norm_A=51.0, preconditioner=M)
        runs.append((res, gather(x)))
    (r0, x0), (r1, x1) = runs
    assert r0.converged and r1.converged
    assert r0.iterations == r1.iterations and r0.hessian_mults == r1.hessian_mults
    assert r1.counts["precond"] == r1.counts["cg"] + r1.counts["expansion"]
    assert np.array_equal(x0, x1)


def test_mprgp_preconditioner_forms_agree():
    """A Mat, a PC, an object with mult: the same Jacobi, the same run."""
    A, b, l, u = box_problem("mixed", seed=3)
    A = scaled(A, np.random.default_rng(4))
    Am = make_mat(A)
    x_like = make_vec(b)
    d = 1.0 / np.diag(A)
    D = make_mat(np.diag(d))
    forms = [D, jacobi_pc(Am), Diagonal(d, x_like)]
    out = []
    for M in forms:
        x = make_vec(np.zeros_like(b))
        res = mprgp(Am, make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=1e-10,
                    norm_A=float(np.linalg.eigvalsh(A).max()), preconditioner=M)
        out.append((res.iterations, res.hessian_mults, gather(x)))
    assert len({o[:2] for o in out}) == 1
    assert all(rel(o[2], out[0][2]) <= 1e-12 for o in out)
    with pytest.raises(TypeError, match="preconditioner"):
        mprgp(Am, make_vec(b), make_vec(np.zeros_like(b)), norm_A=1.0, preconditioner=3.0)


# ----------------------------------------------------------------------------- MPRGP, alpha

@pytest.mark.parametrize("kind", ["lower", "box", "mixed"])
def test_mprgp_bb_same_solution(kind):
    A, b, l, u = box_problem(kind, seed=1)
    ref = ref_box(A, b, l, u)
    Ac, ctx = counting(make_mat(A))
    x = make_vec(np.zeros_like(b))
    mon = Feasibility(x, l, u)
    res = mprgp(Ac, make_vec(b), x, lb=make_vec(l), ub=make_vec(u), rtol=1e-11, alpha="bb",
                monitor=mon)
    c = res.counts
    assert res.converged and mon.violation() == 0.0
    assert rel(gather(x), ref) <= 1e-8
    assert res.hessian_mults == ctx.calls == (1 + c["norm"] + c["cg"] + c["proportioning"]
                                              + 2 * c["expansion"] + c["rejected"])
    f = 0.5 * gather(x) @ A @ gather(x) - b @ gather(x)
    assert abs(res.objective - f) <= 1e-10 * abs(f)


def test_mprgp_bb_monotone_and_faster_on_obstacle():
    """Expansions dominate the obstacle problem: the long BB step needs far fewer of them; the
    energy never increases (the safeguard) and every iterate is feasible."""
    A, b, l, u = obstacle(20)
    ref = ref_box(A.toarray(), b, l, u)
    Am = make_mat(A)
    runs = {}
    for alpha in ("fixed", "bb"):
        x = make_vec(np.maximum(0.0, l))
        mon = Feasibility(x, l, u)
        energies = []

        def monitor(it, gP, kind, x=x, mon=mon, energies=energies):
            mon(it, gP, kind)
            xs = gather(x)
            energies.append(0.5 * xs @ (A @ xs) - b @ xs)

        res = mprgp(Am, make_vec(b), x, lb=make_vec(l), rtol=1e-10, norm_A=8.0 * 21**2,
                    alpha=alpha, monitor=monitor)
        assert res.converged and mon.violation() == 0.0
        assert rel(gather(x), ref) <= 1e-8
        assert np.all(np.diff(energies) <= 1e-12 * np.abs(energies[1:]))
        runs[alpha] = res
    assert runs["bb"].hessian_mults < 0.8 * runs["fixed"].hessian_mults
    assert runs["bb"].counts["expansion"] < runs["fixed"].counts["expansion"]


def test_alpha_validation():
    A, b, l, u = box_problem("box", seed=6, n=10)
    Am, bv = make_mat(A), make_vec(b)
    with pytest.raises(ValueError, match="alpha must be"):
        mprgp(Am, bv, make_vec(np.zeros(10)), alpha="nope", norm_A=51.0)
    with pytest.raises(ValueError, match="expansion='fixed'"):
        mprgp(Am, bv, make_vec(np.zeros(10)), alpha="bb", expansion="optimal", norm_A=51.0)


def test_same_on_self_and_world_preconditioned_bb():
    A, b, l, u = box_problem("mixed", seed=8, n=80)
    A = scaled(A, np.random.default_rng(9))
    runs = []
    for comm in (PETSc.COMM_SELF, COMM):
        x = make_vec(np.zeros_like(b), comm)
        res = mprgp(make_mat(A, comm), make_vec(b, comm), x, lb=make_vec(l, comm),
                    ub=make_vec(u, comm), rtol=1e-10, alpha="bb",
                    norm_A=float(np.linalg.eigvalsh(A).max()),
                    preconditioner=Diagonal(1.0 / np.diag(A), x))
        runs.append((gather(x), res))
    (x1, r1), (x2, r2) = runs
    assert r1.converged and r2.converged
    assert abs(r1.iterations - r2.iterations) <= 2
    assert rel(x2, x1) <= 1e-9


# ---------------------------------------------------------------------------------- SMALBE

def test_projected_preconditioner_operator():
    """P M^{-1} P + Q / rho, and exact on Im D^T for the inner Hessian of A = P F P."""
    rng = np.random.default_rng(25)
    n, m, rho = 30, 4, 7.0
    D = rng.standard_normal((m, n))
    con = orthonormalize(row_block_constraint(D))
    Qo, _ = np.linalg.qr(D.T)
    Q = Qo @ Qo.T
    P = np.eye(n) - Q
    Minv = random_spd(n, rng)
    op = ProjectedPreconditioner(make_mat(Minv), con, rho)
    v = rng.standard_normal(n)
    out = make_vec(np.zeros(n))
    op.mult(make_vec(v), out)
    assert np.allclose(gather(out), (P @ Minv @ P + Q / rho) @ v, atol=1e-11)
    assert op.M.count == 1
    F = random_spd(n, rng)
    H = penalized_operator(projected_operator(make_mat(F), con), con, rho)
    w = Q @ v  # in Im D^T: the preconditioner inverts H there
    op.mult(make_vec(w), out)
    Hw = make_vec(np.zeros(n))
    H.mult(out, Hw)
    assert np.allclose(gather(Hw), w, atol=1e-11)


@pytest.mark.parametrize("form", ["projected", "plain"])
def test_smalbe_preconditioned(form):
    """Badly scaled FETI-like problem: Jacobi of F, projected (default) or plain."""
    F, G, e, d, lower, feasible = feti_like(seed=0, n=60, m=6)
    F = scaled(F, np.random.default_rng(11), decades=1.5)
    ref = ref_active_set(F, d, lower, np.full(len(d), np.inf), G, e, x0=feasible)
    n = len(d)
    lam0, res0, _, _ = solve_feti_like(F, G, e, d, lower, rtol=1e-10)
    M = Diagonal(1.0 / np.diag(F), make_vec(np.zeros(n)))
    lam, res, ctx, _ = solve_feti_like(F, G, e, d, lower, rtol=1e-10, preconditioner=M,
                                       preconditioner_form=form)
    assert res0.converged and res.converged
    assert rel(lam0, ref) <= 1e-8 and rel(lam, ref) <= 1e-8
    assert res.hessian_mults == ctx.calls
    assert res.counts["precond"] == M.calls > 0
    assert "precond" not in res0.counts
    if form == "projected":
        assert res.hessian_mults < 0.75 * res0.hessian_mults


def test_smalbe_preconditioned_bb():
    F, G, e, d, lower, feasible = feti_like(seed=1, n=60, m=6)
    ref = ref_active_set(F, d, lower, np.full(len(d), np.inf), G, e, x0=feasible)
    M = Diagonal(1.0 / np.diag(F), make_vec(np.zeros(len(d))))
    lam, res, _, _ = solve_feti_like(F, G, e, d, lower, rtol=1e-10, preconditioner=M,
                                     inner_options={"alpha": "bb"})
    assert res.converged and rel(lam, ref) <= 1e-8
    assert "rejected" in res.counts


def test_smalbe_preconditioner_validation():
    F, G, e, d, lower, _ = feti_like(seed=2, n=30, m=3)
    M = Diagonal(np.ones(30), make_vec(np.zeros(30)))
    with pytest.raises(ValueError, match="preconditioner"):
        solve_feti_like(F, G, e, d, lower, inner_options={"preconditioner": M})
    with pytest.raises(ValueError, match="preconditioner_form"):
        solve_feti_like(F, G, e, d, lower, preconditioner=M, preconditioner_form="nope")
    with pytest.raises(ValueError, match="inner solver"):
        smalbe(None, None, None, None, inner="cg")
