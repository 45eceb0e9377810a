"""The QP solvers as objects: set up once, solve many QPs; options by prefix; SMALBE's inner object.

Every QP here is plain NumPy/PETSc (no FETI); the references are independent: SciPy's BVLS, a
dense active-set method, a dense KKT solve, and the KKT conditions themselves.
"""

import ast
import sys
from pathlib import Path

import numpy as np
import pytest
from petsc4py import PETSc
from qp_helpers import (
    Diagonal,
    gather,
    make_mat,
    make_vec,
    random_spd,
    ref_active_set,
    ref_box,
    row_block_constraint,
)
from test_qp_mpgp import disc_problem, local_discs
from test_qp_mprgp import box_problem

from dolfinx_feti.errors import InputError
from dolfinx_feti.qp import (
    CG,
    MPGP,
    MPRGP,
    QP,
    SMALBE,
    Absolute,
    ConvergedReason,
    cg,
    mpgp,
    mprgp,
    orthonormalize,
    smalbe,
)
from dolfinx_feti.qp.expansion import (
    BarzilaiBorweinExpansion,
    Expansion,
    OptimalExpansion,
    ProjectedCGExpansion,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))
import cone_qp  # noqa: E402
from petsc_db import petsc_options  # noqa: E402

QP_DIR = Path(__file__).resolve().parents[2] / "dolfinx_feti" / "qp"


def zeros_like(b: PETSc.Vec) -> PETSc.Vec:
    x = b.duplicate()
    x.set(0.0)
    return x


def box_qp(kind: str, seed: int, n: int = 60):
    A, b, l, u = box_problem(kind, seed=seed, n=n)
    qp = QP.create(make_mat(A), make_vec(b), lb=make_vec(l), ub=make_vec(u),
                   norm_A=float(np.linalg.norm(A, 2)))
    return qp, (A, b, l, u)


