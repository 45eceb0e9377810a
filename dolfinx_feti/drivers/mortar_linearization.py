"""The derivatives of the mortar rows of a deformed configuration, by central differences.

A mortar row of the configuration y = x + u is, in physical units,

    g_j(u) = n_j·(y_j − Σ_k w_jk y_k) >= 0,   its force  λ_j b_j,  b_j = n_j ⊗ (Σ_k w_jk e_k − e_j)

with w = M/D and the averaged slave normal n_j of y (:mod:`.current_mortar`). Newton with
D, M, n frozen at the iterate (the increment's rows B Δu <= g(u_k)) leaves out two
derivatives: that of the gap, G = −∂g/∂u (G ≠ B: the segment clipping, the projections and
the normals move with u), and that of the contact forces, H(λ) = ∂(Σ_j λ_j b_j(u))/∂u at
fixed physical multipliers λ (the turning normals and the moving weights).

:class:`RowsAt` takes their products with a direction v, (G v, H v), by central differences
of the row assembly (:func:`.constraints.mortar_rows.mortar_contact_rows` on the deformed
cells along the surfaces) along v itself: two assemblies a product, whatever the number of
surface nodes. Along v, not dof by dof: where a slave facet's end meets a master facet's end
(the flat blocks' interfaces, whose ends stay together as both surfaces stretch) the rows are
not differentiable, their one-sided derivatives differ by the order of the forces; a
difference of one dof alone crosses that kink and takes the mean of both sides, which no
motion has (a rigid translation then moved the forces by 2e-6 of themselves on the blocks
pressed 20 %, and broke their symmetry), while a direction that keeps the ends together
(every homogeneous one) stays on one side. The dense matrices (:func:`row_derivatives`, the
unit directions one by one) serve the tests.

A row is known by its slave node; a row that the perturbed configuration couples no longer
(the edge of the coupled set) differences to zero there, and a row that only the perturbed
configuration has carries no multiplier.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..constraints.rows import Rows

#: The perturbation along a direction (a length: small against the cells, large against
#: the round-off of the coordinates).
EPS = 1e-6


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
        dofs: The dofs differentiated (the only nonzero columns of G and H).
    """

    node: np.ndarray
    spec: np.ndarray
    gap: np.ndarray
    B: np.ndarray
    G: np.ndarray
    H: np.ndarray
    lam: np.ndarray
    dofs: np.ndarray


def _dense(rows: Rows, ndof: int, bs: int) -> np.ndarray:
    """The rows' physical coefficients b_j (coefficients over the scale), dense."""
    out = np.zeros((rows.size, ndof))
    np.add.at(out, (rows.e_row, rows.e_node * bs + rows.e_comp),
              rows.e_coef / rows.scale[rows.e_row])
    return out


def _keys(rows: Rows, npoints: int) -> np.ndarray:
    return rows.spec.astype(np.int64) * npoints + rows.node


