"""Krylov recycling: the CG directions of earlier solves on one operator, reused.

Repeated solves with one Hessian (load cases, load steps, SMALBE's inner solves at fixed ρ) each
build a Krylov subspace of their own. The directions ``W`` of the last CG steps and their
products ``A W`` (which the CG steps computed anyway) span a subspace on which the next solve's
error can be removed by linear algebra alone: the Galerkin step ``x <- x + W c``,
``(WᵀAW) c = -Wᵀg``, ``g <- g + A W c`` — no product by ``A`` (Farhat, Crivelli & Roux 1994;
Risler & Rey 2000, "total reuse"; Gosselet & Rey 2002, selective reuse; Saad, Yeung, Erhel &
Guyomarc'h 2000, deflated CG, whose start this is).

In a bound-constrained QP only the directions that vanish on the entries held at a bound may
be used (they keep the face), and the step is cut where it meets a bound (feasible, and the
energy still decreases: the step length is at most the minimizing one). :class:`.mpgp_steps.
MPGPSolve` applies it at its start and whenever its CG restarts in a new face
(:meth:`Recycle.galerkin`); optionally the CG directions of such a face are then kept
A-conjugate to ``W`` (``deflate``: ``m`` dot products a step), so that CG runs on the deflated
operator.

The operator must be the same: the store is bound to a key (the Hessian object and a shift,
e.g. SMALBE's ρ) and forgets everything when the key changes; a caller whose operator changes
in place (new constraint rows, a new stiffness) calls :meth:`Recycle.clear`. Memory: ``k``
pairs of vectors (a caller may make room for more: :meth:`Recycle.grow`).

A caller whose operator changes a little (a moving curved obstacle turns the contact rows: F = B
K⁺ Bᵀ moves by ~the turn of the normals) calls :meth:`Recycle.carry` instead: the next key of
the same form (the Hessian, or SMALBE's ``(A, ρ)`` whatever ρ) keeps the pairs as *stale* ones,
whose products are of the old operator. The next solve checks the change with one product
(:meth:`Recycle.check`, :data:`CARRY_RTOL`); its Galerkin steps take the coefficients from the
old Gram matrix and multiply their step by the new operator, its deflation is approximate
(:mod:`.mpgp_steps`: refined by repeated Galerkin steps where it loses the descent). The new
exact pairs go into the same ring (their Gram columns are exact; the stale ones, the oldest, are
overwritten first), and each Galerkin step's exact pair replaces the stale column of its largest
weight (:meth:`Recycle.swap`); each column knows whether its product is stale.
"""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from ..parallel.reduce import sum_array, sum_scalar

# Eigenvalues of WᵀAW below this fraction of the largest are dropped: the kept directions of
# different CG segments (restarted at expansions) are not A-conjugate and may be nearly
# dependent.
GRAM_RTOL = 1e-10


#: A store carried across a small change of the operator (:meth:`Recycle.carry`) is kept
#: (stale) only if the newest stored direction's new product differs from its stored one by
#: at most this fraction of it; else it is cleared as before. The moving sphere S3: 3e-4; a
#: random QP of tests/qp (docs/benchmarks_history.md § 34) gained at 2.4e-3 (221 against 237
#: products) and lost at 2.4e-2 (262 against 250).
CARRY_RTOL = 1e-2

#: Tries of the projected Galerkin expansion before their record decides
#: (:meth:`Recycle.project_pays`).
PROJECT_TRIES = 8


