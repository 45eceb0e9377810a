"""Total BETI (``method="tbeti"``): the dual QP of boundary element subdomains.

The decomposition and the rows of B (Dirichlet rows, gluing, node-to-node, mortar and obstacle
contact, friction) are those of Total FETI; every subdomain's stiffness K_s is replaced by its
discrete Steklov–Poincaré operator S_s on its boundary nodes (:mod:`.steklov`), whose kernel is
the same (constants, rigid motions), and the dual layer — F = B S⁺ Bᵀ with S⁺ by fixing nodes,
G, homogenization, projection, MPRGP/SMALBE — takes it unchanged (Langer & Steinbach 2003;
Bouchala, Dostál & Sadowská 2008 for Total BETI of variational inequalities).

Boundary elements need the PDE's fundamental solution and no volume terms: the forms must be
:class:`~dolfinx_feti.Poisson` (no source) or :class:`~dolfinx_feti.Elasticity` (no body
force), in 2D, with P1 elements; loads are the fluxes and tractions on boundary groups.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI

from ..errors import InputError, collective
from ..fem.assembly import SubdomainData, block_diagonal
from ..fem.rigid import rigid_modes
from ..feti.chain import chain_qp
from ..feti.system import BlockSystem
from ..problem.contact_problem import ContactProblem
from ..timing import Timer
from .boundary import Boundaries, pair_keys, subdomain_boundaries
from .operators import lame_operators, laplace_operators
from .reduction import BoundaryReduction
from .steklov import interior_maps, steklov

#: Gauss points per facet for a load given as a function of x.
LOAD_POINTS = 4


def check_problem(problem: ContactProblem) -> None:
    """Refuse, by name, what Total BETI cannot take (before any heavy work)."""
    mesh, forms = problem.mesh, problem.forms
    if mesh.gdim != 2 or mesh.tdim != 2:
        raise InputError(f"method 'tbeti' (Total BETI) is implemented in 2D only; this mesh is "
                         f"{mesh.gdim}D (use 'tfeti')")
    if problem.degree != 1:
        raise InputError("method 'tbeti' uses piecewise linear boundary elements: degree 1, "
                         f"not {problem.degree}")
    describe = getattr(forms, "boundary_model", None)
    if describe is None:
        raise InputError("method 'tbeti' needs the PDE's fundamental solution: the forms must "
                         "be df.Elasticity or df.Poisson, not a forms function")
    model = describe()
    if model.kernel not in KERNELS:
        raise InputError(f"method 'tbeti' has no boundary operators for the fundamental "
                         f"solution {model.kernel!r} (it has {sorted(KERNELS)})")
    if model.volume_load is not None:
        raise InputError(f"method 'tbeti' takes no {model.volume_load} (boundary elements have "
                         f"no volume terms); load the bodies by {model.load_name} on boundary "
                         "groups, or use 'tfeti'")


def _laplace(bnd: Boundaries, c: dict, labels: list[str]) -> tuple[list, list, dict]:
    ops = laplace_operators(bnd.mesh)
    S = [k * steklov(op, lab) for k, op, lab in zip(c["k"], ops, labels, strict=True)]
    return ops, S, {}


def _lame(bnd: Boundaries, c: dict, labels: list[str]) -> tuple[list, list, dict]:
    ops = lame_operators(bnd.mesh, c["mu"], c["nu"])
    S = [steklov(op, lab) for op, lab in zip(ops, labels, strict=True)]
    return ops, S, {"mu": c["mu"], "nu": c["nu"]}


#: The boundary operators of each fundamental solution (``BoundaryModel.kernel``): given the
#: boundaries, the constants per local subdomain and the subdomains' labels, the operators,
#: the Steklov–Poincaré operators S_s and what the interior maps need.
KERNELS = {"laplace": _laplace, "lame": _lame}


def _constants(problem: ContactProblem, share) -> dict[str, np.ndarray]:
    """Per local subdomain, the constants of its body's fundamental solution."""
    bodies = [problem.mesh.body_names[share.dec.sub_body[s]] for s in share.dec.subs]
    return {name: np.array([float(per_body[b]) for b in bodies])
            for name, per_body in problem.forms.boundary_model().constants.items()}


def _evaluate(g, X: np.ndarray, bs: int, group: str) -> np.ndarray:
    """A load (number, vector or function of x) at points X (m, 2) → (m, bs)."""
    if callable(g):
        try:
            val = np.asarray(g(X.T.copy()), dtype=float)
        except Exception as err:
            raise InputError(f"method 'tbeti': the load on {group!r} is a function that "
                             f"failed on NumPy coordinates ({err}); TBETI evaluates loads as "
                             "functions of x[0], x[1] arrays (no UFL operators)") from None
        val = np.broadcast_to(val.reshape(bs, -1) if val.ndim else val, (bs, X.shape[0])).T
    else:
        val = np.broadcast_to(np.asarray(g, dtype=float).reshape(-1), (X.shape[0], bs))
    if not np.all(np.isfinite(val)):
        raise InputError(f"method 'tbeti': the load on {group!r} is not finite")
    return val


