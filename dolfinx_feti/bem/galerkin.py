"""Galerkin double integrals over all element pairs of a batch of boundary meshes, vectorized.

The inner integral (over the trial element) is in closed form (:mod:`.segments`), the outer one
(over the test element) by Gauss rules chosen per pair class:

- far pairs (midpoints more than :data:`NEAR` element lengths apart): :data:`FAR_POINTS`
  Gauss points, :data:`DISTANT_POINTS` beyond :data:`DISTANT` lengths — the outer integrand is
  smooth there;
- identical and adjacent pairs: the outer integrand is as singular as s ln s at the element's
  ends (identical) or at the shared vertex (adjacent), so a composite rule graded geometrically
  towards both ends or that one;
- near pairs: a composite uniform rule.

No Python loop runs over element pairs: the pairs of a class are processed in chunks of arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .segments import (
    Local,
    double_layer_moments,
    dyad_double_layer_moments,
    dyad_moments,
    log_moments,
)

#: A pair is far when its midpoints are more than NEAR times the longer element apart.
NEAR = 4.0
#: Gauss points of the outer integral of a far pair, and of one more than DISTANT lengths apart.
FAR_POINTS, DISTANT, DISTANT_POINTS = 8, 12.0, 4
#: Composite rule of near pairs: panels × points.
NEAR_PANELS, NEAR_POINTS = 4, 8
#: Graded rule of identical and adjacent pairs: ratio, levels, points per panel.
GRADING, LEVELS, GRADED_POINTS = 0.25, 14, 10
#: Points × pairs per chunk of arrays (memory bound).
CHUNK = 400_000


def gauss(q: int) -> tuple[np.ndarray, np.ndarray]:
    """The q-point Gauss–Legendre rule on [0, 1]."""
    s, w = np.polynomial.legendre.leggauss(q)
    return 0.5 * (s + 1.0), 0.5 * w


def composite(breaks: np.ndarray, q: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss rules of q points on the panels between ``breaks`` (ascending, in [0, 1])."""
    s, w = gauss(q)
    lo, hi = breaks[:-1, None], breaks[1:, None]
    return (lo + (hi - lo) * s).ravel(), ((hi - lo) * w).ravel()


def graded_rule(both: bool) -> tuple[np.ndarray, np.ndarray]:
    """A composite rule on [0, 1] graded geometrically towards 0 (and 1 if ``both``)."""
    steps = GRADING ** np.arange(LEVELS, -1, -1, dtype=float)
    if not both:
        return composite(np.r_[0.0, steps], GRADED_POINTS)
    half = 0.5 * steps
    return composite(np.r_[0.0, half, 1.0 - half[::-1][1:], 1.0], GRADED_POINTS)


