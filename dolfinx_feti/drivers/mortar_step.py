"""The Newton step of mortar contact with the rows' derivatives: inner QPs on one tangent.

The nonlinear problem of :mod:`.current_mortar` is r(u) = Σ_j λ_j b_j(u), g_j(u) >= 0,
λ >= 0, λ_j g_j(u) = 0 (physical units). Its Newton step at (u_k, λ_k), for the active set
the QP finds, solves

    (K_t + H) Δu + Bᵀ λ = r,      B Δu <= g − (G − B) Δu

with the derivatives H = ∂(Σ λ_j b_j)/∂u and G = −∂g/∂u (:mod:`.mortar_linearization`).
H is unsymmetric (the turning normal acts on the force, not back) and couples the two bodies,
while FETI's K must be symmetric and block diagonal by subdomain: the factored tangent holds
S, the symmetric part of H on the pairs of dofs of one subdomain, and the remainder R = H − S
and G − B go to the right-hand sides of a fixed point on the same factorization:

    (K_t + S) Δu⁽ⁱ⁺¹⁾ + Bᵀ λ⁽ⁱ⁺¹⁾ = r − R Δu⁽ⁱ⁾,    B Δu⁽ⁱ⁺¹⁾ <= g − (G − B) Δu⁽ⁱ⁾,

every iterate an exact-constraint contact QP (:meth:`~dolfinx_feti.FetiSolver.update_rhs`:
no assembly, no factorization). Its fixed point is the Newton step; it contracts by about the
size of R and G − B against K_t and B (a tenth on the cases measured: docs/benchmarks.md).
Where it does not contract (the change of Δu not falling by a tenth; the blocks compressed
40 %, whose tangent is close to singular) the step is that of the frozen rows. It stops when
the change of Δu is below ``eta`` of Δu, eta of the order of the relative step
itself, so that the outer iteration stays quadratic (an inexact Newton method whose forcing
term falls like the step).
"""

from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..constraints.rows import Kind
from .current_rows import rows_with_rhs


def _row_of_base(mortar, rows) -> np.ndarray:
    """For every own row of ``rows``, its row in ``mortar.derivs`` (−1: not a mortar row)."""
    comm = mortar.comm
    found = None
    if comm.rank == 0:
        d = mortar.derivs
        found = (d.spec.astype(np.int64), mortar._points[d.node].astype(np.int64))
    spec, node = comm.bcast(found, root=0)
    own = rows.own
    big = int(max(node.max(initial=0), own.node.max(initial=0))) + 1
    key = spec * big + node
    want = own.spec.astype(np.int64) * big + own.node
    order = np.argsort(key)
    pos = np.minimum(np.searchsorted(key[order], want), max(key.size - 1, 0))
    mortar_rows = np.isin(own.spec, mortar.specs) & (own.kind == Kind.CONTACT)
    hit = mortar_rows & ((key[order][pos] == want) if key.size else False)
    return np.where(hit, order[pos] if key.size else -1, -1)


def gap_change(mortar, rows, du: PETSc.Vec) -> np.ndarray:
    """−s_j (G − B)_j Δu on the rank's own rows (zero but on mortar rows; collective).

    What the rows' right-hand sides c − B u' miss of the linearized gap g − G Δu at
    u' = u_k + Δu: the violation the line search's merit reads.
    """
    U = mortar._displacement(du)
    found = None
    if mortar.comm.rank == 0:
        d = mortar.derivs
        found = (d.G - d.B) @ U.ravel()
    gap = mortar.comm.bcast(found, root=0)
    base = _row_of_base(mortar, rows)
    out = np.zeros(rows.own.size)
    mine = base >= 0
    out[mine] = -rows.own.scale[mine] * gap[base[mine]]
    return out


def exact_step(solver, mortar, qp, rows, start, max_inner: int = 30, eta: float = 0.1,
               floor: float = 0.0):
    """The Newton step of the mortar rows' consistent linearization (collective).

    Args:
        solver: The FetiSolver, factored with K_t + S and the rows of the iterate.
        mortar: The :class:`~.current_mortar.DeformedMortar` with the derivatives of the
            iterate (``derivs``, ``remainder``).
        qp: The solution of the QP with the plain right-hand sides (the first inner iterate).
        rows: The rank's rows of that QP.
        start: Makes a QP start from the multipliers of the rows (an own-rows array).
        max_inner: Inner QPs at most.
        eta: Bound on the relative change of Δu at which to stop.
        floor: An absolute change of Δu (∞-norm) below which to stop.

    Returns:
        ``(qp, inner)``: the last inner QP's solution and the number of inner QPs solved.
    """
    comm = mortar.comm
    data = solver.data
    f0 = solver.qp.system.f.array_r.copy()
    c0 = rows.own.rhs.copy()
    base = _row_of_base(mortar, rows)
    mine = base >= 0
    col = mortar._col.ravel()
    lo, n = data.primal_start, data.K.shape[0]
    inner = 0
    frozen, last_change = qp, np.inf
    du_old = qp.u_vec.copy()
    while inner < max_inner:
        U = mortar._displacement(qp.u_vec)
        found = None
        if comm.rank == 0:
            dU = U.ravel()
            d = mortar.derivs
            found = (mortar.remainder @ dU, (d.G - d.B) @ dU)
        force, gap = comm.bcast(found, root=0)
        f = f0.copy()
        here = (col >= lo) & (col < lo + n)
        np.add.at(f, col[here] - lo, -force[here])
        c = c0.copy()
        c[mine] -= rows.own.scale[mine] * gap[base[mine]]
        new_rows = rows_with_rhs(rows, c, comm)
        solver.update_rhs(f, new_rows)
        x0 = start(qp.lam.array_r)
        qp = solver.solve(x0)
        if x0 is not None:
            x0.destroy()
        inner += 1
        du_old.axpy(-1.0, qp.u_vec)
        change = du_old.norm(PETSc.NormType.INFINITY)
        size = qp.u_vec.norm(PETSc.NormType.INFINITY)
        du_old.destroy()
        du_old = qp.u_vec.copy()
        if change <= max(eta * size, floor) or not qp.report.converged:
            break
        if change > 0.9 * last_change or inner == max_inner:
            # no contraction (a tangent near a limit point, K⁻¹H not small): the step of
            # the frozen rows, which the line search takes as before
            du_old.destroy()
            return frozen, 0
        last_change = change
    du_old.destroy()
    return qp, inner
