"""MPGP on QPs with interval and disc constraints: agreement with a dense reference, KKT, SMALBE."""

import sys
from pathlib import Path

import numpy as np
import pytest
from qp_helpers import (
    COMM,
    MPI_COMM,
    gather,
    gather_local,
    make_mat,
    make_vec,
    ownership,
    random_spd,
    ref_box,
    row_block_constraint,
)

from dolfinx_feti.qp import Discs, mpgp, mprgp, smalbe

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "support"))
import cone_qp  # noqa: E402

N = 60  # even, and even per rank for 1, 2 or 3 ranks: disc pairs (2k, 2k+1) stay local


def disc_problem(seed: int = 0, n: int = N, mixed: bool = False):
    """Random SPD QP; entries paired (2k, 2k+1) in discs, or (mixed) a mix of discs, lower
    bounds, boxes, free entries, a point (radius 0) and an unbounded disc (radius inf)."""
    rng = np.random.default_rng(seed)
    A = random_spd(n, rng, cond=50.0)
    b = 3.0 * rng.standard_normal(n)
    lb, ub = np.full(n, -np.inf), np.full(n, np.inf)
    pairs = np.arange(n).reshape(-1, 2)
    if mixed:
        which = rng.integers(0, 4, n // 2)  # 0, 1: disc; 2: lower bounds; 3: free/box
        which[:3] = [0, 2, 3]
        keep = which <= 1
        lo = pairs[which == 2].ravel()
        lb[lo] = rng.uniform(-0.5, 0.0, lo.size)
        bx = pairs[which == 3][:, 0]
        lb[bx], ub[bx] = -0.2, 0.3
        pairs = pairs[keep]
    k = pairs.shape[0]
    centre = 0.3 * rng.standard_normal((k, 2))
    radius = rng.uniform(0.05, 0.5, k)
    if mixed:
        radius[0], radius[-1] = 0.0, np.inf
    return A, b, lb, ub, pairs, centre, radius


def local_discs(x, pairs, centre, radius) -> Discs:
    lo, hi = x.getOwnershipRange()
    mine = (pairs[:, 0] >= lo) & (pairs[:, 1] < hi)
    straddle = (pairs[:, 0] < hi) & (pairs[:, 1] >= hi)
    assert not straddle.any(), "a disc pair straddles two ranks"
    return Discs(pairs[mine] - lo, centre[mine], radius[mine])


def run(A, b, lb, ub, pairs, centre, radius, **kw):
    Am, bv = make_mat(A), make_vec(b)
    x = bv.duplicate()
    x.set(0.0)
    lo, hi = x.getOwnershipRange()
    lbv, ubv = make_vec(lb), make_vec(ub)
    res = mpgp(Am, bv, x, lb=lbv, ub=ubv, discs=local_discs(x, pairs, centre, radius), **kw)
    return res, gather(x)


@pytest.mark.parametrize("face", ["tangent", "interior"])
@pytest.mark.parametrize("mixed", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_against_dense_reference(seed, mixed, face):
    A, b, lb, ub, pairs, centre, radius = disc_problem(seed, mixed=mixed)
    res, x = run(A, b, lb, ub, pairs, centre, radius, rtol=1e-11, face=face)
    assert res.converged, res.reason
    cs = cone_qp.ConeSet(lb, ub, pairs, centre, radius)
    ref = cone_qp.solve(A, b, cs)
    assert cone_qp.natural_residual(A, b, cs, ref) <= 1e-13
    assert np.abs(x - ref).max() <= 1e-8 * np.abs(ref).max()
    # feasible to round-off, and a good share of discs on their circles
    Y = x[pairs] - centre
    assert np.all(np.linalg.norm(Y, axis=1) <= radius * (1 + 1e-13) + 1e-15)
    assert np.all(x >= lb) and np.all(x <= ub)
    on = np.linalg.norm(ref[pairs] - centre, axis=1) >= radius * (1 - 1e-9)
    assert 0 < on.sum() < on.size
    active = gather_local(res.active)
    assert np.array_equal(active[pairs[:, 0]], active[pairs[:, 1]])
    assert res.active_count == int(active.sum())


def test_intervals_only_agree_with_mprgp_and_bvls():
    rng = np.random.default_rng(5)
    A = random_spd(N, rng, cond=30.0)
    b = 2.0 * rng.standard_normal(N)
    lb, ub = np.full(N, -0.3), np.full(N, 0.4)
    ref = ref_box(A, b, lb, ub)
    empty = np.zeros((0, 2), dtype=int)
    res, x = run(A, b, lb, ub, empty, np.zeros((0, 2)), np.zeros(0), rtol=1e-11)
    assert res.converged
    assert np.abs(x - ref).max() <= 1e-8 * np.abs(ref).max()
    Am, bv = make_mat(A), make_vec(b)
    y = bv.duplicate()
    y.set(0.0)
    r2 = mprgp(Am, bv, y, lb=make_vec(lb), ub=make_vec(ub), rtol=1e-11)
    assert np.abs(gather(y) - x).max() <= 1e-8 * np.abs(ref).max()
    assert r2.converged


def test_kkt_of_the_result():
    """gᴾ = φ + β is the KKT residual: recompute it here from the definition of the normal cone."""
    A, b, lb, ub, pairs, centre, radius = disc_problem(3)
    res, x = run(A, b, lb, ub, pairs, centre, radius, rtol=1e-10)
    g = A @ x - b
    bn = np.linalg.norm(b)
    for (i, j), c, r in zip(pairs, centre, radius, strict=True):
        y = x[[i, j]] - c
        gi = g[[i, j]]
        if np.linalg.norm(y) >= r * (1 - 1e-12):  # on the circle: g = −ξ n, ξ >= 0
            n = y / np.linalg.norm(y)
            assert gi @ n <= 1e-10 * bn
            assert np.linalg.norm(gi - (gi @ n) * n) <= 1e-10 * bn
        else:
            assert np.linalg.norm(gi) <= 1e-10 * bn
    assert res.gP_norm <= 1e-10 * bn


@pytest.mark.parametrize("face", ["tangent", "interior"])
def test_monotone_energy_and_counts(face):
    A, b, lb, ub, pairs, centre, radius = disc_problem(4)
    Am, bv = make_mat(A), make_vec(b)
    x = bv.duplicate()
    x.set(0.0)
    energies = []

    def monitor(it, gP, kind):
        xa = gather(x)
        energies.append(0.5 * xa @ A @ xa - b @ xa)

    res = mpgp(Am, bv, x, discs=local_discs(x, pairs, centre, radius), rtol=1e-10,
               monitor=monitor, norm_A=float(np.linalg.norm(A, 2)), face=face)
    assert res.converged
    assert np.all(np.diff(energies) <= 1e-12 * max(1.0, abs(energies[0])))
    c = res.counts
    steps = c["cg"] + c["expansion"] + c["proportioning"]
    assert res.iterations == steps
    if face == "interior":
        assert res.hessian_mults == 1 + steps + c["expansion"]
    else:  # turning steps cost a second multiplication, a rejected one two more
        assert 1 + steps + c["expansion"] <= res.hessian_mults
        assert res.hessian_mults <= 1 + 2 * steps + c["expansion"] + 2 * c.get("rejected", 0)
        assert res.iterations < 60  # the plain algorithm needs about 100 here


def test_warm_start_and_g_valid():
    A, b, lb, ub, pairs, centre, radius = disc_problem(6)
    res, x = run(A, b, lb, ub, pairs, centre, radius, rtol=1e-10)
    Am, bv = make_mat(A), make_vec(b)
    xv = make_vec(x)
    g = make_vec(A @ x - b)
    res2 = mpgp(Am, bv, xv, discs=local_discs(xv, pairs, centre, radius), rtol=1e-9, g=g,
                g_valid=True, norm_A=float(np.linalg.norm(A, 2)))
    assert res2.converged and res2.iterations == 0 and res2.hessian_mults == 0


@pytest.mark.parametrize("face", ["tangent", "interior"])
def test_preconditioned_in_face_same_solution(face):
    A, b, lb, ub, pairs, centre, radius = disc_problem(7, mixed=True)
    cs = cone_qp.ConeSet(lb, ub, pairs, centre, radius)
    ref = cone_qp.solve(A, b, cs)
    d = 1.0 / np.diag(A)
    lo, hi = ownership(N)

    def jacobi(x, y):
        y.array[:] = d[lo:hi] * x.array_r

    res, x = run(A, b, lb, ub, pairs, centre, radius, rtol=1e-11, preconditioner=jacobi,
                 face=face)
    assert res.converged and res.counts["precond"] > 0
    assert np.abs(x - ref).max() <= 1e-8 * np.abs(ref).max()


def test_smalbe_with_mpgp_inner():
    """Discs and an equality D x = 0: SMALBE-M with MPGP inside; checked by its KKT conditions
    (feasibility, D x = 0, and the projected gradient of A x − b + Dᵀμ, recomputed here)."""
    A, b, lb, ub, pairs, centre, radius = disc_problem(8, mixed=True)
    rng = np.random.default_rng(8)
    m = 4
    D = np.linalg.qr(rng.standard_normal((N, m)))[0].T  # orthonormal rows
    P = np.eye(N) - D.T @ D
    A = P @ A @ P  # SMALBE's setting: A = P A P, positive definite on ker D
    con = row_block_constraint(D)
    Am, bv = make_mat(A), make_vec(P @ b)
    x = bv.duplicate()
    x.set(0.0)
    # a feasible point of the set with D x = 0 exists (0 is inside every disc? make it so)
    centre = 0.5 * centre
    radius = np.maximum(radius, np.linalg.norm(centre, axis=1) + 0.05)
    radius[-1] = np.inf
    lb = np.minimum(lb, 0.0)
    ub = np.maximum(ub, 0.0)
    res = smalbe(Am, bv, con, x, lb=make_vec(lb), ub=make_vec(ub), rtol=1e-10,
                 inner="mpgp", inner_options={"discs": local_discs(x, pairs, centre, radius)},
                 norm_A=float(np.linalg.norm(A, 2)))
    assert res.converged, res.reason
    xa = gather(x)
    assert np.abs(D @ xa).max() <= 1e-9
    g = A @ xa - P @ b + D.T @ res.multiplier
    cs = cone_qp.ConeSet(lb, ub, pairs, centre, radius)
    gamma = 1.0 / np.linalg.norm(A, 2)
    nat = np.linalg.norm(xa - cs.project(xa - gamma * g)) / gamma
    assert nat <= 1e-8 * np.linalg.norm(b)
    # the same minimizer as a dense reference on ker D with a large penalty is not exact;
    # instead: no feasible point of lower energy along a few random feasible directions
    f0 = 0.5 * xa @ A @ xa - (P @ b) @ xa
    for _ in range(20):
        y = cs.project(xa + 0.01 * P @ rng.standard_normal(N))
        y = y - D.T @ (D @ y)  # back to ker D (may leave the set slightly: skip those)
        if np.all(y >= lb) and np.all(y <= ub) and np.all(
                np.linalg.norm(y[pairs] - centre, axis=1) <= radius):
            assert 0.5 * y @ A @ y - (P @ b) @ y >= f0 - 1e-10


def test_invalid_discs():
    A, b, lb, ub, pairs, centre, radius = disc_problem(0)
    Am, bv = make_mat(A), make_vec(b)
    x = bv.duplicate()
    x.set(0.0)
    discs = local_discs(x, pairs, centre, -radius)
    with pytest.raises(ValueError, match="radius"):
        mpgp(Am, bv, x, discs=discs)
    lbv = make_vec(np.zeros(N))
    with pytest.raises(ValueError, match="finite lb/ub"):
        mpgp(Am, bv, x, lb=lbv, discs=local_discs(x, pairs, centre, radius))
    with pytest.raises(ValueError, match="fixed"):
        mpgp(Am, bv, x, discs=local_discs(x, pairs, centre, radius), expansion="optimal")
    with pytest.raises(ValueError, match="face"):
        mpgp(Am, bv, x, discs=local_discs(x, pairs, centre, radius), face="curved")
    assert MPI_COMM.size == COMM.size
