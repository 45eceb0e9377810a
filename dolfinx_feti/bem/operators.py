"""Galerkin boundary integral operators of the 2D Laplace and Lamé (plane strain) equations.

Dirichlet traces are continuous piecewise linear (P1, the subdomain's boundary nodes), Neumann
traces piecewise constant (P0, its boundary elements). With G the fundamental solution and the
interior problem's conventions (n outward, Steinbach 2008),

    V t = ∫ G t,   K u = ∫ ∂G/∂n_y u,   (½I + K) u = V t,   t = S u,

and the hypersingular operator by integration by parts (the tangential derivative ∂_s):

- Laplace, G = −ln r / 2π: ⟨D u, v⟩ = ⟨V ∂_s u, ∂_s v⟩;
- Lamé, Kelvin's solution U = [−(3 − 4ν) ln r I + r̂ r̂ᵀ] / (8πμ(1 − ν)):
  ⟨D u, v⟩ = ∫∫ ∂_s v(x)ᵀ μ/(2π(1 − ν)) [−ln r I + r̂ r̂ᵀ] ∂_s u(y) (Nédélec 1982), and the
  double layer's Cauchy part (1 − 2ν)/(4π(1 − ν)) J u/R², J = τnᵀ − nτᵀ, integrated by parts
  onto the trial function's derivative against ln r (the polygon is closed).

All integrals come from :func:`.galerkin.pair_integrals` (one pass over the element pairs of
all subdomains); the matrices are dense per subdomain, degrees of freedom node-major (P1) or
element-major (P0) with the components inside.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .galerkin import BoundaryMesh, pair_integrals

#: J = τnᵀ − nτᵀ for n = (τ₂, −τ₁): the same for every element.
J_ROT = np.array([[0.0, -1.0], [1.0, 0.0]])


@dataclass
class Operators:
    """The Galerkin matrices of one subdomain.

    Attributes:
        V: Single layer, P0 × P0.
        K: Double layer, P0 (test) × P1 (trial).
        D: Hypersingular, P1 × P1.
        M: Mass, P0 × P1.
    """

    V: np.ndarray
    K: np.ndarray
    D: np.ndarray
    M: np.ndarray


def incidence(bm: BoundaryMesh, s: int) -> tuple[np.ndarray, np.ndarray]:
    """(element × node) 0/1 matrices of the start and end node of the elements of ``s``."""
    e0, e1 = bm.elem_off[s], bm.elem_off[s + 1]
    n0, n1 = bm.node_off[s], bm.node_off[s + 1]
    ne, nn = e1 - e0, n1 - n0
    inc = np.zeros((2, ne, nn))
    rows = np.arange(ne)
    inc[0, rows, bm.elem[e0:e1, 0] - n0] = 1.0
    inc[1, rows, bm.elem[e0:e1, 1] - n0] = 1.0
    return inc[0], inc[1]


def to_nodes(T: np.ndarray, bm: BoundaryMesh, s: int) -> np.ndarray:
    """(m, elements, 2 ends, ...) integrals against the ends' hat functions → (m, nodes, ...).

    On closed polygons every node starts exactly one element and ends one: two permutations.
    """
    e0, e1 = bm.elem_off[s], bm.elem_off[s + 1]
    ends = bm.elem[e0:e1] - bm.node_off[s]
    out = np.empty((T.shape[0], bm.node_off[s + 1] - bm.node_off[s], *T.shape[3:]))
    out[:, ends[:, 0]] = T[:, :, 0]
    out[:, ends[:, 1]] += T[:, :, 1]
    return out


def _blocks(bm: BoundaryMesh, fields):
    """Per subdomain: its slice of elements and its pair fields as (ne, ne, ...) arrays."""
    _, _, f = pair_integrals(bm, fields)
    ne = np.diff(bm.elem_off)
    off = np.concatenate([[0], np.cumsum(ne * ne)])
    for s in range(bm.count):  # dense per-subdomain algebra; the pair work is done above
        n = int(ne[s])
        yield s, {k: v[off[s]:off[s + 1]].reshape(n, n, *v.shape[1:]) for k, v in f.items()}


def mass_and_derivative(bm: BoundaryMesh, s: int) -> tuple[np.ndarray, np.ndarray]:
    """P0 × P1 mass and the P1 → P0 tangential derivative of subdomain ``s``."""
    inc0, inc1 = incidence(bm, s)
    L = bm.length[bm.elem_off[s]:bm.elem_off[s + 1]]
    return 0.5 * L[:, None] * (inc0 + inc1), inc1 / L[:, None] - inc0 / L[:, None]


def _blocked(T: np.ndarray) -> np.ndarray:
    """(n, m, 2, 2) → (2n, 2m), components inside."""
    n, m = T.shape[:2]
    return T.transpose(0, 2, 1, 3).reshape(2 * n, 2 * m)


def layers(f: dict, bm: BoundaryMesh, s: int, C: np.ndarray, mu: float | None = None,
           nu: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The single layer (P0 trial) and double layer (P1 trial) from the integrals ``f``.

    ``f`` holds the fields of :func:`.galerkin.pair_integrals` (Galerkin: rows are P0 test
    functions) or of :func:`.galerkin.point_fields` reshaped to (points, elements, ...)
    (potentials at points); ``C`` is the subdomain's P1 → P0 derivative. Laplace without
    ``mu``, Lamé (plane strain) with the shear modulus and Poisson's ratio.
    """
    if mu is None:
        return -f["ln"] / (2 * np.pi), to_nodes(f["dl"], bm, s) / (2 * np.pi)
    eye = np.eye(2)
    lnI = f["ln"][..., None, None] * eye
    single = _blocked((-(3 - 4 * nu) * lnI + f["rr"]) / (8 * np.pi * mu * (1 - nu)))
    # the double layer without its Cauchy part, (rows, elements, end k, 2, 2) → P1 nodes ...
    T = ((1 - 2 * nu) * f["dl"][..., None, None] * eye + 2 * f["edl"]) / (4 * np.pi * (1 - nu))
    double = _blocked(to_nodes(T, bm, s))
    # ... and the Cauchy part, integrated by parts onto the trial function's derivative
    double -= (1 - 2 * nu) / (4 * np.pi * (1 - nu)) * np.kron(f["ln"] @ C, J_ROT)
    return single, double