class Recycle:
    """The last ``k`` directions ``w`` and products ``A w`` of solves on one operator.

    Held as two ``n × k`` arrays (this rank's rows) and the Gram matrix ``WᵀAW``, whose new
    columns are computed once, when a solve adds its directions (:meth:`commit`).

    Args:
        k: How many pairs to keep (the oldest are overwritten); 0 keeps none.
        deflate: Keep the CG directions of a face A-conjugate to the usable ``W`` too.
    """

    def __init__(self, k: int, *, deflate: bool = True) -> None:
        if k < 0:
            raise ValueError(f"recycle: k must be >= 0, got {k}")
        self.k, self.deflate = int(k), bool(deflate)
        self.base_k = self.k  # the capacity a new operator starts with (:meth:`clear`)
        self._W = self._AW = None
        self._C = np.zeros((self.k, self.k))
        self._filled = 0  # columns in use
        self._next = 0  # the column the next pair overwrites
        self._pending: list[tuple[np.ndarray, np.ndarray]] = []
        self._key: tuple | None = None
        self._carry = False  # the next new key: keep the pairs, stale (:meth:`carry`)
        self._old = np.zeros(self.k, dtype=bool)  # columns whose product is of an earlier A
        self.checked = True  # the guard of a carried store was applied (:meth:`check`)
        #: the relative change of the newest direction's product that :meth:`check` measured
        self.change = 0.0
        #: Galerkin steps taken, and the directions they used; projected Galerkin expansions
        #: tried and kept (over the store's life, across clears).
        self.stats = {"steps": 0, "directions": 0, "projections": 0, "projections_kept": 0,
                      "carried": 0, "carry_refused": 0}

    def __len__(self) -> int:
        return self._filled

    def clear(self) -> None:
        """Forget every direction (the operator changed); back to the first capacity."""
        self._filled = self._next = 0
        self._pending.clear()
        self._key = None
        self._carry, self.checked = False, True
        if self.k != self.base_k:
            self.k = self.base_k
            self._W = self._AW = None
            self._C = np.zeros((self.k, self.k))
        self._old = np.zeros(self.k, dtype=bool)

    def grow(self, k: int) -> None:
        """Keep up to ``k`` pairs from now on (no fewer than now); the kept ones stay.

        A caller whose next solves are on the same operator and whose errors lie in the span of
        several earlier solves (the steps of a load path) makes room for more than one
        solve's directions (:class:`~dolfinx_feti.FetiSolver` per load case). The columns are
        put in their order of arrival, the Gram matrix with them (no product, no reduction).
        """
        k = int(k)
        if k <= self.k:
            return
        f = self._filled
        order = np.arange(f) if f < self.k else (self._next + np.arange(self.k)) % self.k
        if self._W is not None:
            W, AW = np.zeros((self._W.shape[0], k)), np.zeros((self._W.shape[0], k))
            W[:, :f], AW[:, :f] = self._W[:, order], self._AW[:, order]
            self._W, self._AW = W, AW
        C = np.zeros((k, k))
        C[:f, :f] = self._C[np.ix_(order, order)]
        old = np.zeros(k, dtype=bool)
        old[:f] = self._old[order]
        self._old = old
        self._C, self.k, self._next = C, k, f

    def project_pays(self) -> bool:
        """Whether to try the projected Galerkin expansion (:class:`.expansion.GalerkinExpansion`).

        Each try costs a product and a rejected one buys nothing. Where the recycled space
        reaches the next active set (a load path's growing contact zone) nearly every try is
        kept (20 of 21 on the 3D pushed-sphere path); where it does not (Newton's increment
        QPs with friction: 364 of 3 334 kept) the tries cost more than they save. After
        :data:`PROJECT_TRIES` tries, they go on only while at least half were kept.
        """
        tried, kept = self.stats["projections"], self.stats["projections_kept"]
        return tried < PROJECT_TRIES or 2 * kept >= tried

    def projected(self, kept: bool) -> None:
        """Record a try of the projected Galerkin expansion."""
        self.stats["projections"] += 1
        self.stats["projections_kept"] += int(kept)

    def bind(self, key: tuple) -> None:
        """Use the store for the operator named by ``key``; a new key clears it.

        ``key``: the Hessian object (compared by identity: a new Mat is a new operator; the
        store holds it, so its identity cannot pass to another) and numbers (compared by
        value, e.g. a penalty).
        """
        old = self._key
        same = old is not None and len(old) == len(key) and all(
            a == b if isinstance(a, int | float) else a is b
            for a, b in zip(old, key, strict=True))
        if not same:
            # to a key of the same form whatever its numbers (SMALBE's inner Hessian A + ρG̃ᵀG̃:
            # G̃ changes with the rows and ρ with the new ‖A‖): the guard measures the change
            carried = self._carry and old is not None and len(old) == len(key)
            if carried:
                self._old[:self._filled] = True
                self.checked = False
            else:
                self.clear()
        self._carry = False
        self._key = key

    def carry(self) -> None:
        """The next operator bound is a slightly changed one on the same unknowns.

        The next :meth:`bind` with another key of the same form (MPRGP's Hessian, SMALBE's
        ``(A, ρ)`` with another A and any ρ; a key of another form clears) keeps the pairs as
        stale ones: their products are of the old operator. The solve that binds it checks the
        change (:meth:`check`, one product); its Galerkin steps on stale columns multiply their
        step by the new operator; the pairs it records are exact and overwrite the oldest columns
        (the stale ones first). Nothing stored: as :meth:`clear`.
        """
        if self._filled == 0:
            self.clear()
            return
        self._carry = True

    @property
    def stale(self) -> bool:
        """Whether some stored products are of an earlier operator (:meth:`carry`)."""
        return bool(self._old[:self._filled].any())

    def newest(self) -> tuple[np.ndarray, np.ndarray]:
        """The last stored pair ``(w, A_old w)`` (views)."""
        j = (self._next - 1) % self.k
        return self._W[:, j], self._AW[:, j]

    def check(self, Aw: np.ndarray, comm: MPI.Comm) -> bool:
        """Keep the stale store if the newest direction's new product ``Aw`` is near its old.

        ``‖A_new w − A_old w‖ <= CARRY_RTOL ‖A_old w‖`` (collective); else :meth:`clear`.
        Returns whether the store was kept.
        """
        w, aw = self.newest()
        d2, a2 = sum_array(comm, np.array([float((Aw - aw) @ (Aw - aw)), float(aw @ aw)]))
        self.checked = True
        self.change = math.sqrt(d2 / a2) if a2 > 0.0 else math.inf
        if not d2 <= CARRY_RTOL ** 2 * a2:
            self.stats["carry_refused"] += 1
            self.clear()
            return False
        self.stats["carried"] += 1
        j = (self._next - 1) % self.k
        self._AW[:, j] = Aw
        self._exact(j, comm)
        return True

    def swap(self, c: np.ndarray, d: np.ndarray, Ad: np.ndarray, comm: MPI.Comm) -> bool:
        """Put the exact pair ``(d, A d)`` of a Galerkin step ``d = W c`` in the store.

        It replaces the stale column ``j`` of the largest ``|c_j|`` (unit columns), so the span
        stays (``c_j ≠ 0``) and one column more is exact, the one this solve's error needed
        most; its Gram row and column are computed again (exact, ``f`` dot products). Returns
        whether a column was replaced (collective). The 4-step moving sphere of
        tests/drivers/test_krylov_recycle.py on DOLFINx 0.11's mesh: 56, 53, 51 →
        55, 28, 30 F-multiplications (0.5.2's: 34, 27, 32 → 34, 27, 29; the moving sphere S3's
        path 170 → 167).
        """
        f = self._filled
        wgt = np.where(self._old[:f], np.abs(c[:f]), 0.0)
        j = int(np.argmax(wgt))
        if not wgt[j] > 0.0:
            return False
        nd = math.sqrt(sum_scalar(comm, float(d @ d)))
        if not nd > 0.0:
            return False
        self._W[:, j], self._AW[:, j] = d / nd, Ad / nd
        self._exact(j, comm)
        return True

    def _exact(self, j: int, comm: MPI.Comm) -> None:
        """Column ``j``'s product is now of the current operator: its Gram row and column."""
        self._old[j] = False
        f = self._filled
        col = sum_array(comm, self._W[:, :f].T @ self._AW[:, j])
        self._C[:f, j] = col
        self._C[j, :f] = col

    def record(self, p: np.ndarray, Ap: np.ndarray) -> None:
        """Keep the pair ``(p, A p)`` (copied) when the solve ends (:meth:`commit`)."""
        if self.k:
            self._pending.append((np.array(p, dtype=np.float64),
                                  np.array(Ap, dtype=np.float64)))
            del self._pending[:-self.k]

    def commit(self, comm: MPI.Comm) -> None:
        """Add the pairs of the solve that ended (collective); the Gram matrix's new columns."""
        if not self._pending:
            return
        n = self._pending[0][0].size
        if self._W is None or self._W.shape[0] != n:
            self._W, self._AW = np.zeros((n, self.k)), np.zeros((n, self.k))
            self._filled = self._next = 0
            self._old[:] = False
        # unit columns: the Gram matrix's eigenvalues then lie in A's spectrum for conjugate
        # directions, and GRAM_RTOL drops dependence, not the late CG directions' small norms
        norms = np.sqrt(sum_array(comm, np.array([float(w @ w) for w, _ in self._pending])))
        cols = []
        for (w, a), nw in zip(self._pending, norms, strict=True):
            if not nw > 0.0:
                continue
            j = self._next
            self._W[:, j], self._AW[:, j] = w / nw, a / nw
            self._old[j] = False
            self._next = (j + 1) % self.k
            self._filled = min(self._filled + 1, self.k)
            cols.append(j)
        self._pending.clear()
        if not cols:
            return
        cols = np.array(sorted(set(cols)))
        f = self._filled
        block = sum_array(comm, self._W[:, :f].T @ self._AW[:, cols])  # f × new
        self._C[:f, cols] = block
        self._C[cols, :f] = block.T

    def basis(self, fixed: np.ndarray, comm: MPI.Comm) -> Basis | None:
        """The stored directions that vanish on ``fixed`` (local mask), as a :class:`Basis`."""
        f = self._filled
        if f == 0:
            return None
        bad = np.any(self._W[fixed, :f] != 0.0, axis=0).astype(np.int64)
        use = np.flatnonzero(sum_array(comm, bad) == 0)
        if use.size == 0:
            return None
        return Basis(self._W[:, :f], self._AW[:, :f], self._C[:f, :f], use, comm,
                     stale=bool(self._old[use].any()))


