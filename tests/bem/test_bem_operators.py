"""The 2D boundary integral operators: closed forms, symmetry, definiteness, kernels, accuracy.

Checked against brute-force adaptive quadrature (the segment integrals), the analytic
Dirichlet-to-Neumann map of a disk (Laplace), Kelvin's solution with its source outside
(Lamé), and a harmonic function inside (the representation formula).
"""

from __future__ import annotations

import numpy as np
import pytest
from bem_shapes import batch, disk, kelvin, l_shape, rigid, square, traction_load
from scipy.integrate import quad

from dolfinx_feti.bem.galerkin import BoundaryMesh
from dolfinx_feti.bem.operators import lame_operators, laplace_operators
from dolfinx_feti.bem.segments import (
    Local,
    double_layer_moments,
    dyad_double_layer_moments,
    dyad_moments,
    log_moments,
)
from dolfinx_feti.bem.steklov import interior_maps, steklov

MU, NU = 3.0, 0.3
LAM = 2 * MU * NU / (1 - 2 * NU)


def _brute_moments(a: float, d: float, L: float) -> list[float]:
    """The moments of :mod:`.segments` by adaptive quadrature over u ∈ [−a, L − a]."""
    u1, u2 = -a, L - a
    pts = [0.0] if u1 < 0 < u2 else None

    def integrate(f):
        return quad(f, u1, u2, points=pts, limit=200, epsabs=1e-13, epsrel=1e-12)[0]

    def R2(u):
        return u * u + d * d

    kernels = [lambda u: 0.5 * np.log(R2(u)), lambda u: u * 0.5 * np.log(R2(u)),
               lambda u: u * u / R2(u), lambda u: -u * d / R2(u), lambda u: d * d / R2(u),
               lambda u: d / R2(u), lambda u: u * d / R2(u)]
    parts = (lambda u: u * u, lambda u: -u * d, lambda u: d * d)
    kernels += [lambda u, k=k, c=c: d * u ** k * c(u) / R2(u) ** 2 for k in (0, 1) for c in parts]
    return [integrate(f) for f in kernels]


