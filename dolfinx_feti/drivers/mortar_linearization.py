"""The derivatives of the mortar rows of a deformed configuration, by central differences.

A mortar row of the configuration y = x + u is, in physical units,

    g_j(u) = n_j·(y_j − Σ_k w_jk y_k) >= 0,   its force  λ_j b_j,  b_j = n_j ⊗ (Σ_k w_jk e_k − e_j)

with w = M/D and the averaged slave normal n_j of y (:mod:`.current_mortar`). Newton with
D, M, n frozen at the iterate (the increment's rows B Δu <= g(u_k)) leaves out two
derivatives: that of the gap, G = −∂g/∂u (G ≠ B: the segment clipping, the projections and
the normals move with u), and that of the contact forces, H(λ) = ∂(Σ_j λ_j b_j(u))/∂u at
fixed physical multipliers λ (the turning normals and the moving weights). Both are taken here
by central differences of the row assembly (:func:`.constraints.mortar_rows.mortar_contact_rows`
on the deformed cells along the surfaces) over the displacement components of the surfaces'
nodes: 2 · (surface nodes) · gdim assemblies, each a few milliseconds in 2D.

A row is known by its slave node; a row that the perturbed configuration couples no longer
(the edge of the coupled set) differences to zero there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..constraints.rows import Rows


@dataclass(frozen=True)
class RowDerivatives:
    """The mortar rows of one configuration and their derivatives, on the surfaces' dofs.

    Dofs are flat (point, component) indices of the surfaces' points, ``points × bs``.

    Attributes:
        node: The slave point of every row (the rows of the configuration, in its order).
        spec: The condition of every row.
        gap: The physical gap g_j of every row.
        B: The frozen rows b_j (dense, rows × dofs), physical units.
        G: −∂g/∂u (dense, rows × dofs).
        H: ∂(Σ_j λ_j b_j)/∂u at the given λ (dense, dofs × dofs; zeros when λ is None).
        lam: The physical multiplier of every row, at which H is taken.
    """

    node: np.ndarray
    spec: np.ndarray
    gap: np.ndarray
    B: np.ndarray
    G: np.ndarray
    H: np.ndarray
    lam: np.ndarray


def _dense(rows: Rows, ndof: int, bs: int) -> np.ndarray:
    """The rows' physical coefficients b_j (coefficients over the scale), dense."""
    out = np.zeros((rows.size, ndof))
    np.add.at(out, (rows.e_row, rows.e_node * bs + rows.e_comp),
              rows.e_coef / rows.scale[rows.e_row])
    return out


def _keys(rows: Rows, npoints: int) -> np.ndarray:
    return rows.spec.astype(np.int64) * npoints + rows.node


def row_derivatives(build: Callable[[np.ndarray], Rows], U: np.ndarray, dofs: np.ndarray,
                    lam: np.ndarray | None = None, eps: float = 1e-6) -> RowDerivatives:
    """The rows of ``build(U)`` and their derivatives by central differences.

    Args:
        build: The rows (points of the surfaces as nodes, scaled) of a displacement of the
            surfaces' points, shape ``(points, bs)``.
        U: The displacement of the surfaces' points at which to differentiate.
        dofs: The flat (point, component) dofs to perturb (the others' columns stay zero).
        lam: The physical multiplier of every row of ``build(U)`` (for H), or None.
        eps: The perturbation (a length: small against the cells, large against round-off).
    """
    npoints, bs = U.shape
    ndof = npoints * bs
    base = build(U)
    key0 = _keys(base, npoints)
    order = np.argsort(key0)
    B = _dense(base, ndof, bs)
    gap = base.rhs / base.scale
    G = np.zeros_like(B)
    H = np.zeros((ndof, ndof))
    lam = np.zeros(base.size) if lam is None else np.asarray(lam, dtype=float)

    def at(d: int, h: float) -> tuple[np.ndarray, np.ndarray]:
        Up = U.copy()
        Up.flat[d] += h
        rows = build(Up)
        key = _keys(rows, npoints)
        pos = np.searchsorted(key0[order], key)
        found = (pos < key0.size) & (key0[order][np.minimum(pos, key0.size - 1)] == key)
        where = order[pos[found]]  # the base row of every perturbed row
        g = np.zeros(base.size)
        g[where] = rows.rhs[found] / rows.scale[found]
        lam_p = np.zeros(rows.size)
        lam_p[found] = lam[where]
        force = lam_p @ _dense(rows, ndof, bs)
        present = np.zeros(base.size, dtype=bool)
        present[where] = True
        return np.where(present, g, np.nan), force

    for d in np.asarray(dofs, dtype=np.int64):
        gp, fp = at(int(d), eps)
        gm, fm = at(int(d), -eps)
        dg = (gp - gm) / (2 * eps)
        G[:, d] = -np.where(np.isfinite(dg), dg, 0.0)
        H[:, d] = (fp - fm) / (2 * eps)
    return RowDerivatives(node=base.node, spec=base.spec, gap=gap, B=B, G=G, H=H, lam=lam)


__all__ = ["RowDerivatives", "row_derivatives"]
