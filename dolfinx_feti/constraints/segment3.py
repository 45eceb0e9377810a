"""The 3-node (quadratic) segment: shape functions of its points (a, b, e) on s ∈ [0, 1]."""

from __future__ import annotations

import numpy as np

#: ∫ N_k ds of the points (a, b, e): all positive (so a dual basis exists as it is).
WEIGHTS = np.array([1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0])


def shape(s: np.ndarray) -> np.ndarray:
    """N_a = (1 − s)(1 − 2s), N_b = s(2s − 1), N_e = 4s(1 − s) at s, shape s.shape + (3,)."""
    return np.stack([(1.0 - s) * (1.0 - 2.0 * s), s * (2.0 * s - 1.0), 4.0 * s * (1.0 - s)],
                    axis=-1)


def dshape(s: np.ndarray) -> np.ndarray:
    """dN/ds at s, shape s.shape + (3,)."""
    return np.stack([4.0 * s - 3.0, 4.0 * s - 1.0, 4.0 - 8.0 * s], axis=-1)
