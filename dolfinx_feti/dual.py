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

from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .constraints import Kind, build_rows
from .constraints.dirichlet import dirichlet_mask
from .constraints.friction import friction_data
from .errors import InputError, collective
from .fem.assembly import assemble_subdomains
from .fem.corners import choose_corners, floating_motions, primal_components
from .feti.corners import EliminateCorners
from .feti.dualize import Dualization
from .feti.system import INEQUALITY, BlockSystem
from .feti.transforms import EliminateDirichlet
from .mesh.decompose import decompose
from .problem import ContactProblem
from .qp import (
    Projector,
    RowBlockConstraint,
    estimate_norm,
    homogenize,
    orthonormalize,
    projected_operator,
)
from .share import share_out
from .timing import Timer

#: A load component along a free rigid motion above this, relative to the size of the load
#: (:func:`_unbalanced`), means the load cannot be balanced (e ∉ Im G).
BALANCE_TOL = 1e-8

#: FETI-DP: whether nodes of contact (and other non-gluing) rows may be vertices (corners).
CORNERS_ON_CONTACT = True
#: FETI-DP in 3D: the edges (interface nodes outside the two-subdomain faces) primal, whole.
#: Vertices alone leave F badly conditioned in 3D: on the rigid sphere S2 (bench/
#: hertz3d_fetidp.py) 328 / 115 F-mults with Parts(4) / Parts(16) against 52 / 47 with edges.
CORNER_EDGES = True

#: The FETI methods.
METHODS = ("tfeti", "feti1", "fetidp")


@dataclass
class DualQP:
    """The homogenized, projected dual QP of one problem and the FETI objects behind it.

    Attributes:
        feti: The dual operators (``F``, ``B``, ``d``, ``e``, kernels, primal recovery) of the
            last primal problem of the chain.
        system: The Total FETI system of the problem (all rows; what the solution is checked
            against).
        steps: The primal transforms (eliminate Dirichlet, eliminate corners), in order.
        method: ``"tfeti"``, ``"feti1"`` or ``"fetidp"``.
        dec: This rank's part of the decomposition (:class:`.share.LocalDecomposition`).
        rows: This rank's rows and the contact rows (:class:`.share.RankRows`).
        row_index: Local indices, into the rows of ``system`` owned by this rank, of the rows
            of this QP.
        constraint: ``G̃`` with orthonormal rows (:class:`.qp.RowBlockConstraint`).
        projector: ``P = I − G̃ᵀG̃``.
        A: ``P F P``.
        b: ``P (d − F λ̂)``.
        lb: Lower bound of ``x``: ``−λ̂`` on the inequality rows, ``−inf`` elsewhere.
        lam_hat: The particular solution λ̂ of ``G λ = e``.
        ineq: Local mask of the inequality rows.
        norm_A: Lanczos estimate of ``||P F P||``.
        b_noise: Round-off level of ``b`` (a floor for absolute tolerances).
        warnings: Notes for the report (e.g. an unloaded rigid motion nothing fixes).
        info: Sizes of the method (e.g. FETI-DP's corners).
        mortar: What the contact search found for each mortar condition
            (:class:`.constraints.mortar_rows.MortarInfo`).
        copy_weight: Per local entry of ``system``'s primal vector, 1 / the number of subdomain
            copies of its node (None: all ones).
        friction: The friction rows (:class:`.constraints.friction.FrictionData`) or None.
        share: What this rank holds of the problem (:class:`.share.RankShare`).
        surface: On a distributed mesh with contact, the cells along the contact surfaces
            gathered on rank 0 (:class:`.share_distributed.Surface`; None elsewhere).
    """

    feti: Dualization
    system: BlockSystem
    steps: list
    method: str
    dec: object
    rows: object
    row_index: np.ndarray
    constraint: object
    projector: Projector
    A: PETSc.Mat
    b: PETSc.Vec
    lb: PETSc.Vec
    lam_hat: PETSc.Vec
    ineq: np.ndarray
    norm_A: float
    b_noise: float
    warnings: list[str]
    info: dict = field(default_factory=dict)
    mortar: list = field(default_factory=list)
    copy_weight: np.ndarray | None = None
    friction: object = None
    share: object = None
    surface: object = None

    def start(self, out: PETSc.Vec | None = None) -> PETSc.Vec:
        """A feasible start ``x = max(0, lb)`` (λ = λ̂ where that is feasible).

        Written into ``out`` if given, else into a new Vec.
        """
        x = self.b.duplicate() if out is None else out
        x.array[:] = np.maximum(0.0, self.lb.array_r)
        return x

    def objective(self, x: PETSc.Vec) -> float:
        """``1/2 xᵀ A x − bᵀ x`` (one multiplication by ``A``; collective)."""
        y = x.duplicate()
        self.A.mult(x, y)
        value = 0.5 * y.dot(x) - self.b.dot(x)
        y.destroy()
        return float(value)

    def multipliers(self, x: PETSc.Vec) -> PETSc.Vec:
        """λ = λ̂ + x."""
        lam = x.copy()
        lam.axpy(1.0, self.lam_hat)
        return lam

    @property
    def primal(self):
        """The primal problem that was dualized (the last of the chain)."""
        return self.feti.primal

    def free_motions(self, N: np.ndarray) -> np.ndarray:
        """The motions R n_k (columns of ``N``: coarse vectors) in the layout of ``system``."""
        Z = self.feti.R @ N
        for step in reversed(self.steps):
            Z = step.map_primal(Z)
        return Z

    def map_back(self, lam: PETSc.Vec, alpha: np.ndarray) -> tuple[PETSc.Vec, PETSc.Vec]:
        """(u, λ) of the original problem from the multipliers λ of this QP and α (collective).

        ``u`` is the primal solution subdomain by subdomain (Dirichlet values included), ``λ``
        the multipliers of all rows of ``system`` (those a transform removed recovered from
        equilibrium).
        """
        u = self.feti.primal_solution(lam, alpha)
        lam = lam.copy()
        for step in reversed(self.steps):
            u_new, lam_new = step.map_back(u, lam)
            u.destroy()
            lam.destroy()
            u, lam = u_new, lam_new
        return u, lam


