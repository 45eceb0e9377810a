"""The dual QP of a FETI method, as a plain QP that any bound-constrained solver can take.

The chain of transforms (:mod:`dolfinx_feti.feti`) for each method:

- ``"tfeti"`` (Total FETI): dualize → homogenize → project; every subdomain floats, Dirichlet
  conditions are rows of B;
- ``"feti1"``: eliminate Dirichlet conditions → dualize → homogenize → project; only floating
  subdomains have a kernel;
- ``"fetidp"``: eliminate Dirichlet conditions → eliminate corners → dualize, and homogenize →
  project only when a body floats (else there is no equality constraint on the dual).

``"auto"`` picks one of them by :func:`choose_method` once the rows are known.

After it the problem is

    min 1/2 xᵀ A x − bᵀ x   s.t.   x ≥ lb on the inequality rows,   G̃ x = 0,

with ``A = P F P`` (a PETSc shell Mat), ``b = P (d − F λ̂)``, ``lb = −λ̂`` on the inequality
rows (``−inf`` elsewhere) and ``G̃`` the orthonormalized natural coarse space (no rows when
nothing floats). :func:`solve` runs our solvers on it; :func:`dual_qp` hands the same objects
to anyone else (e.g. PETSc TAO in ``bench/peers``), so that solvers are compared on one
problem; :meth:`DualQP.map_back` turns a dual solution into the primal one of the original
problem.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from ..constraints import Kind
from ..errors import InputError, collective
from ..fem.assembly import assemble_subdomains
from ..feti.chain import DualQP, chain_qp
from ..feti.corners import EliminateCorners
from ..feti.system import BlockSystem
from ..feti.transforms import EliminateDirichlet
from ..problem.contact_problem import ContactProblem
from ..timing import Timer
from .method_rule import method_by_time
from .whole_mesh import as_blocks

#: FETI-DP: whether nodes of contact (and other non-gluing) rows may be vertices (corners).
CORNERS_ON_CONTACT = True
#: FETI-DP in 3D: the edges (interface nodes outside the two-subdomain faces) primal, whole.
#: Vertices alone leave F badly conditioned in 3D: on the rigid sphere S2 (bench/
#: hertz3d_fetidp.py) 328 / 115 F-mults with Parts(4) / Parts(16) against 52 / 47 with edges.
CORNER_EDGES = True

#: The FETI methods.
METHODS = ("tfeti", "feti1", "fetidp")


@dataclass
class SharedProblem:
    """What the set-up hands each rank before assembly: its share and what the rows found.

    Attributes:
        share: This rank's share (:class:`.share.RankShare`: cells, dof points, rows).
        method: The method (``"auto"`` resolved).
        mortar: What the contact search found for each mortar condition.
        friction: The friction rows (:class:`.constraints.friction.FrictionData`) or None.
        surface: On a distributed mesh with contact, the cells along the contact surfaces
            gathered on rank 0; None elsewhere.
        comm: The ranks.
    """

    share: object
    method: str
    mortar: list
    friction: object = None
    surface: object = None
    comm: MPI.Comm | None = None


def dual_qp(problem: ContactProblem, comm: MPI.Comm = MPI.COMM_WORLD, *,
            factor: str | None = None, norm_rtol: float = 1e-4,
            timer: Timer | None = None, method: str = "tfeti",
            dual_operator: str = "implicit") -> DualQP:
    """Decompose, assemble and dualize ``problem``; homogenize and project its dual QP.

    The three stages are :func:`share_problem`, :func:`~.fem.assembly.assemble_subdomains`
    and :func:`qp_of_share`; :class:`~dolfinx_feti.FetiSolver` keeps what each returns.

    Args:
        problem: The contact problem.
        comm: The ranks to spread the subdomains over.
        factor: Sparse Cholesky package for K⁺ (see :class:`.SolverOptions`).
        norm_rtol: Relative tolerance of the Lanczos estimate of ``||P F P||``.
        timer: Records the phases ``decomposition``, ``constraints``, ``distribution`` (the
            shares handed out), ``assembly``, ``factorization``, ``dual operators`` and
            ``coarse problem``; a new one if None.
        method: ``"tfeti"``, ``"feti1"`` or ``"fetidp"`` (see the module docstring).
        dual_operator: How F is applied (:class:`.feti.dualize.Dualization`).

    Returns:
        The dual QP (collective objects on ``comm``).

    Raises:
        InputError: When the load on a floating body cannot be balanced (``e ∉ Im G``).
    """
    timer = Timer() if timer is None else timer
    shared = share_problem(problem, comm, method, timer)
    data = None if shared.method == "tbeti" else \
        assemble_subdomains(problem, shared.share, comm, timer)
    return qp_of_share(problem, shared, data, factor=factor, norm_rtol=norm_rtol, timer=timer,
                       dual_operator=dual_operator)


def share_problem(problem: ContactProblem, comm: MPI.Comm, method: str, timer: Timer
                  ) -> SharedProblem:
    """Decompose ``problem``, build its rows and give every rank its share (collective)."""
    if method not in (*METHODS, "auto", "tbeti"):
        raise InputError(f"method must be one of {(*METHODS, 'auto', 'tbeti')}, got {method!r}")
    if method == "tbeti":  # Total BETI (dolfinx_feti/bem): refuse what it cannot take, early
        from ..bem.tbeti import check_problem
        check_problem(problem)
    held = problem.mesh.root_only
    if held is not None and MPI.Comm.Compare(held, comm) not in (MPI.IDENT, MPI.CONGRUENT):
        raise InputError("the mesh's arrays are held by rank 0 of its communicator only "
                         "(read_gmsh(..., replicate=False)): solve on that communicator")
    whole = None
    if problem.mesh.part is None:  # a whole mesh: its blocks are the input of the pipeline
        problem, whole = as_blocks(problem, comm, timer)
    return _share_distributed(problem, comm, timer, method, whole)


def qp_of_share(problem: ContactProblem, shared: SharedProblem, data, *,
                factor: str | None = None, norm_rtol: float = 1e-4,
                timer: Timer | None = None, factors_of: DualQP | None = None,
                dual_operator: str = "implicit", nearby: DualQP | None = None) -> DualQP:
    """Chain the method's transforms on this rank's assembled subdomains (collective).

    ``factors_of``: a dual QP of the same subdomain matrices (other rows) whose factorizations
    are taken over instead of factoring again, with everything else of K alone
    (:func:`method_steps`) and, for an unchanged load, K⁺f. ``nearby`` (default
    ``factors_of``): a dual QP on the same rows' layout whose ‖P F P‖ estimate's Ritz vector
    starts this one's. Total BETI (``data`` None) builds its own boundary element subdomains
    (:mod:`.bem.tbeti`).
    """
    nearby = factors_of if nearby is None else nearby
    timer = Timer() if timer is None else timer
    if shared.method == "tbeti":
        from ..bem.tbeti import tbeti_qp
        return tbeti_qp(problem, shared.share, shared.comm, factor, norm_rtol, timer,
                        shared.mortar, shared.friction, shared.surface)
    with timer.phase("constraints"):
        total = BlockSystem.from_rows(data, shared.share.rows)
        if factors_of is not None:  # the same K: what depends on it alone is taken over
            steps = method_steps(total, shared, like=factors_of.steps)
            last = steps[-1] if steps else total  # the last factored object of the chain
            last.adopt_factors(factors_of.steps[-1] if factors_of.steps else factors_of.system)
        else:
            steps = method_steps(total, shared)
    qp = chain_qp(total, steps, method=shared.method, factor=factor,
                  norm_rtol=norm_rtol, timer=timer, dec=shared.share.dec,
                  rows=shared.share.rows,
                  info=shared.share.extra["info"] if shared.method == "fetidp" else None,
                  dual_operator=dual_operator,
                  norm_guess=None if nearby is None else nearby.proj.top,
                  same_load=None if factors_of is None else factors_of.feti)
    qp.mortar, qp.friction = shared.mortar, shared.friction
    qp.share, qp.surface = shared.share, shared.surface
    qp.copy_weight = 1.0 / np.repeat(shared.share.dec.multiplicity, problem.value_size)
    return qp


def method_steps(total: BlockSystem, shared: SharedProblem, like: list | None = None) -> list:
    """The primal transforms of the method, applied to ``total`` (the first of the chain).

    ``like``: the steps of a chain of the same K with other rows (a row update): what they
    hold of K alone (the held K, FETI-DP's corner blocks and factors) is shared, only what
    depends on the rows is built.
    """
    steps: list = []
    if shared.method in ("feti1", "fetidp"):
        steps.append(EliminateDirichlet(total, shared.share.rows.own.kind == Kind.DIRICHLET,
                                        like=like[0] if like else None))
    if shared.method == "fetidp":
        if like:
            steps.append(like[1].with_rows(steps[-1].child))
        else:
            part = shared.share.extra
            steps.append(EliminateCorners(steps[-1].child, part["corners"], part["count"],
                                          part["modes"], part["bodies"]))
    return steps


def _share_distributed(problem: ContactProblem, comm: MPI.Comm, timer: Timer, method: str,
                       whole=None) -> SharedProblem:
    """:func:`share_problem` on blocks of the mesh: every rank builds its own share."""
    from .share_distributed import share_from_parts, surface_friction

    if method in ("fetidp", "auto") and not CORNERS_ON_CONTACT:
        raise InputError("FETI-DP takes the corners on contact nodes too "
                         "(CORNERS_ON_CONTACT)")
    share, surface, mortar = share_from_parts(problem, comm, timer, whole)
    with timer.phase("constraints"):
        method = choose_method(problem, share, comm, method)
    fdata = None
    if any(getattr(c, "friction", None) is not None for c in problem.contact):
        with collective(comm, "friction"):
            if comm.rank == 0:  # from the contact rows, on the cells along the surfaces
                fdata = surface_friction(surface, share.rows)
        fdata = comm.bcast(fdata, root=0)
    return SharedProblem(share, method, mortar, fdata, surface, comm)


def choose_method(problem: ContactProblem, share, comm: MPI.Comm, method: str) -> str:
    """The method, ``"auto"`` resolved by the rule of docs/solvers.md (collective).

    For FETI-DP (asked for, or chosen) the share gets its corners and floating motions
    (``share.extra``, :func:`~.fem.distributed_corners.fetidp_share`). The rule is
    :func:`.method_rule.method_by_time` (measured wall time): FETI-1 without gluing rows or
    with few subdomains per body, FETI-DP with many.
    """
    from ..fem.distributed_corners import fetidp_share

    if method == "auto":
        glued = comm.allreduce(bool(np.any(share.rows.own.kind == Kind.GLUE)), op=MPI.LOR)
        method = method_by_time(glued, share.dec.num_subdomains, len(problem.mesh.body_names),
                                problem.mesh.gdim)
    if method == "fetidp":
        method, share.extra = fetidp_share(
            share, problem.value_size, problem.mesh.body_names, comm,
            edges=CORNER_EDGES and problem.mesh.gdim == 3)
    return method


__all__ = ["METHODS", "DualQP", "SharedProblem", "chain_qp", "choose_method", "dual_qp",
           "qp_of_share", "share_problem"]
