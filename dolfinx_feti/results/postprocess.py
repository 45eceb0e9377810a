"""What comes after a solve: derived fields, the pressure plot, NumPy output, run metadata.

- :func:`von_mises`: the von Mises stress per cell of a P1 displacement on simplices, from
  nodal arrays (exact: the strain is constant in each cell; in 2D with the plane-strain
  σ_zz = λ tr ε).
- :func:`output_functions`: the cell fields that :meth:`Solution.write_xdmf` writes besides
  the displacement and the contact pressure: ``subdomain`` (the subdomain of each cell) and,
  the fields the forms name (for :class:`~dolfinx_feti.Elasticity`, ``von_mises`` at the cell
  midpoints, computed in UFL from ``solution.u``, any element), piecewise constant (DG0).
- :func:`pressure_profile` / :func:`plot_pressure`: the contact pressure along a contact
  surface (against x, y, z or, in 2D, the arc length) and its PNG plot.
- :func:`save_nodal_values`: the solution as NumPy arrays in the mesh's node order (``.npz``).
- :func:`versions`: the versions of DOLFINx, PETSc, petsc4py, NumPy and this package.

Files are written atomically: to a temporary name in the target folder, renamed when complete.
"""

from __future__ import annotations

import functools
import os
import tempfile
import threading
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .. import compat
from ..errors import InputError
from ..mesh.data import MeshData