class RowsAt:
    """The mortar rows of one configuration and the products of their derivatives.

    Args:
        build: The rows (points of the surfaces as nodes, scaled) of a displacement of the
            surfaces' points, shape ``(points, bs)``.
        U: The displacement of the surfaces' points at which to differentiate.
        lam: The physical multiplier of every row of ``build(U)`` (for H), or None (zeros).
        eps: The perturbation along a direction (a length).
        base: ``build(U)`` if already built.

    Attributes:
        base: The rows of ``build(U)``.
        gap: Their physical gaps.
        lam: Their physical multipliers.
    """

    def __init__(self, build: Callable[[np.ndarray], Rows], U: np.ndarray,
                 lam: np.ndarray | None = None, eps: float = EPS,
                 base: Rows | None = None) -> None:
        self._build, self.U, self.eps = build, U, eps
        self.npoints, self.bs = U.shape
        self.base = build(U) if base is None else base
        key = _keys(self.base, self.npoints)
        self._order = np.argsort(key)
        self._sorted = key[self._order]
        self.gap = self.base.rhs / self.base.scale
        self.lam = np.zeros(self.base.size) if lam is None else np.asarray(lam, dtype=float)

    @property
    def node(self) -> np.ndarray:
        """The slave point of every row."""
        return self.base.node

    @property
    def spec(self) -> np.ndarray:
        """The condition of every row."""
        return self.base.spec

    def _flat(self, rows: Rows) -> np.ndarray:
        return rows.e_node.astype(np.int64) * self.bs + rows.e_comp

    def frozen(self, v: np.ndarray) -> np.ndarray:
        """B v: the rows of the configuration, D, M, n held, times v (flat, per row)."""
        b = self.base
        out = np.zeros(b.size)
        np.add.at(out, b.e_row, b.e_coef / b.scale[b.e_row] * v[self._flat(b)])
        return out

    def _at(self, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The gaps of the base rows (NaN where uncoupled) and the forces, at V."""
        rows = self._build(V)
        key = _keys(rows, self.npoints)
        pos = np.minimum(np.searchsorted(self._sorted, key), max(self._sorted.size - 1, 0))
        found = (self._sorted[pos] == key) if self._sorted.size else np.zeros(key.size, bool)
        where = self._order[pos[found]]  # the base row of every perturbed row
        g = np.full(self.base.size, np.nan)
        g[where] = rows.rhs[found] / rows.scale[found]
        lam = np.zeros(rows.size)
        lam[found] = self.lam[where]
        force = np.zeros(self.U.size)
        np.add.at(force, self._flat(rows),
                  lam[rows.e_row] * rows.e_coef / rows.scale[rows.e_row])
        return g, force

    def derivative(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(G v, H v) by a central difference along v (two assemblies).

        Args:
            v: A direction of the surfaces' dofs (flat, ``points × bs``).

        Returns:
            G v per base row and H v per dof.
        """
        size = float(np.abs(v).max(initial=0.0))
        if size == 0.0:
            return np.zeros(self.base.size), np.zeros(self.U.size)
        h = self.eps / size
        step = (h * v).reshape(self.U.shape)
        gp, fp = self._at(self.U + step)
        gm, fm = self._at(self.U - step)
        dg = (gp - gm) / (2 * h)
        return -np.where(np.isfinite(dg), dg, 0.0), (fp - fm) / (2 * h)

    def dense(self, dofs: np.ndarray) -> RowDerivatives:
        """G and H as matrices: the derivatives along every dof of ``dofs`` (2 per dof)."""
        ndof = self.U.size
        dofs = np.asarray(dofs, dtype=np.int64)
        G = np.zeros((self.base.size, ndof))
        H = np.zeros((ndof, ndof))
        e = np.zeros(ndof)
        for d in dofs:
            e[d] = 1.0
            G[:, d], H[:, d] = self.derivative(e)
            e[d] = 0.0
        return RowDerivatives(node=self.node, spec=self.spec, gap=self.gap,
                              B=_dense(self.base, ndof, self.bs), G=G, H=H, lam=self.lam,
                              dofs=dofs)


def row_derivatives(build: Callable[[np.ndarray], Rows], U: np.ndarray, dofs: np.ndarray,
                    lam: np.ndarray | None = None, eps: float = EPS) -> RowDerivatives:
    """The rows of ``build(U)`` and their derivatives as matrices (:meth:`RowsAt.dense`).

    Args:
        build: The rows of a displacement of the surfaces' points (:class:`RowsAt`).
        U: The displacement of the surfaces' points at which to differentiate.
        dofs: The flat (point, component) dofs to perturb (the others' columns stay zero).
        lam: The physical multiplier of every row of ``build(U)`` (for H), or None.
        eps: The perturbation (a length: small against the cells, large against round-off).
    """
    return RowsAt(build, U, lam, eps).dense(dofs)


__all__ = ["EPS", "RowDerivatives", "RowsAt", "row_derivatives"]
