"""The extrapolation of SMALBE's slow outer loop (qp/aitken.py) and its choice by 'auto'."""

from __future__ import annotations

import numpy as np
import pytest

from dolfinx_feti.qp.aitken import CAP, Aitken


def test_geometric_residuals_extrapolated_to_their_sum():
    """Residuals r, q r (q = 0.8, one direction): the step becomes the series' sum 1/(1-q)."""
    a, r = Aitken(), np.array([3.0, -1.0, 2.0])
    assert np.array_equal(a.step(r, 2.0 * r), 2.0 * r)  # no pair yet
    step = a.step(0.8 * r, 1.6 * r)
    assert np.allclose(step, 1.6 * r / (1.0 - 0.8))
    assert a.count == 1
    # the pair is used up: the next residual alone is not extrapolated
    assert np.array_equal(a.step(0.6 * r, 1.2 * r), 1.2 * r)


def test_extrapolation_capped():
    a, r = Aitken(), np.array([1.0, 1.0])
    a.step(r, r)
    assert np.allclose(a.step(0.999 * r, 0.999 * r), CAP * 0.999 * r)


@pytest.mark.parametrize("second", [np.array([1.0, 0.5]) * 0.9,   # turned (cosine 0.95)
                                    np.array([1.0, 0.0]) * 1.1,   # growing
                                    np.array([1.0, 0.0]) * 0.3,   # fast: left to the plain step
                                    np.array([-1.0, 0.0]) * 0.9])  # overshot
def test_plain_step_unless_slow_and_aligned(second):
    a = Aitken()
    a.step(np.array([1.0, 0.0]), np.array([1.0, 0.0]))
    assert np.array_equal(a.step(second, 2.0 * second), 2.0 * second)
    assert a.count == 0