def test_segment_integrals_match_adaptive_quadrature():
    rng = np.random.default_rng(1)
    p = rng.uniform(-1, 1, (12, 2))
    ang = rng.uniform(0, 2 * np.pi, 12)
    tau = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    L = rng.uniform(0.1, 1.0, 12)
    x = p + rng.uniform(-1, 1, (12, 2))
    x[0] = p[0] + 0.3 * L[0] * tau[0]  # on the segment: the double layers vanish
    x[1] = p[1] + 1e-3 * np.array([tau[1, 1], -tau[1, 0]]) + 0.5 * L[1] * tau[1]  # near it
    loc = Local.of(x, p, tau, L)
    got = np.stack([*log_moments(loc), *dyad_moments(loc), *double_layer_moments(loc),
                    *dyad_double_layer_moments(loc)[0], *dyad_double_layer_moments(loc)[1]])
    for i in range(12):
        want = _brute_moments(loc.a[i], loc.d[i], L[i])
        if i == 0:  # on the segment's line: the flat double layer is zero, not a jump
            want[5:] = [0.0] * 8
        np.testing.assert_allclose(got[:, i], want, rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("shape", [square, l_shape])
@pytest.mark.parametrize("bs", [1, 2])
def test_single_layer_spd_and_steklov_kernel(shape, bs):
    bm = shape(6)
    op = (laplace_operators(bm) if bs == 1 else
          lame_operators(bm, np.array([MU]), np.array([NU])))[0]
    np.testing.assert_array_equal(op.V, op.V.T)
    assert np.linalg.eigvalsh(op.V).min() > 0
    S = steklov(op)
    assert np.abs(S - S.T).max() <= 1e-13 * np.abs(S).max()
    ev = np.linalg.eigvalsh(0.5 * (S + S.T))
    k = 1 if bs == 1 else 3
    assert np.all(np.abs(ev[:k]) <= 1e-12 * ev[-1])  # exactly k zero eigenvalues ...
    assert ev[k] > 1e-3 * ev[-1]  # ... and no more
    R = rigid(bm.x, bs)
    assert np.abs(S @ R).max() <= 1e-12 * np.abs(S).max() * np.abs(R).max()


def _p1_mass(bm: BoundaryMesh) -> np.ndarray:
    n = bm.x.shape[0]
    M = np.zeros((n, n))
    for k, w in ((0, 0), (1, 1)):
        np.add.at(M, (bm.elem[:, k], bm.elem[:, w]), bm.length / 3)
    np.add.at(M, (bm.elem[:, 0], bm.elem[:, 1]), bm.length / 6)
    np.add.at(M, (bm.elem[:, 1], bm.elem[:, 0]), bm.length / 6)
    return M


def test_disk_dirichlet_to_neumann_converges():
    """S cos(kθ) → k cos(kθ)/R on a disk of radius R, at second order in h."""
    radius, errors = 0.4, []
    for n in (32, 64, 128):
        bm = disk(n, radius)
        S = steklov(laplace_operators(bm)[0])
        th = np.arctan2(bm.x[:, 1], bm.x[:, 0])
        M = _p1_mass(bm)
        err = 0.0
        for k in (1, 2, 3):
            u = np.cos(k * th)
            t = np.linalg.solve(M, S @ u)
            err = max(err, np.abs(t - k * u / radius).max() / (k / radius))
        errors.append(err)
    assert errors[-1] < 2e-4
    assert errors[0] / errors[1] > 3.5 and errors[1] / errors[2] > 3.5


@pytest.mark.parametrize("shape", [square, l_shape])
def test_lame_steklov_against_kelvin(shape):
    """⟨S u, φ_i⟩ → ∫ σ(u)n φ_i for Kelvin's solution with its source outside."""
    x0 = np.array([0.5, 0.17])
    errors = []
    for n in (4, 8, 16):
        bm = shape(n)
        S = steklov(lame_operators(bm, np.array([MU]), np.array([NU]))[0])
        for j in (0, 1):
            u, _ = kelvin(bm.x, x0, j, MU, NU)

            def traction(X, nrm, j=j):
                g = kelvin(X, x0, j, MU, NU)[1]
                eps = 0.5 * (g + g.transpose(0, 2, 1))
                sig = 2 * MU * eps + LAM * np.trace(eps, axis1=1, axis2=2)[:, None, None] * \
                    np.eye(2)
                return np.einsum("iab,ib->ia", sig, nrm)

            b = traction_load(bm, traction, 2)
            errors.append(np.linalg.norm(S @ u.ravel() - b) / np.linalg.norm(b))
    e = np.array(errors).reshape(3, 2).max(axis=1)
    assert e[-1] < 1e-2
    assert e[0] / e[1] > 2.5 and e[1] / e[2] > 2.5


@pytest.mark.parametrize("bs", [1, 2])
def test_representation_formula_inside(bs):
    """Interior values of a solution from its boundary values (two subdomains at once)."""
    x0 = np.array([0.55, -0.2])
    errors = []
    for n in (8, 16, 32):
        bm = batch([square(n), l_shape(n // 2)])
        mu, nu = np.array([MU, MU]), np.array([NU, NU])
        ops = laplace_operators(bm) if bs == 1 else lame_operators(bm, mu, nu)
        X = np.array([[0.1, 0.1], [0.15, 0.2], [0.12, 0.08], [0.3, 0.1]])
        sub = np.array([0, 0, 1, 1])
        E = interior_maps(bm, ops, X, sub, bs, mu, nu)

        def exact(y):
            if bs == 1:
                return np.log(np.linalg.norm(y - x0, axis=1))[:, None]
            return kelvin(y, x0, 0, MU, NU)[0] + kelvin(y, x0, 1, MU, NU)[0]

        err = 0.0
        for s in (0, 1):
            nodes = slice(bm.node_off[s], bm.node_off[s + 1])
            got = E[s] @ exact(bm.x[nodes]).ravel()
            want = exact(X[sub == s]).ravel()
            err = max(err, np.abs(got - want).max() / np.abs(want).max())
        errors.append(err)
    assert errors[-1] < 1e-3
    assert errors[0] / errors[1] > 3 and errors[1] / errors[2] > 3
