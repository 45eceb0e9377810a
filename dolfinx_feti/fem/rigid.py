"""Rigid body modes (the kernel of a floating subdomain's stiffness matrix) from coordinates."""

from __future__ import annotations

import numpy as np


def rigid_motions(x: np.ndarray, value_size: int, centre: np.ndarray | None = None,
                  scale: float = 1.0) -> np.ndarray:
    """The rigid motions at nodes ``x`` (n, gdim), dofs node-major, not orthonormalized.

    Scalar problems: the constant. 2D: two translations and the rotation about ``centre``.
    3D: three translations and three rotations. Rotations are divided by ``scale`` (a length
    of the body) so that all columns have comparable size.

    Returns:
        An array of shape (n * value_size, k), k = 1, 3 or 6.
    """
    n, gdim = x.shape
    if value_size == 1:
        return np.ones((n, 1))
    xc = (x - (x.mean(axis=0) if centre is None else centre)) / scale
    if gdim == 2:
        R = np.zeros((n, 2, 3))
        R[:, 0, 0] = 1.0
        R[:, 1, 1] = 1.0
        R[:, 0, 2] = -xc[:, 1]
        R[:, 1, 2] = xc[:, 0]
    else:
        R = np.zeros((n, 3, 6))
        R[:, 0, 0] = R[:, 1, 1] = R[:, 2, 2] = 1.0
        R[:, 1, 3], R[:, 2, 3] = -xc[:, 2], xc[:, 1]
        R[:, 0, 4], R[:, 2, 4] = xc[:, 2], -xc[:, 0]
        R[:, 0, 5], R[:, 1, 5] = -xc[:, 1], xc[:, 0]
    return R.reshape(n * gdim, R.shape[2])


def rigid_modes(x: np.ndarray, value_size: int) -> np.ndarray:
    """Orthonormal basis of the rigid motions at nodes ``x`` (n, gdim), dofs ordered node-major.

    Scalar problems: the constant. 2D: two translations and the rotation. 3D: three
    translations and three rotations. Coordinates are centred first so the rotations are
    nearly orthogonal to the translations before the QR step.

    Returns:
        R with shape (n * value_size, k) and orthonormal columns.
    """
    if value_size == 1:
        return np.full((x.shape[0], 1), 1.0 / np.sqrt(x.shape[0]))
    q, _ = np.linalg.qr(rigid_motions(x, value_size))
    return q