@contextmanager
def atomic_file(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it to ``path`` if the block succeeds.

    On an exception the temporary file is removed and ``path`` is left as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes the file private: give it the usual mode
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


# ------------------------------------------------------------------------------------------
# Cell fields
# ------------------------------------------------------------------------------------------


def _per_cell(value: float | Mapping[str, float], mesh: MeshData) -> np.ndarray:
    if isinstance(value, Mapping):
        table = np.array([float(value[b]) for b in mesh.body_names])
        return table[mesh.cell_body]
    return np.full(mesh.cells.shape[0], float(value))


def von_mises(mesh: MeshData, u: np.ndarray, E, nu) -> np.ndarray:
    """The von Mises stress in each cell of a P1 displacement field.

    Args:
        mesh: The mesh (of simplices).
        u: Nodal displacements, shape (N, gdim) (for a degree-2 solution: its vertex rows,
            which give the P1 interpolant's stress).
        E: Young's modulus: a number or body name → number.
        nu: Poisson's ratio: a number or body name → number.

    Returns:
        One value per cell, sqrt(3/2 s:s) with s the deviator of the 3×3 stress (plane strain
        in 2D: σ_zz = λ tr ε).
    """
    if mesh.cell_type not in ("triangle", "tetrahedron"):
        raise InputError(f"von_mises from nodal arrays needs simplices, not {mesh.cell_type} "
                         "cells: use output_functions (UFL) instead")
    x, cells, d = mesh.x, mesh.cells, mesh.gdim
    G = x[cells[:, 1:]] - x[cells[:, :1]]  # (C, d, d): edge vectors from the first vertex
    dU = u[cells[:, 1:]] - u[cells[:, :1]]  # (C, d, d)
    grad = np.linalg.solve(G, dU).transpose(0, 2, 1)  # grad[c, i, j] = du_i/dx_j
    eps = 0.5 * (grad + grad.transpose(0, 2, 1))
    Ec, nuc = _per_cell(E, mesh), _per_cell(nu, mesh)
    mu = Ec / (2 * (1 + nuc))
    lmbda = Ec * nuc / ((1 + nuc) * (1 - 2 * nuc))
    tr = np.trace(eps, axis1=1, axis2=2)
    sigma = np.zeros((cells.shape[0], 3, 3))
    sigma[:, :d, :d] = 2 * mu[:, None, None] * eps + (lmbda * tr)[:, None, None] * np.eye(d)
    if d == 2:
        sigma[:, 2, 2] = lmbda * tr
    s = sigma - np.trace(sigma, axis1=1, axis2=2)[:, None, None] / 3 * np.eye(3)
    return np.sqrt(1.5 * np.einsum("cij,cij->c", s, s))


def output_functions(solution) -> list:
    """DG0 Functions for the XDMF output besides the displacement and the contact pressure.

    ``subdomain`` (the subdomain index of each cell) always, and the fields the forms name
    (their ``output_fields``: ``von_mises`` for :class:`~dolfinx_feti.Elasticity`; a forms
    function's material law is unknown, so none). The von Mises stress is interpolated on
    each rank's own cells from the distributed ``solution.u``: no rank holds the whole
    mesh's displacements.
    """
    from .output import cell_function

    mesh, comm = solution.problem.mesh, solution.comm
    msh = solution.u.function_space.mesh
    share = solution.share  # the values of this rank's own cells go where the output has them

    def cellwise(values, name):
        return cell_function(mesh, values, name, comm, msh, cells=share.cell_ids,
                             num_cells=share.num_cells)

    out = [cellwise(share.dec.cell_sub.astype(float), "subdomain")]
    fields = getattr(solution.problem.forms, "output_fields", None)
    if fields is not None:  # the forms know their derived fields (a forms function: none)
        for name, expr in fields(solution.u, lambda v: cellwise(_per_cell(v, share.mesh),
                                                                 "coefficient")).items():
            f = cellwise(np.zeros(share.cell_ids.size), name)
            compat.interpolate_expression(f, expr)
            out.append(f)
    return out


# ------------------------------------------------------------------------------------------
# Contact pressure along a surface
# ------------------------------------------------------------------------------------------


def surface_arclength(mesh: MeshData, group: str) -> tuple[np.ndarray, np.ndarray]:
    """The nodes of a 2D boundary group in order along it, and their arc length.

    The walk starts at the end with the smaller (x, y); a closed curve starts at its node with
    the smallest (x, y).

    Raises:
        InputError: If the mesh is not 2D or the group is not one simple curve.
    """
    if mesh.gdim != 2:
        raise InputError(f"the arc length along a surface needs a 2D mesh (this one is "
                         f"{mesh.gdim}D): use x, y or z")
    edges = mesh.facets(group)
    nodes, inverse = np.unique(edges, return_inverse=True)
    local = inverse.reshape(edges.shape)
    degree = np.bincount(local.ravel(), minlength=nodes.size)
    if np.any(degree > 2):
        raise InputError(f"boundary group {group!r} branches: the arc length needs one curve")
    ends = np.flatnonzero(degree == 1)
    if ends.size not in (0, 2):
        raise InputError(f"boundary group {group!r} has {ends.size // 2} separate pieces: the "
                         "arc length needs one curve")
    candidates = ends if ends.size else np.arange(nodes.size)
    xy = mesh.x[nodes[candidates]]
    start = candidates[np.lexsort((xy[:, 1], xy[:, 0]))[0]]
    neighbours = [[] for _ in range(nodes.size)]
    for a, b in local:
        neighbours[a].append(b)
        neighbours[b].append(a)
    order, prev, cur = [start], -1, start
    while True:
        nxt = [n for n in neighbours[cur] if n != prev]
        if not nxt or nxt[0] == start:
            break
        prev, cur = cur, nxt[0]
        order.append(cur)
    if len(order) != nodes.size:
        raise InputError(f"boundary group {group!r} is not one connected curve")
    ordered = nodes[np.array(order)]
    steps = np.linalg.norm(np.diff(mesh.x[ordered], axis=0), axis=1)
    return ordered, np.concatenate(([0.0], np.cumsum(steps)))


def pressure_profile(solution, contact: int = 0, along: str = "x"
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The contact pressure at the nodes of one contact condition against a coordinate.

    Args:
        solution: The solution.
        contact: Index of the condition in ``problem.contact``.
        along: ``"x"``, ``"y"``, ``"z"`` or ``"arclength"`` (2D: along the slave curve).

    Returns:
        (coordinate, pressure), sorted by the coordinate.
    """
    data = solution.contact.of(contact)
    if along == "arclength":
        spec = solution.problem.contact[contact]
        group = getattr(spec, "slave", None) or spec.group
        mesh = solution.problem.mesh
        nodes, s = surface_arclength(mesh, group)
        lookup = np.full(mesh.num_nodes, np.nan)
        lookup[nodes] = s
        coord = lookup[data.node]
    else:
        coord = data.x[:, "xyz".index(along)]
    order = np.argsort(coord, kind="stable")
    return coord[order], data.pressure[order]


@functools.cache
def _matplotlib() -> tuple[type, type]:
    """matplotlib's ``Figure`` and ``FigureCanvasAgg``, imported the first time on a thread.

    The first import of matplotlib leaves reference cycles (the exceptions its mathtext
    grammar raises while pyparsing builds it, with their tracebacks) whose frames reach every
    caller's frame and locals through ``f_back``: a plot made after a solve would keep the
    Solutions and their PETSc objects until each rank's cyclic collector runs, at its own
    moment (tests/feti/test_reference_cycles.py). A thread's first frame has no caller.
    """
    loaded: dict = {}

    def load() -> None:
        try:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure
            loaded["classes"] = Figure, FigureCanvasAgg
        except BaseException as e:  # re-raised on the caller's thread
            loaded["error"] = e

    thread = threading.Thread(target=load, name="dolfinx_feti-import-matplotlib")
    thread.start()
    thread.join()
    if "error" in loaded:
        raise loaded.pop("error")
    return loaded["classes"]


def plot_pressure(solution, path: str | os.PathLike, contact: int = 0, along: str = "x",
                  title: str | None = None) -> None:
    """Write a PNG plot of the contact pressure along a contact surface (call on one rank)."""
    Figure, FigureCanvasAgg = _matplotlib()
    s, p = pressure_profile(solution, contact, along)
    spec = solution.problem.contact[contact]
    group = getattr(spec, "slave", None) or spec.group
    fig = Figure(figsize=(6, 3.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.plot(s, p, "o-", ms=3, lw=0.8)
    ax.set_xlabel("arc length" if along == "arclength" else along)
    ax.set_ylabel("contact pressure")
    ax.set_title(title or f"contact pressure on {group!r}")
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    with atomic_file(path) as tmp:
        fig.savefig(tmp, format="png", dpi=120)


# ------------------------------------------------------------------------------------------
# NumPy output and metadata
# ------------------------------------------------------------------------------------------


def save_nodal_values(solution, path: str | os.PathLike) -> None:
    """Write the solution in the mesh's node order to ``.npz`` (call on one rank).

    ``solution.nodal_values()`` and ``solution.cell_subdomains()`` are collective: call them
    on every rank first (they are cached).

    Arrays: ``x`` (N, gdim) node coordinates, ``u`` (N, value_size) the solution, ``cells``,
    ``cell_body``, ``body_names``, ``cell_subdomain``, and per contact node ``contact_<name>``
    for every field of :class:`~dolfinx_feti.ContactData` that is set (``spec``, ``node``,
    ``partner``, ``normal``, ``force``, ``pressure``, ``gap``; with friction also the
    tangential force, slip, slip bound and state).
    """
    mesh, c = solution.problem.mesh, solution.contact
    contact = {f"contact_{k}": np.asarray(v) for k, v in vars(c).items()
               if v is not None and k != "x"}  # spec, node, force, ... (friction data too)
    with atomic_file(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, x=mesh.x, u=solution.nodal_values(), cells=mesh.cells,
                 cell_body=mesh.cell_body, cell_subdomain=solution.cell_subdomains(),
                 body_names=np.array(mesh.body_names), **contact)


def versions() -> dict[str, str]:
    """Versions of the libraries a solve depends on, for reports."""
    from importlib import metadata

    import mpi4py
    import petsc4py
    from mpi4py import MPI
    from petsc4py import PETSc

    try:
        own = metadata.version("dolfinx_feti")
    except metadata.PackageNotFoundError:
        own = "unknown"
    petsc = ".".join(str(v) for v in PETSc.Sys.getVersion())
    return {"dolfinx_feti": own, "dolfinx": compat.DOLFINX_VERSION, "petsc": petsc,
            "petsc4py": petsc4py.__version__, "numpy": np.__version__,
            "mpi4py": mpi4py.__version__,
            "mpi": MPI.Get_library_version().replace("\x00", "").split(",")[0].strip()}


def results(solution) -> dict:
    """A few numbers that characterize a solution (for the report)."""
    u = solution.nodal_values()
    c = solution.contact
    return {"max_abs_u": float(np.abs(u).max()) if u.size else 0.0,
            "energy": float(solution.energy),
            "total_contact_force": [float(v) for v in solution.total_contact_force],
            "max_contact_pressure": float(c.pressure.max()) if c.pressure.size else 0.0,
            "contact_nodes": int(c.node.size),
            "active_contact_nodes": int(np.sum(c.force > 1e-10 * max(c.force.max(), 1e-300)))
            if c.force.size else 0}


__all__ = ["atomic_file", "output_functions", "plot_pressure", "pressure_profile", "results",
           "save_nodal_values", "surface_arclength", "versions", "von_mises"]