def load_vector(problem: ContactProblem, share, n_pairs: int) -> np.ndarray:
    """∫ g φ_i over the loaded facets of each local subdomain (P1, node-major)."""
    bs, loads = problem.value_size, problem.forms.boundary_model().loads
    f = np.zeros((n_pairs, bs))
    s_q, w_q = np.polynomial.legendre.leggauss(LOAD_POINTS)
    s_q, w_q = 0.5 * (s_q + 1), 0.5 * w_q
    x = share.points.x[:, :2]
    keys, npts = pair_keys(share), x.shape[0]
    for i, s in enumerate(share.dec.subs):  # per subdomain and loaded group: arrays of facets
        for group, g in loads.items():
            fac = share.facets.get(int(s), {}).get(group)
            if fac is None or fac.shape[0] == 0:
                continue
            p, q = x[fac[:, 0]], x[fac[:, 1]]
            L = np.linalg.norm(q - p, axis=1)
            X = (p[:, None, :] + s_q[None, :, None] * (q - p)[:, None, :]).reshape(-1, 2)
            val = _evaluate(g, X, bs, group).reshape(fac.shape[0], s_q.size, bs)
            w = (w_q[None, :] * L[:, None])[..., None]
            pairs = np.searchsorted(keys, i * npts + fac)
            np.add.at(f, pairs[:, 0], ((1 - s_q)[None, :, None] * val * w).sum(axis=1))
            np.add.at(f, pairs[:, 1], (s_q[None, :, None] * val * w).sum(axis=1))
    return f.ravel()


def boundary_operators(problem: ContactProblem, share, bnd: Boundaries
                       ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per local subdomain, S_s (boundary dofs) and the interior map (collective-free)."""
    labels = [f"subdomain {s}" for s in share.dec.subs]
    kernel = KERNELS[problem.forms.boundary_model().kernel]
    ops, S, interior = kernel(bnd, _constants(problem, share), labels)
    dec = share.dec
    inner = np.ones(dec.pair_node.size, dtype=bool)
    inner[bnd.pair] = False
    ipairs = np.flatnonzero(inner)
    isub = np.repeat(np.arange(dec.subs.size), np.diff(dec.pair_ptr))[ipairs]
    X = bnd.scaled(share.points.x[dec.pair_node[ipairs], :2], isub)
    E = interior_maps(bnd.mesh, ops, X, isub, problem.value_size, **interior)
    return S, E


def tbeti_chain(problem: ContactProblem, share, comm: MPI.Comm, timer: Timer
                ) -> tuple[BlockSystem, list, dict]:
    """The Total FETI system of the pairs' layout and the step to the boundary (collective).

    Returns:
        The parent system (all rows; what the solution is checked against), the list with the
        :class:`.reduction.BoundaryReduction` step, and sizes for the report.
    """
    check_problem(problem)
    bs, dec = problem.value_size, share.dec
    n_pairs = dec.pair_node.size
    with timer.phase("assembly"), collective(comm, "assembly"):
        bnd = subdomain_boundaries(share)
        S, E = boundary_operators(problem, share, bnd)
        f = load_vector(problem, share, n_pairs)
        comp = np.arange(bs)
        bdofs = (bs * bnd.pair[:, None] + comp).ravel()
        inner = np.ones(n_pairs, dtype=bool)
        inner[bnd.pair] = False
        idofs = (bs * np.flatnonzero(inner)[:, None] + comp).ravel()
        Kb = block_diagonal([sp.csr_matrix(s) for s in S])
        Kfull = _embed(Kb, bdofs, bs * n_pairs)
        x = share.points.x
        nodes = [dec.nodes(s) for s in dec.subs]
        off = bnd.mesh.node_off
        kernels_b = [rigid_modes(bnd.x[a:b], bs) for a, b in zip(off[:-1], off[1:], strict=True)]
        interior = block_diagonal([sp.csr_matrix(e) for e in E])
    sub_offset = np.concatenate([[0], np.cumsum(bs * dec.sub_size)]).astype(np.int64)
    local_node = np.repeat(np.concatenate(nodes), bs) if nodes else np.zeros(0, np.int64)
    body = [problem.mesh.body_names[dec.sub_body[s]] for s in dec.subs]
    data = SubdomainData(
        comm=comm, bs=bs, gdim=2, local_subs=dec.subs, sub_offset=sub_offset, K=Kfull, f=f,
        kernels=[rigid_modes(x[n], bs) for n in nodes],
        labels=[f"subdomain {s} of body {b!r}" for s, b in zip(dec.subs, body, strict=True)],
        bodies=body, dof_x=x[local_node], dof_comp=np.tile(np.arange(bs), local_node.size // bs),
        dof_node=np.repeat(share.pair_points, bs),
        dof_sub=np.repeat(dec.subs, bs * np.array([n.size for n in nodes], dtype=np.int64)))
    with timer.phase("constraints"):
        total = BlockSystem.from_rows(data, share.rows)
        step = BoundaryReduction(total, bdofs, idofs, Kb, bs * off, kernels_b, interior)
    n_b = comm.allreduce(int(bdofs.size))
    return total, [step], {"boundary_dofs": n_b}


def _embed(Kb: sp.csr_matrix, dofs: np.ndarray, n: int) -> sp.csr_matrix:
    """Kb (on ``dofs``) as an n × n matrix zero elsewhere."""
    coo = Kb.tocoo()
    return sp.csr_matrix((coo.data, (dofs[coo.row], dofs[coo.col])), shape=(n, n))


def tbeti_qp(problem: ContactProblem, share, comm: MPI.Comm, factor, norm_rtol: float,
             timer: Timer, mortar: list, fdata, surface=None):
    """The dual QP of Total BETI on a rank's share (what ``dual.qp_of_share`` gives FETI)."""
    total, steps, info = tbeti_chain(problem, share, comm, timer)
    qp = chain_qp(total, steps, method="tbeti", factor=factor, norm_rtol=norm_rtol,
                  timer=timer, dec=share.dec, rows=share.rows, info=info)
    qp.mortar, qp.friction, qp.share, qp.surface = mortar, fdata, share, surface
    qp.copy_weight = 1.0 / np.repeat(share.dec.multiplicity, problem.value_size)
    return qp


__all__ = ["KERNELS", "check_problem", "load_vector", "tbeti_chain", "tbeti_qp"]