def equality_qp(seed: int, n: int = 40, m: int = 4):
    """A box QP with ``D x = 0`` (D orthonormalized on the PETSc side, kept dense here)."""
    rng = np.random.default_rng(seed)
    A = random_spd(n, rng, cond=30.0)
    b = 3.0 * rng.standard_normal(n)
    l, u = np.full(n, -0.4), np.full(n, np.inf)
    u[: n // 4] = 0.5
    Dd = rng.standard_normal((m, n))
    con = orthonormalize(row_block_constraint(Dd))
    qp = QP.create(make_mat(A), make_vec(b), lb=make_vec(l), ub=make_vec(u), eq=con,
                   norm_A=float(np.linalg.norm(A, 2)))
    return qp, (A, b, l, u, Dd)


def same(r1, x1, r2, x2) -> bool:
    """Identical runs: iterates, counts and reasons (bit for bit)."""
    return (np.array_equal(gather(x1), gather(x2)) and r1.counts == r2.counts
            and r1.hessian_mults == r2.hessian_mults and r1.reason == r2.reason
            and r1.iterations == r2.iterations)


def test_one_object_solves_many_qps():
    """An MPRGP made once solves QPs of different sizes and bounds, each as a new object."""
    solver = MPRGP(rtol=1e-10, expansion="projcg", gamma=0.8)
    for kind, seed, n in (("box", 1, 60), ("mixed", 2, 40), ("lower", 3, 60), ("box", 1, 60)):
        qp, (A, b, l, u) = box_qp(kind, seed, n)
        x = zeros_like(qp.b)
        res = solver.solve(qp, x)
        assert res.converged and res.converged_reason == ConvergedReason.CONVERGED_RTOL
        ref = ref_box(A, b, l, u)
        assert np.linalg.norm(gather(x) - ref) <= 1e-8 * np.linalg.norm(ref)
        fresh = zeros_like(qp.b)
        again = MPRGP(rtol=1e-10, expansion="projcg", gamma=0.8).solve(qp, fresh)
        assert same(res, x, again, fresh)  # nothing of the earlier solves was kept


def test_functions_are_the_objects():
    """cg, mprgp, mpgp and smalbe give the iterates and counts of their objects."""
    qp, (A, b, l, u) = box_qp("mixed", 4)
    M = Diagonal(1.0 / np.diag(A), qp.b)
    qp.preconditioner = M
    x1, x2 = zeros_like(qp.b), zeros_like(qp.b)
    r1 = MPRGP(rtol=1e-9, alpha="bb").solve(qp, x1)
    r2 = mprgp(qp.A, qp.b, x2, lb=make_vec(l), ub=make_vec(u), rtol=1e-9, alpha="bb",
               norm_A=qp.norm_A, preconditioner=M)
    assert same(r1, x1, r2, x2) and "rejected" in r1.counts
    x1, x2 = zeros_like(qp.b), zeros_like(qp.b)
    r1 = MPGP(rtol=1e-9, gamma=2.0).solve(qp, x1)
    r2 = mpgp(qp.A, qp.b, x2, lb=make_vec(l), ub=make_vec(u), rtol=1e-9, gamma=2.0,
              norm_A=qp.norm_A, preconditioner=M)
    assert same(r1, x1, r2, x2)

    eqp, (A, b, l, u, Dd) = equality_qp(5)
    x1, x2 = zeros_like(eqp.b), zeros_like(eqp.b)
    r1 = SMALBE(MPRGP(), rtol=1e-9, rho=Absolute(3.0), M=2.0, acceleration="none",
                depth=5).solve(eqp, x1)
    r2 = smalbe(eqp.A, eqp.b, eqp.eq, x2, lb=make_vec(l), ub=make_vec(u), rtol=1e-9, rho=3.0,
                M=2.0 * eqp.norm_A, norm_A=eqp.norm_A)
    assert same(r1, x1, r2, x2) and np.array_equal(r1.multiplier, r2.multiplier)

    free = QP(eqp.A, eqp.b, eq=eqp.eq)
    x1, x2 = zeros_like(eqp.b), zeros_like(eqp.b)
    from dolfinx_feti.qp import Projector

    r1 = CG(rtol=1e-10).solve(free, x1)
    r2 = cg(eqp.A, eqp.b, x2, projector=Projector(eqp.eq), rtol=1e-10)
    assert same(r1, x1, r2, x2)


def test_options_from_the_database_under_the_prefix():
    """-feti_smalbe_* and -feti_mprgp_* set SMALBE and its default inner MPRGP; keywords win."""
    eqp, (A, b, l, u, Dd) = equality_qp(6)
    with petsc_options(feti_smalbe_rho="2.5", feti_smalbe_acceleration="none",
                       feti_smalbe_eta="0.05", feti_mprgp_gamma="0.5",
                       feti_mprgp_expansion="optimal", myqp_mprgp_alpha="bb"):
        s = SMALBE(options_prefix="feti_", M=4.0, rtol=1e-9)
        assert (s.rho, s.M, s.eta, s.acceleration, s.depth) == (2.5, 4.0, 0.05, "none", 3)
        assert isinstance(s.inner, MPRGP) and s.inner.gamma == 0.5
        assert isinstance(s.inner.expansion_step, OptimalExpansion)
        own = MPRGP(options_prefix="myqp_")  # another prefix: only its own options
        assert (own.gamma, own.expansion, own.alpha) == (1.0, "fixed", "bb")
        assert isinstance(own.expansion_step, BarzilaiBorweinExpansion)
        assert MPRGP().gamma == 1.0  # no prefix: the database is not read
        assert MPRGP(options_prefix="feti_", gamma=3.0).gamma == 3.0
        x1 = zeros_like(eqp.b)
        r1 = s.solve(eqp, x1)
    # relative options: the same solve as the absolute values they stand for
    x2 = zeros_like(eqp.b)
    r2 = smalbe(eqp.A, eqp.b, eqp.eq, x2, lb=make_vec(l), ub=make_vec(u), rtol=1e-9,
                rho=2.5 * eqp.norm_A, M=4.0 * eqp.norm_A, eta=0.05 * eqp.b.norm(),
                norm_A=eqp.norm_A, inner_options={"gamma": 0.5, "expansion": "optimal"})
    assert r1.converged and same(r1, x1, r2, x2)
    with petsc_options(feti_mprgp_gamma="-1"), pytest.raises(InputError, match="mprgp_gamma"):
        MPRGP(options_prefix="feti_")
    with petsc_options(feti_smalbe_depth="many"), pytest.raises(InputError, match="depth"):
        SMALBE(options_prefix="feti_")


def test_smalbe_owns_an_mpgp_on_discs():
    """SMALBE(MPGP()) on discs, bounds and D x = 0: the KKT conditions hold; one object twice."""
    A, b, lb, ub, pairs, centre, radius = disc_problem(7, mixed=True)
    n = len(b)
    rng = np.random.default_rng(7)
    Dd = rng.standard_normal((3, n))
    con = orthonormalize(row_block_constraint(Dd))
    radius = np.maximum(radius, np.linalg.norm(centre, axis=1) + 0.05)  # 0 is feasible
    radius[-1] = np.inf
    lb, ub = np.minimum(lb, 0.0), np.maximum(ub, 0.0)
    # eq_rtol: ||D x|| <= eq_rtol ||b|| <= 1e-9 below for both scales (||b|| = 23.4, 46.9),
    # by the stopping test and not by the path (the default eq_rtol = rtol left 2.6e-9 at
    # scale -2 on two ranks once MPGP deferred the products of its pull-backs)
    solver = SMALBE(MPGP(face="tangent"), rtol=1e-10, eq_rtol=2e-11, acceleration="anderson")
    for scale in (1.0, -2.0):  # two QPs, one solver
        bv = make_vec(scale * b)
        x = zeros_like(bv)
        qp = QP.create(make_mat(A), bv, lb=make_vec(lb), ub=make_vec(ub), eq=con,
                       discs=local_discs(x, pairs, centre, radius))
        res = solver.solve(qp, x)
        assert res.converged and res.converged_reason == ConvergedReason.CONVERGED_KKT
        assert res.counts["norm"] > 0  # ||A|| was not given: estimated and counted
        xa = gather(x)
        Dt = np.linalg.qr(Dd.T)[0]  # the same row space, orthonormal
        assert np.abs(Dt.T @ xa).max() <= 1e-9
        cs = cone_qp.ConeSet(lb, ub, pairs, centre, radius)
        assert np.allclose(cs.project(xa), xa, rtol=0, atol=1e-12)
        # KKT: x = P(x - γ(∇f + Dᵀμ)) with the returned multiplier (D the orthonormalized D)
        Dt_mu = gather(_dt_mu(con, res.multiplier, bv))
        g = A @ xa - scale * b + Dt_mu
        gamma = 1.0 / np.linalg.norm(A, 2)
        nat = np.linalg.norm(xa - cs.project(xa - gamma * g)) / gamma
        assert nat <= 1e-8 * np.linalg.norm(b)


def _dt_mu(con, mu, like: PETSc.Vec) -> PETSc.Vec:
    out = like.duplicate()
    con.mult_transpose(mu, out)
    return out


def test_numpy_qp_against_dense_references():
    """Bounds and equalities by SMALBE, the equality alone by CG: dense active set and KKT."""
    eqp, (A, b, l, u, Dd) = equality_qp(8)
    x = zeros_like(eqp.b)
    res = SMALBE(rtol=1e-11).solve(eqp, x)
    assert res.converged
    ref = ref_active_set(A, b, l, u, D=Dd, e=np.zeros(len(Dd)), x0=np.zeros(len(b)))
    assert np.linalg.norm(gather(x) - ref) <= 1e-8 * np.linalg.norm(ref)
    # min 1/2 x'Ax - b'x s.t. D x = 0: the KKT system [[A, D'], [D, 0]]
    n, m = A.shape[0], Dd.shape[0]
    K = np.block([[A, Dd.T], [Dd, np.zeros((m, m))]])
    kkt = np.linalg.solve(K, np.concatenate([b, np.zeros(m)]))[:n]
    y = zeros_like(eqp.b)
    cres = CG(rtol=1e-12, max_it=200).solve(QP(eqp.A, eqp.b, eq=eqp.eq), y)
    assert cres.converged and np.linalg.norm(gather(y) - kkt) <= 1e-9 * np.linalg.norm(kkt)


@pytest.mark.parametrize("expansion, alpha, kind", [
    ("fixed", "fixed", Expansion), ("optimal", "fixed", OptimalExpansion),
    ("projcg", "fixed", ProjectedCGExpansion), ("fixed", "bb", BarzilaiBorweinExpansion)])
def test_variant_chosen_once(expansion, alpha, kind):
    solver = MPRGP(expansion=expansion, alpha=alpha)
    assert type(solver.expansion_step) is kind
    qp, (A, b, l, u) = box_qp("box", 9)
    x = zeros_like(qp.b)
    res = solver.solve(qp, x)
    assert res.converged and ("rejected" in res.counts) == kind.rejects


def test_refused_by_name():
    qp, _ = box_qp("box", 10)
    eqp, _ = equality_qp(10)
    with pytest.raises(ValueError, match="expansion='fixed'"):
        MPGP(expansion="optimal", alpha="bb")
    with pytest.raises(InputError, match="mpgp gamma"):
        MPGP(gamma=0.0)
    with pytest.raises(ValueError, match="preconditioning"):
        MPGP(preconditioning="somewhere")
    with pytest.raises(ValueError, match="equality"):
        MPGP().solve(eqp, zeros_like(eqp.b))
    with pytest.raises(ValueError, match="inequality"):
        CG().solve(qp, zeros_like(qp.b))
    with pytest.raises(ValueError, match="no equality"):
        SMALBE().solve(qp, zeros_like(qp.b))
    with pytest.raises(TypeError, match="CG cannot be the inner solver"):
        SMALBE(CG())
    A, b, lb, ub, pairs, centre, radius = disc_problem(0)
    bv = make_vec(b)
    discs = QP.create(make_mat(A), bv, discs=local_discs(bv, pairs, centre, radius))
    with pytest.raises(ValueError, match="disc"):
        MPRGP().solve(discs, zeros_like(bv))
    with pytest.raises(ValueError, match="fixed expansion"):
        MPGP(expansion="optimal").solve(discs, zeros_like(bv))


def test_preconditioning_chosen_once():
    """The QP's preconditioner is applied in face unless the solver was made without it."""
    qp, (A, b, l, u) = box_qp("mixed", 11)
    qp.preconditioner = Diagonal(1.0 / np.diag(A), qp.b)
    x1, x2 = zeros_like(qp.b), zeros_like(qp.b)
    r1 = MPRGP(rtol=1e-9).solve(qp, x1)
    r2 = MPRGP(rtol=1e-9, preconditioning="none").solve(qp, x2)
    assert r1.counts["precond"] > 0 and "precond" not in r2.counts
    qp.preconditioner = None
    x3 = zeros_like(qp.b)
    assert same(r2, x2, MPRGP(rtol=1e-9).solve(qp, x3), x3)


def test_signed_reason_from_the_solver():
    qp, _ = box_qp("box", 12)
    res = MPRGP(rtol=1e-12, max_it=3).solve(qp, zeros_like(qp.b))
    assert res.converged_reason == ConvergedReason.DIVERGED_MAX_IT < 0
    eqp, _ = equality_qp(12)
    res = SMALBE(rtol=1e-12, max_outer=1).solve(eqp, zeros_like(eqp.b))
    assert res.converged_reason == ConvergedReason.DIVERGED_MAX_OUTER


def _body_lines(fn: ast.FunctionDef) -> int:
    first = fn.body[0]
    docstring = isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
        and isinstance(first.value.value, str) and len(fn.body) > 1
    start = fn.body[1].lineno if docstring else first.lineno
    return fn.end_lineno - start + 1


def test_solver_functions_are_short():
    """No function of the QP solvers is longer than 60 lines of code (docstrings aside)."""
    files = ["cg.py", "mpgp.py", "mpgp_steps.py", "expansion.py", "mprgp.py", "smalbe.py",
             "solver.py", "problem.py", "anderson.py", "aitken.py", "dual_search.py"]
    long = []
    for name in files:
        tree = ast.parse((QP_DIR / name).read_text())
        long += [(name, f.name, _body_lines(f)) for f in ast.walk(tree)
                 if isinstance(f, ast.FunctionDef) and _body_lines(f) > 60]
    assert not long, long
