"""Closed-form integrals of the 2D Laplace and Kelvin kernels over straight segments.

A segment starts at ``p``, has unit tangent τ, outward normal n = (τ₂, −τ₁) (the segments of a
counter-clockwise polygon) and length L. For a point x, with a = (x − p)·τ and d = (x − p)·n,

    y(t) − x = u τ − d n,   u = t − a ∈ [u₁, u₂] = [−a, L − a],   R² = u² + d²,

and every integral below is over u in closed form (no quadrature: exact for a point as close to
the segment as one likes). θ = ∫ d / R² du is the angle the segment subtends at x; on the
segment's own line (d = 0) every term with a factor d is zero, θ included, which is the value a
boundary point x of the segment's line gives a flat double layer.

The moments are vectorized over matching arrays of points and segments.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Local:
    """A batch of points in the frames of a batch of segments (arrays of one shape)."""

    u1: np.ndarray
    u2: np.ndarray
    d: np.ndarray
    a: np.ndarray
    theta: np.ndarray
    R1: np.ndarray
    R2: np.ndarray

    @classmethod
    def of(cls, x: np.ndarray, p: np.ndarray, tau: np.ndarray, L: np.ndarray) -> Local:
        """Points ``x`` (..., 2) against segments ``p``, ``tau`` (..., 2), ``L`` (...)."""
        dx = x - p
        a = dx[..., 0] * tau[..., 0] + dx[..., 1] * tau[..., 1]
        d = dx[..., 0] * tau[..., 1] - dx[..., 1] * tau[..., 0]
        # a point on the segment's line has d at round-off of its coordinates: zero it, so the
        # double layer of a flat element vanishes there exactly
        d = np.where(np.abs(d) <= 1e-13 * (np.abs(a) + L), 0.0, d)
        u1, u2 = -a, L - a
        theta = np.where(d == 0.0, 0.0, np.arctan2(d * (u2 - u1), d * d + u1 * u2))
        return cls(u1, u2, d, a, theta, u1 * u1 + d * d, u2 * u2 + d * d)


def _xlogx(u: np.ndarray, R2: np.ndarray) -> np.ndarray:
    """u ln R² with the limit 0 at R = 0."""
    return np.where(R2 > 0, u * np.log(np.where(R2 > 0, R2, 1.0)), 0.0)


def _diff_log(loc: Local) -> np.ndarray:
    """ln R₂² − ln R₁² (finite where used: multiplied by d, or R > 0 at both ends)."""
    ok = (loc.R1 > 0) & (loc.R2 > 0)
    return np.where(ok, np.log(np.where(ok, loc.R2, 1.0) / np.where(ok, loc.R1, 1.0)), 0.0)


def log_moments(loc: Local) -> tuple[np.ndarray, np.ndarray]:
    """∫ ln R du and ∫ u ln R du."""
    m0 = 0.5 * (_xlogx(loc.u2, loc.R2) - _xlogx(loc.u1, loc.R1)) - (loc.u2 - loc.u1) \
        + loc.d * loc.theta
    m1 = 0.25 * (_xlogx(loc.R2, loc.R2) - _xlogx(loc.R1, loc.R1) - loc.u2 ** 2 + loc.u1 ** 2)
    return m0, m1


def dyad_moments(loc: Local) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """∫ r̂ r̂ᵀ du in the frame (τ, n): the ττ, τn (= nτ) and nn parts, r̂ = (y − x)/R."""
    tt = (loc.u2 - loc.u1) - loc.d * loc.theta
    tn = -0.5 * loc.d * _diff_log(loc)
    nn = loc.d * loc.theta
    return tt, tn, nn


def double_layer_moments(loc: Local) -> tuple[np.ndarray, np.ndarray]:
    """∫ d / R² du and ∫ u d / R² du (−(r̂·n)/R, the Laplace double layer up to 1/2π)."""
    return loc.theta, 0.5 * loc.d * _diff_log(loc)


def dyad_double_layer_moments(loc: Local) -> tuple[tuple, tuple]:
    """∫ d r̂r̂ᵀ / R² u^k du for k = 0, 1, each as its ττ, τn and nn parts."""
    d, u1, u2, R1, R2 = loc.d, loc.u1, loc.u2, loc.R1, loc.R2
    safe1, safe2 = np.where(R1 > 0, R1, 1.0), np.where(R2 > 0, R2, 1.0)
    on = d != 0.0

    def diff(f1, f2):
        return np.where(on, f2 / safe2 - f1 / safe1, 0.0)

    half = 0.5 * loc.theta
    d2, d3 = d * d, d * d * d
    # antiderivatives of u^p / R⁴ times powers of d (see the module docstring)
    dJ2 = -0.5 * diff(d * u1, d * u2) + half
    d2J1 = -0.5 * diff(d2 + 0 * u1, d2 + 0 * u2)
    d3J0 = 0.5 * diff(d * u1, d * u2) + half
    dJ3 = 0.5 * diff(d3 + 0 * u1, d3 + 0 * u2) + 0.5 * d * _diff_log(loc)
    d2J2 = -0.5 * diff(d2 * u1, d2 * u2) + d * half
    d3J1 = -0.5 * diff(d3 + 0 * u1, d3 + 0 * u2)
    return (dJ2, -d2J1, d3J0), (dJ3, -d2J2, d3J1)


__all__ = ["Local", "double_layer_moments", "dyad_double_layer_moments", "dyad_moments",
           "log_moments"]