def _mirrored(rule: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    return 1.0 - rule[0], rule[1]


RULES = {"distant": gauss(DISTANT_POINTS), "far": gauss(FAR_POINTS),
         "near": composite(np.linspace(0.0, 1.0, NEAR_PANELS + 1), NEAR_POINTS),
         "identical": graded_rule(True), "at_start": graded_rule(False),
         "at_end": _mirrored(graded_rule(False))}


@dataclass
class BoundaryMesh:
    """Closed boundary polygons of a batch of subdomains (P1 nodes, straight elements).

    Attributes:
        x: Node coordinates (n, 2), the nodes of subdomain s at ``node_off[s]:node_off[s+1]``.
        elem: Elements (m, 2) as batch node indices, oriented so the subdomain lies to the
            left (counter-clockwise outer boundary); those of s at ``elem_off[s]:elem_off[s+1]``.
        node_off: Node offsets per subdomain.
        elem_off: Element offsets per subdomain.
    """

    x: np.ndarray
    elem: np.ndarray
    node_off: np.ndarray
    elem_off: np.ndarray

    def __post_init__(self) -> None:
        p, q = self.x[self.elem[:, 0]], self.x[self.elem[:, 1]]
        self.p = p
        self.length = np.linalg.norm(q - p, axis=1)
        self.tau = (q - p) / self.length[:, None]
        self.normal = np.stack([self.tau[:, 1], -self.tau[:, 0]], axis=1)
        self.mid = 0.5 * (p + q)

    @property
    def count(self) -> int:
        """Number of subdomains."""
        return self.elem_off.size - 1

    def sizes(self) -> tuple[np.ndarray, np.ndarray]:
        """Elements and nodes per subdomain."""
        return np.diff(self.elem_off), np.diff(self.node_off)

    def elem_sub(self) -> np.ndarray:
        """The subdomain of every element."""
        return np.repeat(np.arange(self.count), np.diff(self.elem_off))

    def derivative(self) -> np.ndarray:
        """Per element, dφ/ds of its start and end node's hat function: (−1/L, 1/L)."""
        return np.stack([-1.0 / self.length, 1.0 / self.length], axis=1)


def element_pairs(bm: BoundaryMesh) -> tuple[np.ndarray, np.ndarray]:
    """All (test, trial) element pairs within each subdomain, block by block, row-major."""
    n = np.diff(bm.elem_off)
    total = n * n
    sub = np.repeat(np.arange(n.size), total)
    k = np.arange(int(total.sum())) - np.repeat(np.cumsum(total) - total, total)
    first = bm.elem_off[:-1][sub]
    return first + k // n[sub], first + k % n[sub]


def pair_classes(bm: BoundaryMesh, I: np.ndarray, J: np.ndarray) -> dict[str, np.ndarray]:
    """Masks of the pairs per quadrature class (the keys of :data:`RULES`).

    identical; adjacent at the start or at the end of the test element; near; far; distant.
    """
    ei, ej = bm.elem[I], bm.elem[J]
    same = I == J
    start = (ei[:, :1] == ej).any(axis=1) & ~same
    end = (ei[:, 1:] == ej).any(axis=1) & ~same & ~start
    touch = same | start | end
    dist = np.linalg.norm(bm.mid[I] - bm.mid[J], axis=1) / np.maximum(bm.length[I],
                                                                        bm.length[J])
    near, distant = dist <= NEAR, dist > DISTANT
    return {"identical": same, "at_start": start, "at_end": end, "near": near & ~touch,
            "far": ~near & ~distant & ~touch, "distant": distant & ~touch}


def frame_tensor(tt, tn, nn, tau: np.ndarray, nrm: np.ndarray) -> np.ndarray:
    """tt ττᵀ + tn (τnᵀ + nτᵀ) + nn nnᵀ as (..., 2, 2)."""
    def outer(a, b):
        return a[..., :, None] * b[..., None, :]
    return (tt[..., None, None] * outer(tau, tau) + tn[..., None, None] *
            (outer(tau, nrm) + outer(nrm, tau)) + nn[..., None, None] * outer(nrm, nrm))


def _p1(m0: np.ndarray, m1: np.ndarray, a: np.ndarray, L: np.ndarray) -> np.ndarray:
    """u-moments → the integrals against the hat functions of the start and end node."""
    t1 = m1 + a * m0  # ∫ k t dt, t = u + a
    return np.stack([m0 - t1 / L, t1 / L], axis=-1)


def _pair_fields(bm: BoundaryMesh, I, J, s, w, fields) -> dict[str, np.ndarray]:
    """The requested outer-integrated fields of pairs (I, J) with the rule (s, w)."""
    x = bm.p[I][:, None, :] + (s[None, :] * bm.length[I][:, None])[..., None] * \
        bm.tau[I][:, None, :]
    tau, nrm = bm.tau[J][:, None, :], bm.normal[J][:, None, :]
    L = bm.length[J][:, None]
    loc = Local.of(x, bm.p[J][:, None, :], tau, L)
    wq = w[None, :] * bm.length[I][:, None]
    out = {}
    if "ln" in fields:
        out["ln"] = (log_moments(loc)[0] * wq).sum(axis=1)
    if "rr" in fields:
        tt, tn, nn = (np.sum(v * wq, axis=1) for v in dyad_moments(loc))
        out["rr"] = frame_tensor(tt, tn, nn, tau[:, 0], nrm[:, 0])
    if "dl" in fields:
        m0, m1 = double_layer_moments(loc)
        out["dl"] = (_p1(m0, m1, loc.a, L) * wq[..., None]).sum(axis=1)
    if "edl" in fields:
        k0, k1 = dyad_double_layer_moments(loc)
        parts = [(_p1(c0, c1, loc.a, L) * wq[..., None]).sum(axis=1)
                 for c0, c1 in zip(k0, k1, strict=True)]  # 3 × (P, 2)
        out["edl"] = frame_tensor(*[np.moveaxis(p, -1, 0) for p in parts],
                                  np.broadcast_to(tau[:, 0], (2, *tau[:, 0].shape)),
                                  np.broadcast_to(nrm[:, 0], (2, *nrm[:, 0].shape)))
        out["edl"] = np.moveaxis(out["edl"], 0, 1)  # (P, 2 nodes, 2, 2)
    return out


def pair_integrals(bm: BoundaryMesh, fields: tuple[str, ...]
                   ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Outer-integrated fields of every element pair of every subdomain.

    Fields: ``"ln"`` ∫∫ ln|x − y| (P0 × P0), ``"rr"`` ∫∫ r̂r̂ᵀ (P0 × P0, 2 × 2), ``"dl"``
    ∫∫ d/R² φ_k (P0 × the trial element's two hat functions), ``"edl"`` ∫∫ d r̂r̂ᵀ/R² φ_k
    (the same, 2 × 2).

    Returns:
        The test and trial element of each pair and the fields (first axis: pairs).
    """
    I, J = element_pairs(bm)
    classes = pair_classes(bm, I, J)
    shapes = {"ln": (), "rr": (2, 2), "dl": (2,), "edl": (2, 2, 2)}
    out = {f: np.zeros((I.size, *shapes[f])) for f in fields}
    for name, mask in classes.items():
        s, w = RULES[name]
        idx = np.flatnonzero(mask)
        step = max(1, CHUNK // s.size)
        for lo in range(0, idx.size, step):  # chunks of many pairs each (memory bound)
            sel = idx[lo:lo + step]
            part = _pair_fields(bm, I[sel], J[sel], s, w, fields)
            for f in fields:
                out[f][sel] = part[f]
    return I, J, out


def point_fields(bm: BoundaryMesh, X: np.ndarray, sub: np.ndarray, fields: tuple[str, ...]
                 ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """The inner integrals at points ``X`` (k, 2) of subdomains ``sub`` over their elements.

    For potentials inside a subdomain (the representation formula). Returns the point and
    element of each (point, element) pair of the same subdomain and the fields as
    :func:`pair_integrals` without the outer integral.
    """
    n = np.diff(bm.elem_off)[sub]
    P = np.repeat(np.arange(X.shape[0]), n)
    E = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n) + \
        np.repeat(bm.elem_off[:-1][sub], n)
    out: dict[str, list] = {f: [] for f in fields}
    step = CHUNK
    for lo in range(0, P.size, step):
        p_, e_ = P[lo:lo + step], E[lo:lo + step]
        tau, nrm, L = bm.tau[e_], bm.normal[e_], bm.length[e_]
        loc = Local.of(X[p_], bm.p[e_], tau, L)
        if "ln" in fields:
            out["ln"].append(log_moments(loc)[0])
        if "rr" in fields:
            out["rr"].append(frame_tensor(*dyad_moments(loc), tau, nrm))
        if "dl" in fields:
            out["dl"].append(_p1(*double_layer_moments(loc), loc.a, L))
        if "edl" in fields:
            k0, k1 = dyad_double_layer_moments(loc)
            parts = [_p1(c0, c1, loc.a, L) for c0, c1 in zip(k0, k1, strict=True)]
            T = frame_tensor(*[np.moveaxis(p, -1, 0) for p in parts],
                             np.broadcast_to(tau, (2, *tau.shape)),
                             np.broadcast_to(nrm, (2, *nrm.shape)))
            out["edl"].append(np.moveaxis(T, 0, 1))
    return P, E, {f: np.concatenate(v) for f, v in out.items()}


__all__ = ["BoundaryMesh", "element_pairs", "pair_classes", "pair_integrals", "point_fields"]