def dual_qp(problem: ContactProblem, comm: MPI.Comm = MPI.COMM_WORLD, *,
            factor: str | None = None, norm_rtol: float = 1e-4,
            timer: Timer | None = None, method: str = "tfeti",
            dual_operator: str = "implicit") -> DualQP:
    """Decompose, assemble and dualize ``problem``; homogenize and project its dual QP.

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
    if method not in (*METHODS, "auto"):
        raise InputError(f"method must be one of {(*METHODS, 'auto')}, got {method!r}")
    timer = Timer() if timer is None else timer
    bs = problem.value_size
    held = problem.mesh.root_only
    if held is not None and MPI.Comm.Compare(held, comm) not in (MPI.IDENT, MPI.CONGRUENT):
        raise InputError("the mesh's arrays are held by rank 0 of its communicator only "
                         "(read_gmsh(..., replicate=False)): solve on that communicator")
    if problem.mesh.part is not None:
        return _dual_qp_distributed(problem, comm, factor, norm_rtol, timer, method,
                                    dual_operator)
    dec = rows = extra = common = None
    # Rank 0 (the rank that read the mesh) decomposes and builds the rows from the global
    # arrays; every rank then keeps only its share (:mod:`.share`).
    with timer.phase("decomposition"), collective(comm, "decomposition"):
        if comm.rank == 0:
            dec = decompose(problem.mesh, problem.decomposition, comm.size, problem.dof_points)
    with timer.phase("constraints"):
        with collective(comm, "constraints"):
            if comm.rank == 0:
                mortar: list = []
                rows = build_rows(problem, dec, mortar)
                if method == "auto":
                    method = choose_method(problem, dec, rows)
                if method == "fetidp":
                    extra = _fetidp_parts(problem, dec, rows, comm.size)
                common = (method, mortar)
        fdata = None
        with collective(comm, "friction"):
            if comm.rank == 0:
                fdata = friction_data(problem, rows)
        method, mortar = comm.bcast(common, root=0)
        fdata = comm.bcast(fdata, root=0)
    with timer.phase("distribution"):
        share = share_out(problem.mesh, problem.dof_points if comm.rank == 0 else None, dec,
                          rows, bs, comm, extra)
        del dec, rows
    return _qp_of_share(problem, share, comm, method, factor, norm_rtol, timer, mortar, fdata,
                        dual_operator=dual_operator)


def _qp_of_share(problem: ContactProblem, share, comm: MPI.Comm, method: str, factor,
                 norm_rtol: float, timer: Timer, mortar: list, fdata, surface=None,
                 dual_operator: str = "implicit") -> DualQP:
    """Assemble this rank's subdomains and chain the method's transforms (collective)."""
    data = assemble_subdomains(problem, share, comm, timer)
    info: dict = {}
    with timer.phase("constraints"):
        total = BlockSystem.from_rows(data, share.rows)
        steps: list = []
        if method in ("feti1", "fetidp"):
            steps.append(EliminateDirichlet(total, share.rows.own.kind == Kind.DIRICHLET))
        if method == "fetidp":
            part = share.extra
            steps.append(EliminateCorners(steps[-1].child, part["corners"], part["count"],
                                          part["modes"], part["bodies"]))
            info = part["info"]
    qp = chain_qp(total, steps, method=method, factor=factor, norm_rtol=norm_rtol,
                  timer=timer, dec=share.dec, rows=share.rows, info=info,
                  dual_operator=dual_operator)
    qp.mortar, qp.friction, qp.share, qp.surface = mortar, fdata, share, surface
    qp.copy_weight = 1.0 / np.repeat(share.dec.multiplicity, problem.value_size)
    return qp


def _dual_qp_distributed(problem: ContactProblem, comm: MPI.Comm, factor, norm_rtol: float,
                         timer: Timer, method: str, dual_operator: str = "implicit") -> DualQP:
    """:func:`dual_qp` of a problem on a distributed mesh: every rank builds its own share."""
    from .fem.distributed_corners import fetidp_share
    from .share_distributed import share_from_parts, surface_friction

    if method in ("fetidp", "auto") and not CORNERS_ON_CONTACT:
        raise InputError("FETI-DP on a distributed mesh takes the corners on contact nodes "
                         "too (dual.CORNERS_ON_CONTACT); read the mesh with distribute=False")
    share, surface, mortar = share_from_parts(problem, comm, timer)
    with timer.phase("constraints"):
        auto = method == "auto"
        if auto:  # choose_method's rule, its first branch here
            glued = comm.allreduce(bool(np.any(share.rows.own.kind == Kind.GLUE)), op=MPI.LOR)
            method = "fetidp" if glued else "feti1"
        if method == "fetidp":  # the rule's last branch: "tfeti" if a primal component floats
            method, share.extra = fetidp_share(
                share, problem.value_size, problem.mesh.body_names, comm, auto=auto,
                edges=CORNER_EDGES and problem.mesh.gdim == 3)
    fdata = None
    if any(getattr(c, "friction", None) is not None for c in problem.contact):
        with collective(comm, "friction"):
            if comm.rank == 0:  # from the contact rows, on the cells along the surfaces
                fdata = surface_friction(surface, share.rows)
        fdata = comm.bcast(fdata, root=0)
    return _qp_of_share(problem, share, comm, method, factor, norm_rtol, timer, mortar, fdata,
                        surface, dual_operator)


def _fetidp_parts(problem: ContactProblem, dec, rows, size: int) -> list[dict]:
    """FETI-DP's corners and floating motions, for the dofs of each rank (on rank 0)."""
    mesh, bs = problem.mesh, problem.value_size
    fixed, _ = dirichlet_mask(problem, mesh)
    avoid = None if CORNERS_ON_CONTACT else np.unique(np.r_[
        rows.e_node[~np.isin(rows.kind[rows.e_row], (Kind.GLUE, Kind.DIRICHLET))]])
    x = problem.dof_points.x
    corners = choose_corners(mesh, dec, fixed, bs, avoid, x,
                             edges=CORNER_EDGES and mesh.gdim == 3)
    dofs = []
    for r in range(size):
        pairs = dec.rank_pairs(r)
        node = np.repeat(dec.pair_node[pairs], bs)
        dofs.append((node, np.tile(np.arange(bs), node.size // bs),
                     np.repeat(dec.pair_sub[pairs], bs)))
    modes, bodies = floating_motions(mesh, dec, rows, fixed, bs, dofs, x,
                                     primal_components(mesh, dec))
    info = {"corner_nodes": int(corners.nodes.size), "vertices": corners.vertices,
            "corner_dofs": corners.count}
    return [{"corners": corners.local(node, comp), "count": corners.count, "modes": Z,
             "bodies": bodies, "info": info} for (node, comp, _), Z in zip(dofs, modes,
                                                                          strict=True)]


def choose_method(problem: ContactProblem, dec, rows) -> str:
    """The method ``method="auto"`` picks (the rule of docs/solvers.md).

    Derived from ``bench/method_choice.py`` (F-multiplications of every method on problems with
    and without floating bodies, 2D and 3D, few and many subdomains):

    - every subdomain a whole body (no gluing rows): ``"feti1"``. FETI-DP would find no
      corners, and FETI-1's dual lacks TFETI's Dirichlet rows: 1.2–3× fewer F-mults;
    - no body floats (every body's rigid motions stopped by its Dirichlet conditions; a body
      held only through a mortar tie floats, as it does in K̃): ``"fetidp"``. K̃ is
      definite, the contact problem is bound-constrained and MPRGP runs alone: 3–5× fewer
      F-mults on held B1 and the 3D rigid sphere; the one measured exception, B4 (a block
      sheared by its prescribed top), takes 1.6–2.5× more than TFETI;
    - else ``"tfeti"``: the fewest F-mults or within 30 % on the measured floating cases (B1,
      3D blocks), the one exception 2D Hertz (FETI-DP 20–45 % fewer).

    Reads the global decomposition and rows (on the rank that holds them).
    """
    if not np.any(rows.kind == Kind.GLUE):
        return "feti1"
    fixed, _ = dirichlet_mask(problem, problem.mesh)
    none = np.zeros(0, dtype=np.int64)
    _, free = floating_motions(problem.mesh, dec, rows, fixed, problem.value_size,
                               [(none, none, none)], problem.dof_points.x,
                               primal_components(problem.mesh, dec))
    return "tfeti" if free else "fetidp"


def chain_qp(total: BlockSystem, steps: list, *, method: str = "tfeti",
             factor: str | None = None, norm_rtol: float = 1e-4, timer: Timer | None = None,
             dec=None, rows=None, info: dict | None = None,
             dual_operator: str = "implicit") -> DualQP:
    """Factor the last system of a chain of primal transforms, dualize, homogenize, project.

    Args:
        total: The first system of the chain (Total FETI form: every row).
        steps: The primal transforms applied to it, in order (each ``steps[i].parent`` is the
            previous one's ``child``); may be empty.
        method: The name of the method (for the report).
        factor: Sparse Cholesky package.
        norm_rtol: Relative tolerance of the Lanczos estimate of ``||P F P||``.
        timer: Phase timers (a new one if None).
        dec: The decomposition behind ``total``, if any.
        rows: The constraint rows behind ``total``, if any.
        info: Sizes of the method for the report.
        dual_operator: How F is applied (:class:`.feti.dualize.Dualization`).
    """
    timer = Timer() if timer is None else timer
    comm = total.comm
    system = steps[-1].child if steps else total
    row_index = np.arange(total.dual_size[0])
    for step in steps:
        row_index = row_index[step.kept]
    with timer.phase("factorization"):
        system.factorize(factor, site="factorization")  # guarded inside (collective phases)
    with timer.phase("dual operators"):
        feti = Dualization(system, dual_operator)
    ineq = system.types == INEQUALITY
    with timer.phase("coarse problem"):
        ocon = orthonormalize(RowBlockConstraint(feti.Gt_local, comm), rhs=feti.e)
        warnings = _check_balance(ocon, feti)
        lam_hat = feti.d.duplicate()
        homogenize(ocon, lam_hat)
        Flh = feti.d.duplicate()
        feti.F.mult(lam_hat, Flh)
        b_noise = 1e3 * np.finfo(float).eps * (feti.d.norm() + Flh.norm())
        Flh.aypx(-1.0, feti.d)  # d − F λ̂
        projector = Projector(ocon)
        b = Flh.duplicate()
        projector.apply(Flh, b)
        Flh.destroy()
        A = projected_operator(feti.F, ocon)
        norm = estimate_norm(A, b, rtol=norm_rtol)
        lb = b.duplicate()
        lb.array[:] = np.where(ineq, -lam_hat.array_r, -np.inf)
    return DualQP(feti=feti, system=total, steps=steps, method=method, dec=dec, rows=rows,
                  row_index=row_index, constraint=ocon, projector=projector, A=A, b=b, lb=lb,
                  lam_hat=lam_hat, ineq=ineq, norm_A=float(norm.value),
                  b_noise=float(b_noise), warnings=warnings, info=info or {})


def _check_balance(ocon, feti: Dualization) -> list[str]:
    """Refuse a load that the constraints cannot balance; note undetermined motions."""
    N = ocon.null_space
    if N.shape[1] == 0:
        return []
    weight = np.abs(N).max(axis=1)
    cols = np.flatnonzero(weight > 1e-6 * weight.max())
    bodies = sorted({feti.kernel_bodies[i] for i in cols})
    ratio = _unbalanced(N, feti)
    if ratio > BALANCE_TOL:
        raise InputError(
            f"the load cannot be balanced: bodies {bodies} can move rigidly without meeting any "
            "Dirichlet or contact condition, and the load has a component along that motion "
            f"(relative size {ratio:.2e}), so the problem has no solution (e is "
            "not in Im G). Add a Dirichlet condition or a contact surface that stops it, or "
            "remove that load component")
    return [f"{N.shape[1]} rigid motion(s) of bodies {bodies} are not fixed by any condition "
            "(and not loaded); of the solutions, which differ by these motions, the one "
            "returned is orthogonal to them (zero nodal mean along each, in the nodal l2 inner "
            "product): the same for every decomposition and number of ranks"]


def _unbalanced(N: np.ndarray, feti: Dualization) -> float:
    """The largest load component along a free rigid motion, relative to the load's size.

    ``|n_kᵀ e|`` against ``|n_k|ᵀ ẽ + ||e||`` with ``ẽ = |R|ᵀ |f|`` (the size of the terms
    summed in e = Rᵀf; ``||e||`` for the round-off of n_k itself): a self-equilibrated load
    has ``n_kᵀ e`` at round-off of ẽ, not of ``||e||``, which is itself round-off then.
    """
    e_abs = feti.comm.allreduce(abs(feti.R).T @ np.abs(feti.f.array_r), op=MPI.SUM)
    scale = np.abs(N).T @ e_abs + np.linalg.norm(feti.e)
    along = np.abs(N.T @ feti.e)
    return float(np.max(along / np.maximum(scale, 1e-300), initial=0.0))


__all__ = ["METHODS", "DualQP", "chain_qp", "dual_qp"]
