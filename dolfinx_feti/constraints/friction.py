"""Friction rows: tangents of the contact normals, the tangential rows of B and their slip bounds.

A contact node with friction gets, next to its normal (non-penetration) row, one tangential row
per tangent direction t (one in 2D, two orthonormal ones in 3D)::

    node-to-node:  scale · (u_slave − u_master)·t      (scale = 1/√2, like the normal row)
    obstacle:      u·t                                 (scale = 1)

with right-hand side 0: the row measures the relative tangential displacement (the slip). Its
multiplier λ_T (physical value scale·λ, a nodal force) is bounded: |λ_T| <= g in 2D (a box),
||(λ_T1, λ_T2)|| <= g in 3D (a disc), g the nodal slip bound. The rows of one node are
consecutive in B (normal row first) and are owned by the same rank.

On a symmetry plane (a contact node with exactly one displacement component held by a Dirichlet
condition, u_j, and a contact normal nearly in that plane) the friction force has no component
normal to the plane (the mirror image of the problem cancels it), and the tangential row along
it is nearly a combination of the Dirichlet rows u_j = 0 of the slave and the plane's master
nodes: kept, it makes the dual problem nearly singular in that row and the disc couples the
ill-determined multiplier with the one that carries the load (measured: tens to hundreds of
times the F-multiplications). Such a node's tangents are the in-plane tangent t1 ∝ n × e_j and
t2 = n × t1 (the plane's normal, made tangent), and its t2 row is *pinned*: its multiplier is
held at zero, so the disc becomes the interval |λ_T1| <= g (2D: the one tangent lies along
e_j and is pinned). :data:`SYMMETRY_NORMAL` bounds |n·e_j|.

Sign convention (Lagrangian ½uᵀKu − fᵀu + λᵀ(Bu − c)): the friction force on the slave node is
−Σ_k λ_T,k t_k; where a node slips, its slip s = Σ_k ((u_s − u_m)·t_k) t_k is parallel to
Σ_k λ_T,k t_k, i.e. opposite to the friction force; where it sticks (|λ_T| < g), s = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..mesh.data import MeshData
from ..problem.conditions import Coulomb, Tresca
from ..problem.contact_problem import ContactProblem
from ..validation import evaluate
from .contact import surface
from .rows import Kind, Rows

#: Components of a unit normal within this of its smallest count as tied for t1's axis (the
#: first of them wins): a normal in a coordinate plane, (ε, 1, ε') with ε, ε' round-off, must
#: not swap t1 between e_x and e_z from one Newton iterate to the next — the tangential
#: multipliers of the last iterate's rows would then act along the other tangent in the rows
#: of the next one, and Newton's exact check with the rows of u fails until the round-off
#: happens to agree.
TANGENT_TIE = 1e-8

#: Values of ``ContactData.state``.
FRICTIONLESS, STICK, SLIP = 0, 1, 2

#: A contact node with one Dirichlet-held component j is on a symmetry plane when its normal
#: has |n_j| at most this (a normal averaged over the facets on one side of the plane tilts
#: by about h / (2 × the radius of curvature)).
SYMMETRY_NORMAL = 0.5


def symmetry_axes(fixed: np.ndarray | None, node: np.ndarray, normal: np.ndarray
                  ) -> np.ndarray:
    """Per contact node: the axis j of the symmetry plane it lies on, or −1 (module docstring).

    Args:
        fixed: (points, bs) mask of the Dirichlet-held components, or None (no plane).
        node: The contact nodes (points).
        normal: Their unit contact normals, (k, gdim).
    """
    k, d = np.shape(normal)
    axis = np.full(k, -1, dtype=np.int64)
    if fixed is None or k == 0:
        return axis
    held = np.asarray(fixed)[np.asarray(node), :d]
    one = held.sum(axis=1) == 1
    j = np.argmax(held, axis=1)
    flat = np.abs(np.asarray(normal)[np.arange(k), j]) <= SYMMETRY_NORMAL
    axis[one & flat] = j[one & flat]
    return axis


def tangent_basis(normal: np.ndarray, plane_axis: np.ndarray | None = None) -> np.ndarray:
    """Unit tangents orthogonal to unit normals, shape (k, gdim − 1, gdim).

    2D: t = (n_y, −n_x), so that (t, n) is right-handed. 3D: t1 is the coordinate axis least
    aligned with n (the first one in a tie, within :data:`TANGENT_TIE`) made orthogonal to n
    by Gram–Schmidt, t2 = n × t1, so that (t1, t2, n) is right-handed. A node on a symmetry
    plane of axis j (``plane_axis`` >= 0, :func:`symmetry_axes`) gets t1 ∝ n × e_j instead (in
    the plane).
    """
    n = np.asarray(normal, dtype=float)
    k, d = n.shape
    if d == 2:
        return np.stack([n[:, 1], -n[:, 0]], axis=1)[:, None, :]
    a = np.abs(n)
    axis = np.argmax(a <= a.min(axis=1, keepdims=True) + TANGENT_TIE, axis=1)
    e = np.zeros((k, 3))
    e[np.arange(k), axis] = 1.0
    t1 = e - np.einsum("ij,ij->i", e, n)[:, None] * n
    t1 /= np.linalg.norm(t1, axis=1)[:, None]
    on = np.flatnonzero(plane_axis >= 0) if plane_axis is not None else np.zeros(0, int)
    if on.size:
        ej = np.zeros((on.size, 3))
        ej[np.arange(on.size), plane_axis[on]] = 1.0
        t = np.cross(n[on], ej)
        t1[on] = t / np.linalg.norm(t, axis=1)[:, None]
    t2 = np.cross(n, t1)
    return np.stack([t1, t2], axis=1)


def with_tangential_rows(normal: Rows, fixed: np.ndarray | None = None) -> Rows:
    """The normal rows of one contact condition with their tangential rows interleaved.

    ``fixed``: the (points, bs) mask of the Dirichlet-held components; the nodes on a symmetry
    plane get the tangents of :func:`tangent_basis` (the pinned one last).

    A normal row is Σ_k w_k n·u_k over its nodes (node-to-node: the slave and its master;
    mortar: the slave and the weighted master nodes; obstacle: the node alone), so each
    node's weight is w_k = Σ_c coef_c n_c; its tangential rows are −Σ_k w_k t·u_k, which puts
    the slave node with +scale·t as the module docstring says. Row order: for each contact
    node, its normal row, then its gdim − 1 tangential rows.
    """
    k, d = normal.normal.shape
    nt = d - 1
    T = tangent_basis(normal.normal, symmetry_axes(fixed, normal.node, normal.normal))
    # The weight of each (row, node): entries of one node in one row are summed.
    key = normal.e_row.astype(np.int64) * (int(normal.e_node.max(initial=0)) + 1) + normal.e_node
    uniq, first_entry, inv = np.unique(key, return_index=True, return_inverse=True)
    w = np.zeros(uniq.size)
    np.add.at(w, inv, normal.e_coef * normal.normal[normal.e_row, normal.e_comp])
    u_row, u_node, u_sub = (a[first_entry] for a in (normal.e_row, normal.e_node, normal.e_sub))
    nrow = k * nt
    # Entries: for each (row, node) and each tangent, d components.
    e_row = (u_row[:, None] * nt + np.arange(nt)[None, :]).repeat(d, axis=1).ravel()
    e_coef = (-w[:, None, None] * T[u_row]).ravel()
    e_node = np.repeat(u_node, nt * d)
    e_sub = np.repeat(u_sub, nt * d)
    e_comp = np.tile(np.arange(d), u_row.size * nt)
    # a node whose normal row has every component (an obstacle's; a pair's under large
    # deformation) keeps them all: its tangents turn with the current normal
    # (drivers/newton_friction.py)
    full = np.bincount(inv, minlength=uniq.size) == d
    keep = (e_coef != 0.0) | np.repeat(full, nt * d)
    tangential = Rows(
        e_row=e_row[keep], e_sub=e_sub[keep].astype(np.int32), e_node=e_node[keep],
        e_comp=e_comp[keep].astype(np.int8), e_coef=e_coef[keep], rhs=np.zeros(nrow),
        kind=np.full(nrow, Kind.TANGENT, dtype=np.int8), scale=np.repeat(normal.scale, nt),
        node=np.repeat(normal.node, nt), partner=np.repeat(normal.partner, nt),
        normal=T.reshape(nrow, d), spec=np.repeat(normal.spec, nt))
    both = Rows.concatenate([normal, tangential])
    order = np.empty((k, nt + 1), dtype=np.int64)
    order[:, 0] = np.arange(k)
    order[:, 1:] = k + np.arange(nrow).reshape(k, nt)
    return both.permuted(order.ravel())


@dataclass
class FrictionData:
    """The friction rows of a problem in the global row order (the same on every rank).

    Attributes:
        rows: Global indices of the TANGENT rows, ascending; the ``per_node`` rows of one
            contact node are consecutive.
        normal_row: The normal (CONTACT or OBSTACLE) row of the same contact node, per row.
        per_node: Tangential rows per contact node (gdim − 1).
        tresca: Nodal Tresca bound (a force: traction bound × lumped area) per row; NaN on
            Coulomb rows.
        coefficient: Coulomb coefficient per row; NaN on Tresca rows.
        area: Lumped area (length in 2D) of the contact node on its surface, per row.
        rtol: The Coulomb residual max|g − 𝓕λ_N| / max λ_N that ends the Coulomb fixed point.
        max_steps: Budget of Coulomb fixed-point steps.
        pinned: Per row: the row along the normal of a symmetry plane, whose multiplier is
            held at zero (the module docstring); None: none.
    """

    rows: np.ndarray
    normal_row: np.ndarray
    per_node: int
    tresca: np.ndarray
    coefficient: np.ndarray
    area: np.ndarray
    rtol: float
    max_steps: int
    pinned: np.ndarray | None = None

    @property
    def coulomb(self) -> bool:
        """Whether any bound depends on the normal forces (a fixed point is needed)."""
        return bool(np.any(~np.isnan(self.coefficient)))


def friction_data(problem: ContactProblem, rows: Rows, fixed: np.ndarray | None = None
                  ) -> FrictionData | None:
    """Collect the friction rows of built (and ordered) rows; None without friction.

    ``fixed`` is the mask the rows were built with (:func:`with_tangential_rows`): the rows
    pinned on symmetry planes follow from it.
    """
    t = np.flatnonzero(rows.tangential)
    if t.size == 0:
        return None
    mesh: MeshData = problem.mesh
    nt = mesh.gdim - 1
    ineq = np.flatnonzero(rows.inequality)
    N = np.int64(problem.dof_points.num_points)
    key_n = rows.spec[ineq].astype(np.int64) * N + rows.node[ineq]
    key_t = rows.spec[t].astype(np.int64) * N + rows.node[t]
    sorter = np.argsort(key_n, kind="stable")
    pos = np.minimum(np.searchsorted(key_n[sorter], key_t), key_n.size - 1)
    normal_row = ineq[sorter[pos]]
    if not np.array_equal(key_n[sorter[pos]], key_t):
        raise AssertionError("a tangential row has no normal row")
    grouped = t.reshape(-1, nt)
    if not (np.all(np.diff(grouped, axis=1) == 1)
            and np.all(normal_row.reshape(-1, nt) == normal_row.reshape(-1, nt)[:, :1])):
        raise AssertionError("the tangential rows of a contact node are not consecutive")
    owner = rows.min_subdomain()
    if not np.array_equal(owner[t], owner[normal_row]):
        raise AssertionError("a tangential row and its normal row have different owners")

    tresca = np.full(t.size, np.nan)
    coefficient = np.full(t.size, np.nan)
    area = np.zeros(t.size)
    rtol, max_steps = np.inf, 0
    for i, c in enumerate(problem.contact):
        m = rows.spec[t] == i
        if not np.any(m):
            continue
        group = c.group
        nodes, _, a = surface(mesh, group, problem.dof_points)
        node = rows.node[t[m]]
        area[m] = a[np.searchsorted(nodes, node)]
        fr = c.friction
        tresca[m], coefficient[m] = NODAL_VALUES[type(fr)](fr, problem.dof_points.x[node],
                                                           group, area[m])
        if (point := fr.fixed_point()) is not None:
            rtol, max_steps = min(rtol, point[0]), max(max_steps, point[1])
    axis = symmetry_axes(fixed, rows.node[t], rows.normal[normal_row])
    pinned = (axis >= 0) & (np.arange(t.size) % nt == nt - 1)  # the last tangent of the node
    return FrictionData(rows=t, normal_row=normal_row, per_node=nt, tresca=tresca,
                        coefficient=coefficient, area=area, rtol=float(rtol),
                        max_steps=int(max_steps), pinned=pinned if pinned.any() else None)


def _tresca_values(fr: Tresca, x: np.ndarray | None, group: str, area: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The nodal slip bounds g(x)·A of Tresca's rows (no Coulomb coefficient)."""
    return _traction_bound(fr, x, group, area.size) * area, np.full(area.size, np.nan)


def _coulomb_values(fr: Coulomb, x: np.ndarray | None, group: str, area: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Coulomb's coefficient at each row (the slip bounds come from the normal forces)."""
    return np.full(area.size, np.nan), np.full(area.size, float(fr.coefficient))


#: Friction law → ``values(law, x, group, area) -> (Tresca bounds, Coulomb coefficients)`` of
#: its rows at the nodes x (NaN where the law has none); x may be None for a bound that is a
#: number. A new friction law is a class in problem/ and an entry here.
NODAL_VALUES = {Tresca: _tresca_values, Coulomb: _coulomb_values}


def _traction_bound(fr: Tresca, x: np.ndarray | None, group: str, n: int) -> np.ndarray:
    """The Tresca traction bound g(x) at the n nodes x, checked."""
    if callable(fr.bound):
        g = evaluate(fr.bound, x, f"Tresca bound on {group!r}: bound", [(x.shape[0],), ()])
        g = np.broadcast_to(g, (x.shape[0],))
    else:
        g = np.full(n, float(fr.bound))
    if np.any(np.isnan(g)) or np.any(g < 0):
        raise InputError(f"Tresca bound on {group!r}: the slip bound must be >= 0 (inf allowed) "
                         "at every node")
    return g
