"""The geometries added for friction: meshes.hertz2d_full and meshes.tresca2d; tangent bases."""

from __future__ import annotations

import numpy as np
import pytest

import dolfinx_feti as df
from dolfinx_feti.constraints.friction import tangent_basis
from dolfinx_feti.io import meshes


def contact_abscissae(mesh, group):
    return np.sort(mesh.x[np.unique(mesh.facet_groups[group]), 0])


def test_hertz2d_full():
    h, R = 0.1, 8.0
    mesh = df.build_mesh(meshes.hertz2d_full, h_contact=h, R=R)
    assert set(mesh.body_names) == {"disk", "block"}
    for g in ("disk_contact", "block_contact", "load", "bottom"):
        assert mesh.facet_groups[g].shape[0] > 0
    xs, xm = contact_abscissae(mesh, "disk_contact"), contact_abscissae(mesh, "block_contact")
    assert np.allclose(xs, xm, rtol=0, atol=1e-12)
    assert np.allclose(xs, -xs[::-1], atol=1e-12) and np.allclose(np.diff(xs), h)
    s = np.unique(mesh.facet_groups["disk_contact"])
    assert np.allclose(np.hypot(mesh.x[s, 0], mesh.x[s, 1] - R), R, atol=1e-10)  # on the circle
    load = np.unique(mesh.facet_groups["load"])
    assert np.allclose(mesh.x[load, 1], R) and np.isclose(np.ptp(mesh.x[load, 0]), 2 * R)
    with pytest.raises(ValueError):
        meshes.hertz2d_full(h_contact=3.0, contact_width=2.5)


@pytest.mark.parametrize("foundation", [(4.0, 1.0), None])
def test_tresca2d(foundation):
    mesh = df.build_mesh(meshes.tresca2d, n=4, foundation=foundation)
    bodies = {"block"} if foundation is None else {"block", "foundation"}
    assert set(mesh.body_names) == bodies
    xb = contact_abscissae(mesh, "block_bottom")
    assert np.allclose(np.diff(xb), 0.25)
    if foundation is not None:
        xf = contact_abscissae(mesh, "foundation_top")
        assert np.all(np.min(np.abs(xb[:, None] - xf[None, :]), axis=1) < 1e-12)  # matching
        assert np.isclose(xb.min(), 1.0) and np.isclose(xb.max(), 3.0)
    with pytest.raises(ValueError):
        meshes.tresca2d(n=4, block=(5.0, 1.0))


@pytest.mark.parametrize("d", [2, 3])
def test_tangent_basis_orthonormal(d):
    rng = np.random.default_rng(d)
    n = rng.standard_normal((50, d))
    n[:3] = np.eye(d)[:3] if d == 3 else np.vstack([np.eye(2), [[0.6, -0.8]]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    T = tangent_basis(n)
    assert T.shape == (50, d - 1, d)
    frame = np.concatenate([T, n[:, None, :]], axis=1)  # (t..., n)
    assert np.allclose(np.einsum("kij,klj->kil", frame, frame), np.eye(d), atol=1e-14)
    assert np.allclose(np.linalg.det(frame), 1.0)  # right-handed
    if d == 2:
        assert np.allclose(tangent_basis(np.array([[0.0, 1.0]])), [[[1.0, 0.0]]])


def test_tangent_basis_ignores_round_off_in_a_coordinate_plane():
    """A normal along y with round-off in x and z gets t1 = e_x whichever is larger: the
    tangents of one node must not swap between Newton iterates (the exact check of the rows
    of u took 19 iterations of the cone's last step in tests/drivers/
    test_newton_mortar_friction3d.py instead of 7)."""
    n = np.array([[1e-17, 1.0, 3e-17], [3e-17, 1.0, 1e-17], [0.0, 1.0, 0.0]])
    T = tangent_basis(n / np.linalg.norm(n, axis=1)[:, None])
    assert np.allclose(T[:, 0], [1.0, 0.0, 0.0], atol=1e-15)
    # a genuine difference still decides
    m = np.array([[1e-3, 1.0, 1e-6]])
    assert np.allclose(tangent_basis(m / np.linalg.norm(m))[0, 0], [0.0, 0.0, 1.0], atol=1e-5)
