"""Friction on mortar pairs under Newton: the slip of the load step, relative to the master.

A slave node j of a :class:`~dolfinx_feti.Mortar` pair with friction has, beside its normal
row, gdim − 1 tangential rows built from the normal row as for a small-deformation mortar
pair (:func:`~dolfinx_feti.constraints.friction.with_tangential_rows`):

    T_j(u) v = s_j t_j·(v_j − Σ_k w_jk v_k),      t_j ⊥ n_j (2D (n_jy, −n_jx); 3D the basis
                                                  of ``tangent_basis``),

with w_jk = M_jk / D_j, the averaged slave normal n_j and the scale s_j of the configuration
x + u the rows are searched on (:mod:`.current_mortar`: every Newton iterate's). Σ_k w_jk y_k
is the point of the master surface the mortar integrals pair the slave node with, the master
material under it. The **slip of the load step** is the tangential motion of the slave node
relative to the master material it is paired with now, since the end of the last converged
step u_0:

    ς_j(u) = T_j(u)(u − u_0)/s_j = t_j·((y_j − y_j⁰) − Σ_k w_jk(u)(y_k − y_k⁰)),

y = x + u, y⁰ = x + u_0: the weighted relative tangential displacement increment of Puso &
Laursen (2004) and Gitterle, Popp, Gee & Wall (2010), with the weights and the tangent of the
current configuration. A slave node that sticks (ς_j = 0) moves with the master material
under it; the weights follow the slave point over the master surface, so a sliding node is
paired with the master material it is over at the end of the step, and the slip is measured
against that. Under a rigid rotation θ of the pair in a step ς_j = t_j·(R − I)P_j⁰, P_j⁰ =
y_j⁰ − Σ_k w_jk y_k⁰ the node's offset from its weighted master point (its gap along n, zero
in contact, and a tangential part of the mortar discretization): a spurious slip of order
θ² × that offset. (The offset itself is no slip measure: the re-searched weights keep it
near zero while the node slides.)

The increment's tangential row, with the rows of the iterate u_k frozen (the linearization of
the normal rows: the derivatives of D, M and t are not in the tangent), is

    T_j(u_k) Δu − c_j,    c_j = T_j(u_k)(u_0 − u_k),

so B_t Δu − c = s_j ς_j(u_k + Δu) with the rows of u_k, and the friction law (Tresca's bound,
or Coulomb's fixed point over Tresca solves that every QP solve runs) acts on the slip of the
step as on a small-deformation load path. No history is kept per tangent: the slip vector of
the step is measured anew in each iterate's tangents, so in 3D the basis (two tangents, disc
bounds) may change from one iterate to the next.
"""

from __future__ import annotations

import numpy as np

from ..constraints.friction import with_tangential_rows
from ..constraints.rows import Kind, Rows
from ..problem.contact_problem import ContactProblem


class MortarSlip:
    """The mortar pairs with friction of one Newton set-up and the step's start (rank 0).

    Args:
        problem: The problem (its contact conditions).
        specs: The indices of its mortar conditions.
        fixed: The Dirichlet mask of the layer's points (symmetry planes), or None.
    """

    def __init__(self, problem: ContactProblem, specs: np.ndarray, fixed: np.ndarray | None
                 ) -> None:
        self.with_friction = {int(i) for i in specs
                              if getattr(problem.contact[int(i)], "friction", None) is not None}
        self._fixed = fixed
        self._u0: np.ndarray | None = None  # the layer's displacement at the step's start

    def rows_of(self, rows: Rows, spec: int) -> Rows:
        """The normal rows of condition ``spec`` with their tangential rows, if it has friction."""
        return with_tangential_rows(rows, self._fixed) if spec in self.with_friction else rows

    def begin(self, U: np.ndarray) -> None:
        """The step starts from the layer's displacement ``U`` (the last converged one)."""
        self._u0 = U.copy()

    def rhs(self, rows: Rows, U: np.ndarray) -> np.ndarray:
        """The right-hand sides T_j(u)(u_0 − u) of the tangential rows (others unchanged).

        Args:
            rows: The rows of the layer's configuration x + U (its points as nodes).
            U: The layer's displacement.
        """
        rhs = rows.rhs.copy()
        t = rows.kind == Kind.TANGENT
        d = (np.zeros_like(U) if self._u0 is None else self._u0) - U
        val = np.bincount(rows.e_row, weights=rows.e_coef * d[rows.e_node, rows.e_comp],
                          minlength=rows.size)
        rhs[t] = val[t]
        return rhs


__all__ = ["MortarSlip"]
