"""The FETI layer as algebra: the transforms on hand-made K, B, R (no mesh, no assembly).

Two scalar "membranes" on a grid, each cut into subdomains by hand; Q1 element matrices of the
Laplacian assembled here; gluing (orthonormal), Dirichlet and contact rows written here. Total
FETI, FETI-1 and FETI-DP (corners chosen by hand) must all give the solution of a monolithic
primal-dual active set solve of the same QP, and the transforms' pieces must be what their
definitions say.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.drivers.qp_solve import solve_qp
from dolfinx_feti.feti import BlockSystem, EliminateCorners, EliminateDirichlet
from dolfinx_feti.feti.system import EQUALITY, INEQUALITY, petsc_aij
from dolfinx_feti.setup.stages import chain_qp

comm = MPI.COMM_WORLD
Q1 = np.array([[4, -1, -2, -1], [-1, 4, -1, -2], [-2, -1, 4, -1], [-1, -2, -1, 4]]) / 6.0


class Membranes:
    """Body A = [0,4]×[0,4] cells (held on x = 0), body B = [4,6]×[0,4] cells (held on x = 6
    when ``held``, else floating), contact u_A − u_B <= 0 on x = 4 (matching nodes).

    A is cut into 2 × 2 subdomains of 2 × 2 cells; B into two subdomains stacked in y. Loads
    are lumped: −1 on B's cells, −0.5 on A's upper cells.
    """

    def __init__(self, held: bool) -> None:
        self.held = held
        nx, ny = 7, 5  # nodes of the two grids side by side (A: x 0..4, B: x 4..6)
        self.nodes_A = [(i, j) for i in range(5) for j in range(ny)]
        self.nodes_B = [(i, j) for i in range(4, nx) for j in range(ny)]
        pts = [("A", p) for p in self.nodes_A] + [("B", p) for p in self.nodes_B]
        self.node_id = {p: k for k, p in enumerate(pts)}
        self.N = len(pts)
        # subdomains: (body, i-range of cells, j-range of cells)
        self.subs = [("A", (0, 2), (0, 2)), ("A", (2, 4), (0, 2)), ("A", (0, 2), (2, 4)),
                     ("A", (2, 4), (2, 4)), ("B", (4, 6), (0, 2)), ("B", (4, 6), (2, 4))]
        self.sub_nodes, self.sub_K, self.sub_f = [], [], []
        for body, (i0, i1), (j0, j1) in self.subs:
            nodes = sorted({self.node_id[(body, (i, j))] for i in range(i0, i1 + 1)
                            for j in range(j0, j1 + 1)})
            loc = {n: k for k, n in enumerate(nodes)}
            K = np.zeros((len(nodes), len(nodes)))
            f = np.zeros(len(nodes))
            for i in range(i0, i1):
                for j in range(j0, j1):
                    cell = [loc[self.node_id[(body, q)]] for q in
                            ((i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1))]
                    K[np.ix_(cell, cell)] += Q1
                    load = -1.0 if body == "B" else (-0.5 if j >= 2 else 0.0)
                    f[cell] += load / 4
            self.sub_nodes.append(np.array(nodes))
            self.sub_K.append(K)
            self.sub_f.append(f)
        self.fixed = {self.node_id[("A", (0, j))] for j in range(ny)}
        if held:
            self.fixed |= {self.node_id[("B", (6, j))] for j in range(ny)}
        self.contact = [(self.node_id[("A", (4, j))], self.node_id[("B", (4, j))])
                        for j in range(ny)]
        self._rows()

    def _rows(self) -> None:
        """Rows as (entries [(sub, node, coef)], rhs, type, kind); sorted by first subdomain."""
        rows = []
        where = {}
        for s, nodes in enumerate(self.sub_nodes):
            for n in nodes:
                where.setdefault(int(n), []).append(s)
        for n, subs in sorted(where.items()):
            if n in self.fixed:
                for s in subs:
                    rows.append(([(s, n, 1.0)], 0.0, EQUALITY, "dirichlet"))
            elif len(subs) > 1:  # Helmert: k − 1 orthonormal rows
                k = len(subs)
                for j in range(1, k):
                    h = np.sqrt(j * (j + 1))
                    rows.append(([(subs[a], n, 1.0 / h) for a in range(j)]
                                 + [(subs[j], n, -j / h)], 0.0, EQUALITY, "glue"))
        for a, b in self.contact:
            rows.append(([(where[a][0], a, 1 / np.sqrt(2)), (where[b][0], b, -1 / np.sqrt(2))],
                         0.0, INEQUALITY, "contact"))
        rows.sort(key=lambda r: min(e[0] for e in r[0]))
        self.rows = rows
        self.where = where

    # --- the distributed system ------------------------------------------------------------
    def system(self) -> BlockSystem:
        nsub = len(self.subs)
        owner = np.minimum(np.arange(nsub) * comm.size // nsub, comm.size - 1)
        mine = np.flatnonzero(owner == comm.rank)
        sizes = np.array([n.size for n in self.sub_nodes])
        self.offset = np.r_[0, np.cumsum(sizes)]
        start = int(self.offset[mine[0]]) if mine.size else int(self.offset[-1])
        K = sp.block_diag([sp.csr_matrix(self.sub_K[s]) for s in mine], format="csr") \
            if mine.size else sp.csr_matrix((0, 0))
        f = np.concatenate([self.sub_f[s] for s in mine]) if mine.size else np.zeros(0)
        row_owner = np.array([owner[min(e[0] for e in r[0])] for r in self.rows])
        my_rows = [r for r, o in zip(self.rows, row_owner, strict=True) if o == comm.rank]
        data, ii, jj = [], [], []
        for k, (entries, *_rest) in enumerate(my_rows):
            for s, n, coef in entries:
                ii.append(k)
                jj.append(int(self.offset[s]) + int(np.searchsorted(self.sub_nodes[s], n)))
                data.append(coef)
        n_tot = int(self.offset[-1])
        Bl = sp.csr_matrix((data, (ii, jj)), shape=(len(my_rows), n_tot))
        B = petsc_aij(Bl, (len(my_rows), len(self.rows)), (K.shape[0], n_tot), comm)
        self.mine, self.start, self.my_rows = mine, start, my_rows
        kernels = [np.full((self.sub_nodes[s].size, 1), 1 / np.sqrt(self.sub_nodes[s].size))
                   for s in mine]
        return BlockSystem(comm, K, f, B, np.array([r[1] for r in my_rows]),
                           np.array([r[2] for r in my_rows]),
                           np.r_[0, np.cumsum(sizes[mine])], kernels,
                           [f"sub {s}" for s in mine], [self.subs[s][0] for s in mine])

    def dirichlet_rows(self) -> np.ndarray:
        return np.array([r[3] == "dirichlet" for r in self.my_rows], dtype=bool)

    def local_dof_nodes(self) -> np.ndarray:
        return np.concatenate([self.sub_nodes[s] for s in self.mine]) if self.mine.size else \
            np.zeros(0, dtype=np.int64)

    def corners(self, nodes) -> tuple[np.ndarray, int]:
        """Local coarse index of each dof: corner nodes numbered in the given order."""
        index = {int(n): k for k, n in enumerate(nodes)}
        return np.array([index.get(int(n), -1) for n in self.local_dof_nodes()]), len(nodes)

    def floating_modes(self) -> tuple[np.ndarray, list[str]]:
        """The constant on B when B floats (B's two subdomains form one component)."""
        if self.held:
            return np.zeros((self.local_dof_nodes().size, 0)), []
        isB = np.isin(self.local_dof_nodes(), list({int(n) for s in (4, 5)
                                                      for n in self.sub_nodes[s]}))
        return isB[:, None].astype(float), ["B"]

    def nodal(self, u: np.ndarray) -> np.ndarray:
        """Mean over copies of the local primal values, gathered (N,)."""
        acc, cnt = np.zeros(self.N), np.zeros(self.N)
        pos = 0
        for s in self.mine:
            n = self.sub_nodes[s]
            acc[n] += u[pos:pos + n.size]
            cnt[n] += 1
            pos += n.size
        return comm.allreduce(acc) / np.maximum(comm.allreduce(cnt), 1)

    # --- the monolithic reference ----------------------------------------------------------
    def monolithic(self) -> tuple[np.ndarray, np.ndarray]:
        """Primal-dual active set on the assembled problem: (u, contact forces)."""
        N = self.N
        K = np.zeros((N, N))
        f = np.zeros(N)
        for nodes, Ks, fs in zip(self.sub_nodes, self.sub_K, self.sub_f, strict=True):
            K[np.ix_(nodes, nodes)] += Ks
            f[nodes] += fs
        free = np.setdiff1d(np.arange(N), sorted(self.fixed))
        C = np.zeros((len(self.contact), N))
        for r, (a, b) in enumerate(self.contact):
            C[r, a], C[r, b] = 1.0, -1.0
        Kf, ff, Cf = K[np.ix_(free, free)], f[free], C[:, free]
        active = np.ones(len(self.contact), dtype=bool)
        for _ in range(50):
            A = Cf[active]
            M = np.block([[Kf, A.T], [A, np.zeros((A.shape[0], A.shape[0]))]])
            sol = np.linalg.lstsq(M, np.r_[ff, np.zeros(A.shape[0])], rcond=None)[0]
            uf, lam = sol[:free.size], np.zeros(len(self.contact))
            lam[active] = sol[free.size:]
            new = lam + 1e3 * (Cf @ uf) > 0
            if np.array_equal(new, active):
                break
            active = new
        u = np.zeros(N)
        u[free] = uf
        # KKT certificate
        assert np.abs(Kf @ uf - ff + Cf.T @ lam).max() <= 1e-10
        assert (Cf @ uf).max() <= 1e-10 and lam.min() >= -1e-10
        assert np.abs(lam * (Cf @ uf)).max() <= 1e-10
        return u, lam


def run(mem: Membranes, method: str, **opts):
    total = mem.system()
    steps = []
    if method in ("feti1", "fetidp"):
        steps.append(EliminateDirichlet(total, mem.dirichlet_rows()))
    if method == "fetidp":
        # the cross point of A's 2 × 2 subdomains, and the middle of B's shared edge
        coarse, nc = mem.corners([mem.node_id[("A", (2, 2))], mem.node_id[("B", (5, 2))]])
        modes, bodies = mem.floating_modes()
        steps.append(EliminateCorners(steps[-1].child, coarse, nc, modes, bodies))
    qp = chain_qp(total, steps, method=method)
    options = df.SolverOptions(rtol=1e-12, **opts)
    options.validate()
    out = solve_qp(qp, options)
    return qp, out


@pytest.fixture(scope="module", params=[True, False], ids=["held", "floating"])
def mem(request):
    return Membranes(request.param)


@pytest.fixture(scope="module")
def mono(mem):
    return mem.monolithic()


@pytest.fixture(scope="module")
def runs(mem):
    return {m: run(mem, m) for m in ("tfeti", "feti1", "fetidp")}


@pytest.mark.parametrize("method", ["tfeti", "feti1", "fetidp"])
def test_against_monolithic(mem, mono, runs, method):
    u_ref, lam_ref = mono
    qp, out = runs[method]
    assert out.result.converged
    u = mem.nodal(out.u.array_r)
    assert np.abs(u - u_ref).max() <= 1e-8 * np.abs(u_ref).max()
    lam = out.lam.array_r[[r[3] == "contact" for r in mem.my_rows]] / np.sqrt(2)  # row scale
    lam_all = np.concatenate(comm.allgather(lam))
    assert np.abs(lam_all - lam_ref).max() <= 1e-8 * lam_ref.max()
    assert lam_ref.max() > 0


def test_methods_agree_on_all_multipliers(runs):
    """Removed rows (Dirichlet, corner gluing) get the same multipliers as in Total FETI."""
    lam = {m: np.concatenate(comm.allgather(out.lam.array_r)) for m, (_, out) in runs.items()}
    scale = np.abs(lam["tfeti"]).max()
    for m in ("feti1", "fetidp"):
        assert np.abs(lam[m] - lam["tfeti"]).max() <= 1e-8 * scale


def test_solver_per_method(mem, runs):
    """Contact and a coarse space: SMALBE; FETI-DP with every body held: MPRGP alone."""
    assert runs["tfeti"][0].constraint.m == 6  # the kernels of all 6 blocks
    assert runs["fetidp"][0].constraint.m == (0 if mem.held else 1)
    # FETI-1: A's blocks at x = 0 and (held) B's are held; the others keep their constant
    assert runs["feti1"][0].constraint.m == (2 if mem.held else 4)


def test_eliminate_dirichlet(mem):
    total = mem.system()
    step = EliminateDirichlet(total, mem.dirichlet_rows())
    child = step.child
    nd = comm.allreduce(int(mem.dirichlet_rows().sum()))
    assert child.dual_size[1] == total.dual_size[1] - nd
    # the fixed dofs: identity rows and columns, zero load, no kernel on held blocks
    K = child.K.toarray()
    fx = step.fixed
    assert np.allclose(K[np.ix_(fx, fx)], np.eye(int(fx.sum())))
    assert np.all(K[np.ix_(fx, ~fx)] == 0) and np.all(child.f.array_r[fx] == 0)
    for i, seg in child.segments():
        held = fx[seg].any()
        assert child.kernels[i].shape[1] == (0 if held else 1)
        if not held:
            assert np.allclose(child.K[seg][:, seg] @ child.kernels[i], 0)


def test_corner_system(mem):
    """K̃ = Eᵀ K E assembled by hand; positive definite exactly when no body floats; K̃⁺ is a
    generalized inverse; the gluing rows between corner copies are gone."""
    total = mem.system()
    s1 = EliminateDirichlet(total, mem.dirichlet_rows())
    corner_nodes = [mem.node_id[("A", (2, 2))], mem.node_id[("B", (5, 2))]]
    coarse, nc = mem.corners(corner_nodes)
    modes, bodies = mem.floating_modes()
    s2 = EliminateCorners(s1.child, coarse, nc, modes, bodies)
    s2.child.factorize()
    # the gluing rows at the corners: 3 at A's cross point, 1 at B's: removed
    assert s1.child.dual_size[1] - s2.child.dual_size[1] == 4
    Kt = s2.child.assembled()
    dense = _gather_dense(Kt)
    # by hand: the assembled matrix on (non-corner copies, corner unknowns)
    Kfull = _gather_dense_csr(s1.child.K, s1.child.primal_start, s1.child.primal_size[1])
    n = Kfull.shape[0]
    is_c = np.concatenate(comm.allgather(coarse >= 0))
    cidx = np.concatenate(comm.allgather(coarse))
    E = np.zeros((n, n + nc))
    E[np.flatnonzero(~is_c), np.flatnonzero(~is_c)] = 1.0
    E[np.flatnonzero(is_c), n + cidx[is_c]] = 1.0
    perm = _dp_columns(s2, n, nc)
    by_hand = (E.T @ Kfull @ E)[np.ix_(perm, perm)]
    assert np.allclose(dense, by_hand, atol=1e-13)
    # restricted to the used unknowns (corner copies are unused entries with identity rows)
    used = np.ones(n + nc, dtype=bool)
    used[np.flatnonzero(is_c)] = False
    used = used[perm]
    w = np.linalg.eigvalsh(dense[np.ix_(used, used)])
    zero = w <= 1e-10 * w.max()
    assert zero.sum() == (0 if mem.held else 1)
    # K̃ K̃⁺ K̃ = K̃ on a random vector
    v = Kt.createVecRight()
    v.setRandom()
    b = v.duplicate()
    Kt.mult(v, b)
    y = v.duplicate()
    s2.child.apply_kplus(b, y)
    r = v.duplicate()
    Kt.mult(y, r)
    r.axpy(-1.0, b)
    assert r.norm() <= 1e-10 * b.norm()
    # Ψ (kept as dense blocks per subdomain) solves K_rr Ψ = K_rc, zero on the corner copies;
    # S_cc = K_cc − K_rcᵀ Ψ summed over the ranks (the corners hold every block here)
    assert all(k.shape[1] == 0 for k in s2.kernels_rr)
    Psi, Krc = s2.algebra.Psi.toarray(), s2.algebra.K_rc.toarray()
    assert not Psi[s2.is_corner].any()
    scale = max(comm.allreduce(float(np.abs(Krc).max(initial=0.0)), op=MPI.MAX), 1e-300)
    assert np.abs(s2.algebra.K_rr @ Psi - Krc)[~s2.is_corner].max(initial=0.0) <= 1e-12 * scale
    S = comm.allreduce(s2.algebra._K_cc_local.toarray() - Krc.T @ Psi)
    assert np.abs(s2.algebra.S.toarray() - S).max() <= 1e-12 * np.abs(S).max()


def _gather_dense(M) -> np.ndarray:
    from dolfinx_feti.feti.system import local_csr
    A = local_csr(M)
    return np.vstack(comm.allgather(A.toarray()))


def _gather_dense_csr(K, start: int, n: int) -> np.ndarray:
    K = sp.csr_matrix(K)
    rows = np.zeros((K.shape[0], n))
    rows[:, start:start + K.shape[1]] = K.toarray()
    return np.vstack(comm.allgather(rows))


def _dp_columns(step, n: int, nc: int) -> np.ndarray:
    """Global DP-layout index → index in [non-corner layout (n), corners (nc)]: rank 0 holds
    the corners after its own entries."""
    n0 = comm.bcast(step.parent.K.shape[0] if comm.rank == 0 else None)
    order = np.r_[np.arange(n0), n + np.arange(nc), np.arange(n0, n)]
    return order