def laplace_operators(bm: BoundaryMesh) -> list[Operators]:
    """V, K, D, M of the Laplace operator on every subdomain of ``bm`` (conductivity 1)."""
    out = []
    for s, f in _blocks(bm, ("ln", "dl")):
        M, C = mass_and_derivative(bm, s)
        V, K = layers(f, bm, s, C)
        out.append(Operators(V=_sym(V), K=K, D=_sym(C.T @ V @ C), M=M))
    return out


def lame_operators(bm: BoundaryMesh, mu: np.ndarray, nu: np.ndarray) -> list[Operators]:
    """V, K, D, M of plane-strain elasticity on every subdomain (shear modulus, Poisson ratio)."""
    out = []
    eye = np.eye(2)
    for s, f in _blocks(bm, ("ln", "rr", "dl", "edl")):
        m, v = float(mu[s]), float(nu[s])
        M, C = mass_and_derivative(bm, s)
        V, K = layers(f, bm, s, C, m, v)
        Q = _blocked((-f["ln"][..., None, None] * eye + f["rr"]) * (m / (2 * np.pi * (1 - v))))
        Ck = np.kron(C, eye)
        out.append(Operators(V=_sym(V), K=K, D=_sym(Ck.T @ Q @ Ck), M=np.kron(M, eye)))
    return out


def _sym(A: np.ndarray) -> np.ndarray:
    """The symmetric part (the matrices are symmetric up to the outer quadrature)."""
    return 0.5 * (A + A.T)


__all__ = ["Operators", "incidence", "lame_operators", "laplace_operators", "layers",
           "mass_and_derivative",
           "to_nodes"]