class Basis:
    """Usable recycled directions: columns ``use`` of ``W``, ``A W`` and ``(WᵀAW)^+``.

    The products go over all stored columns, the unused ones with zero weight (no copy of
    the ``n × k`` arrays).
    """

    def __init__(self, W: np.ndarray, AW: np.ndarray, C: np.ndarray, use: np.ndarray,
                 comm: MPI.Comm, stale: bool = False) -> None:
        self.W, self.AW, self.use, self.comm = W, AW, use, comm
        #: ``AW`` and ``C`` are of an earlier operator (:meth:`Recycle.carry`)
        self.stale = stale
        self.c: np.ndarray | None = None  # the weights of the last Galerkin step
        Cu = C[np.ix_(use, use)]
        lam, Q = np.linalg.eigh(0.5 * (Cu + Cu.T))
        keep = lam > GRAM_RTOL * max(float(lam[-1]), 0.0)
        # C^+ restricted to its well-conditioned part: Q_k diag(1/λ_k) Q_kᵀ
        self.Q, self.inv = Q[:, keep], 1.0 / lam[keep]
        self.m = int(keep.sum())

    def _solve(self, r: np.ndarray) -> np.ndarray:
        """``(WᵀAW)^+ r`` on the used columns, as a weight of every stored column."""
        c = np.zeros(self.W.shape[1])
        ru = r[self.use]
        c[self.use] = self.Q @ (self.inv * (self.Q.T @ ru))
        return c

    def galerkin(self, g: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """``(d, A d)`` with ``d = W c``, ``(WᵀAW) c = -Wᵀg``; None when nothing to gain."""
        if self.m == 0:
            return None
        c = self._solve(-sum_array(self.comm, self.W.T @ g))
        if not np.all(np.isfinite(c)) or not np.any(c):
            return None
        self.c = c  # the weights of the last step (Recycle.swap)
        return self.W @ c, self.AW @ c

    def conjugate(self, p: np.ndarray) -> np.ndarray:
        """``p - W (WᵀAW)^+ (AW)ᵀ p``: A-conjugate to the usable directions."""
        if self.m == 0:
            return p
        return p - self.W @ self._solve(sum_array(self.comm, self.AW.T @ p))


def galerkin_step(S, xa: np.ndarray, ga: np.ndarray, d: np.ndarray, Ad: np.ndarray,
                  comm: MPI.Comm) -> tuple[float, float] | None:
    """Step length along ``d`` (``x + t d``): the minimizing one cut at the set's boundary.

    Returns ``(t, t_min)`` with ``t_min`` the minimizing length, or None when ``d`` is no
    descent direction (rounding) or the step is empty.
    """
    gd, dAd = sum_array(comm, np.array([float(ga @ d), float(d @ Ad)]))
    if not (dAd > 0.0 and gd < 0.0 and math.isfinite(gd)):
        return None
    t_min = -gd / dAd
    t = min(t_min, S.max_step(xa, -d))
    return (t, t_min) if t > 0.0 else None


__all__ = ["CARRY_RTOL", "GRAM_RTOL", "PROJECT_TRIES", "Basis", "Recycle", "galerkin_step"]
