"""One subdomain as a serial DOLFINx mesh, its tagged measures, and its assembled K_i, f_i.

The assembled matrix and vector are permuted into the canonical order of
:class:`~dolfinx_feti.mesh.decompose.Decomposition` (sorted global dof point, then component),
so nothing downstream depends on DOLFINx's dof numbering.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
import scipy.sparse as sp
import ufl
from mpi4py import MPI

from .. import compat
from ..errors import InputError
from ..mesh.checks import check_boundary_group
from ..mesh.data import MeshData
from ..mesh.dofpoints import DofPoints, dof_points
from ..mesh.topology import row_keys
from .dofmap import cell_dof_points
from .form_checks import (
    check_finite_literals,
    check_form_kinds,
    check_magnitudes,
    check_symmetric,
)
from .load_form import LoadForm

_NO_FACET = 2**30  # a tag value no facet carries: an integral over it is zero


def _is_zero(L) -> bool:
    """Whether a linear form is absent or identically zero (UFL folds a zero load to Zero)."""
    if L is None or (isinstance(L, (int, float)) and L == 0):
        return True
    return isinstance(L, ufl.Form) and (L.empty() or all(
        isinstance(i.integrand(), ufl.constantvalue.Zero) for i in L.integrals()))


class Subdomain:
    """Subdomains' serial mesh with the parent's tags, as the user's form callback sees it.

    One or several subdomains of a rank are meshed together as a disjoint union: each keeps its
    own copy of the nodes it shares with others, so the assembled matrix is block diagonal,
    one block per subdomain, in the canonical order. Assembling several subdomains at once
    costs one mesh construction and one assembly instead of one per subdomain (a rank's
    subdomains are grouped into meshes of about ``fem.assembly.CELLS_PER_MESH`` cells).

    Attributes:
        indices: Subdomain numbers (global), in the order of their blocks.
        mesh: The DOLFINx mesh on ``MPI.COMM_SELF``.
        nodes: Global dof point of each canonical local dof point (a point shared by two of
            the subdomains appears twice).
        bodies: Names of the bodies with cells here.
        degree: Degree of the Lagrange space the forms are given.
    """

    def __init__(self, indices: Sequence[int], mesh: MeshData, cells: Sequence[np.ndarray],
                 nodes: Sequence[np.ndarray], facets: Sequence[Mapping[str, np.ndarray]],
                 points: DofPoints | None = None,
                 check_group: Callable[[str, str], None] | None = None) -> None:
        """Build the serial mesh of the given subdomains and tag it.

        Args:
            indices: Subdomain numbers.
            mesh: The mesh data the subdomains are in (the whole mesh, or a rank's share of
                it: :mod:`dolfinx_feti.setup.share`).
            cells: Per subdomain, the indices of its cells in ``mesh``.
            nodes: Per subdomain, the sorted dof points of those cells (of ``points``).
            facets: Per subdomain, boundary group name → the group's facets (vertices)
                there.
            points: The dof points of ``mesh`` (default: the vertices, degree 1).
            check_group: ``check_group(group, what)`` refuses a boundary group that cannot
                carry a boundary integral (default: checked on ``mesh`` itself, which must
                then be the whole mesh).
        """
        self.indices = tuple(int(i) for i in indices)
        self._mesh_data = mesh
        self._check_group = check_group or (
            lambda group, what: check_boundary_group(mesh, group, what))
        self._points = dof_points(mesh, 1) if points is None else points
        self.degree = self._points.degree
        self.nodes = np.concatenate(nodes)
        # The mesh's input nodes: the vertices (they come first among the sorted dof points of
        # a subdomain), or all dof points of a curved mesh (its geometry nodes: degree 2).
        curved = mesh.geometry_degree == 2
        verts = nodes if curved else [n[:np.searchsorted(n, mesh.num_nodes)] for n in nodes]
        conn, xg = (self._points.cell_points, self._points.x) if curved else (mesh.cells, mesh.x)
        offsets = np.cumsum([0] + [v.size for v in verts[:-1]])
        self._input_global = np.concatenate(verts)  # mesh input node → global dof point
        # the input nodes are the canonical points in their order (no points beyond vertices)
        self._inputs_are_points = not curved and self._input_global.size == self.nodes.size
        local = np.empty(xg.shape[0], dtype=np.int64)
        parts = []
        for c, v, o in zip(cells, verts, offsets, strict=True):  # over the subdomains
            local[v] = np.arange(o, o + v.size)  # this subdomain's copy of each node
            parts.append(local[conn[c]])
        local_cells = np.concatenate(parts)
        self.mesh = compat.create_mesh(MPI.COMM_SELF, local_cells, xg[self._input_global],
                                       mesh.cell_type, mesh.geometry_degree)
        self._node_of_geom = compat.node_input_indices(self.mesh)  # geometry node → input node
        cell_input = compat.cell_input_indices(self.mesh)
        block = np.repeat(np.arange(len(cells)), [c.size for c in cells])
        self._cell_block = block[cell_input]
        body = mesh.cell_body[np.concatenate(cells)][cell_input]
        self.bodies = tuple(mesh.body_names[b] for b in np.unique(body))
        self._cell_tags = compat.cell_tags(self.mesh, np.arange(body.size), body)
        self._node_ptr = np.cumsum([0] + [n.size for n in nodes])
        local_facets: dict[str, list[np.ndarray]] = {}
        for f, v, o in zip(facets, verts, offsets, strict=True):
            for name, fac in f.items():
                local_facets.setdefault(name, []).append(np.searchsorted(v, fac) + o)
        self._facet_ids, self._facet_data = self._group_facets(
            {name: np.concatenate(parts) for name, parts in local_facets.items()})
        self._facet_tags_made = None
        self._kept_load: LoadForm | None = None  # the last load's compiled form (load_form.py)

    @property
    def _ids(self) -> str:
        return ", ".join(map(str, self.indices))

    @property
    def index(self) -> int:
        """The (first) subdomain number, for messages."""
        return self.indices[0]

    def _group_facets(self, facets: Mapping[str, np.ndarray]):
        """Each facet's class (the set of groups it is in) and each group's classes."""
        # A facet may sit in several groups: tag each facet with the index of its set of
        # groups, so every group is a union of tag values of one MeshTags (UFL allows only one
        # subdomain_data per integral type in a form).
        names = [n for n, f in facets.items() if f.shape[0] > 0]
        if not names:
            return {}, None
        allf = np.concatenate([facets[n] for n in names])
        group = np.concatenate([np.full(facets[n].shape[0], i) for i, n in enumerate(names)])
        keys = row_keys(allf)
        ukeys, first, inv = np.unique(keys, return_index=True, return_inverse=True)
        member = np.zeros((ukeys.size, len(names)), dtype=bool)
        member[inv, group] = True
        classes, cls = np.unique(member, axis=0, return_inverse=True)
        ids = {n: tuple(int(c) + 1 for c in np.flatnonzero(classes[:, i]))
               for i, n in enumerate(names)}
        return ids, (allf[first], cls.ravel() + 1)

    @property
    def _facet_tags(self):
        """The facet MeshTags, made on the first ``ds`` (facet connectivity is not cheap)."""
        if self._facet_tags_made is None and self._facet_data is not None:
            local, values = self._facet_data
            geom_of_node = np.empty_like(self._node_of_geom)
            geom_of_node[self._node_of_geom] = np.arange(self._node_of_geom.size)
            self._facet_tags_made = compat.facet_tags(self.mesh, geom_of_node[local], values)
        return self._facet_tags_made

    @property
    def body(self) -> str:
        """The body this subdomain belongs to (an error if it spans several)."""
        if len(self.bodies) != 1:
            raise InputError(f"subdomains {list(self.indices)} span bodies {list(self.bodies)}: "
                             "use sub.bodies, sub.dx(body) or sub.cellwise({...})")
        return self.bodies[0]

    def has_facets(self, group: str) -> bool:
        """Whether the boundary group has facets in this subdomain."""
        return group in self._facet_ids

    def dx(self, *bodies: str) -> ufl.Measure:
        """Cell measure over the whole subdomain, or over the cells of the named bodies."""
        if not bodies:
            return compat.measure("dx", self.mesh)
        ids = tuple(self._mesh_data.body_index(b) for b in bodies)
        return compat.measure("dx", self.mesh, self._cell_tags)(ids)

    def ds(self, *groups: str) -> ufl.Measure:
        """Exterior facet measure over the named boundary groups (zero if none is here)."""
        for g in groups:  # known, not empty, and no facet between two cells
            self._check_group(g, "the boundary integral sub.ds over")
        ids = tuple(sorted({i for g in groups for i in self._facet_ids.get(g, ())}))
        return compat.measure("ds", self.mesh, self._facet_tags)(ids or (_NO_FACET,))

    def cellwise(self, values: Mapping[str, float]):
        """A coefficient that is constant on each body's cells (a DG0 Function if it varies)."""
        vals = {values[b] for b in self.bodies}
        if len(vals) == 1:
            return float(vals.pop())
        Q = compat.dg0_space(self.mesh)
        q = compat.function(Q, "cellwise")
        table = np.array([values.get(b, np.nan) for b in self._mesh_data.body_names])
        body_of_cell = self._cell_tags.values[np.argsort(self._cell_tags.indices)]
        dofs = compat.cell_dofs(Q).ravel()  # one dof per cell, in cell order
        q.x.array[dofs] = table[body_of_cell]
        return q

    @property
    def dof_permutation(self) -> np.ndarray:
        """The DOLFINx dof of each canonical dof of the space the forms were given.

        Set before the first call of the forms: ``w.x.array[perm] = values`` puts canonical
        values into a Function ``w`` of that space.
        """
        return self._perm

    def _canonical_points(self, V) -> np.ndarray:
        """For each (blocked) dof of V, its index in the canonical order of the dof points."""
        block = self._cell_block[:, None]
        if self._inputs_are_points:  # a vertex is its own point: its input node is its place
            dofs, pos = cell_dof_points(V, self._node_of_geom, self._points)
            wrong = (pos < self._node_ptr[block]) | (pos >= self._node_ptr[block + 1])
        else:
            dofs, pts = cell_dof_points(V, self._input_global[self._node_of_geom],
                                        self._points)
            # The block of a cell says which copy of a shared dof point its dofs are.
            key_nodes = np.repeat(np.arange(len(self._node_ptr) - 1), np.diff(self._node_ptr)) \
                * np.int64(self._points.num_points) + self.nodes
            want = block * np.int64(self._points.num_points) + pts
            pos = np.minimum(np.searchsorted(key_nodes, want), key_nodes.size - 1)
            wrong = key_nodes[pos] != want
        out = np.full(compat.dof_count(V), -1, dtype=np.int64)
        out[dofs] = pos
        # each dof on its own point of this subdomain: else the permutation below has holes
        if np.any(wrong) or np.any(out < 0) or \
                np.any(np.bincount(out, minlength=out.size) != 1):
            raise AssertionError(f"subdomain(s) {self._ids}: the space's dofs do not sit one "
                                 "by one on the subdomain's dof points")
        return out

    def _check_space(self, forms, V) -> None:
        """Refuse forms whose arguments live on a space other than V."""
        for form, what in forms:
            if not isinstance(form, ufl.Form):
                continue
            for arg in form.arguments():
                W = arg.ufl_function_space()
                if not compat.same_space(W, V):
                    kind = "test" if arg.number() == 0 else "trial"
                    raise InputError(
                        f"subdomain(s) {self._ids}: the {what} form's {kind} function is "
                        f"defined on a function space other than the one the library gives "
                        f"(V: {compat.describe_space(V)}; the form's: "
                        f"{compat.describe_space(W)}). Build the forms on the V passed to "
                        "forms(V, sub); choose the degree with ContactProblem(..., degree=2) "
                        "or Elasticity/Poisson(..., degree=2)")

    def assemble(self, forms, value_size: int) -> tuple[sp.csr_matrix, np.ndarray]:
        """Assemble the user's forms and return (K, f) in the canonical dof order.

        ``forms`` may return ``L = None`` (or an empty form) for an unloaded subdomain. The
        space and the dof permutation are kept for :meth:`assemble_load`.
        """
        a, L = self._forms(forms, value_size)
        self._kept_load = LoadForm.of(forms, self, None if _is_zero(L) else L)
        A = compat.assemble_matrix(a)
        indptr, indices, data = A.getValuesCSR()
        K = sp.csr_matrix((data, indices, indptr), shape=A.getSize())
        A.destroy()
        perm = self._perm
        K = K[perm][:, perm].tocsr()
        K.eliminate_zeros()  # P1 on structured grids leaves exact zeros: they cost in the factor
        K.sort_indices()
        if not np.all(np.isfinite(K.data)):
            raise InputError(f"{self._where}: the assembled stiffness matrix has non-finite "
                             "entries (NaN/Inf in the data)")
        f = self._load(L, K.shape[0], self._kept_load)
        check_magnitudes(K, f, self._where)
        check_symmetric(K, self._where)  # before K K⁺ K = K, which would blame the null space
        return K, f

    def assemble_load(self, forms, value_size: int) -> np.ndarray:
        """Assemble only the linear form of ``forms`` (a new load case on the same space).

        A load of the shape of the last one (see :mod:`~dolfinx_feti.fem.load_form`) sets the
        kept compiled form's constants; any other is built and compiled again.
        """
        if self._kept_load is not None and self._kept_load.matches(forms, self):
            return self._load(None, self._perm.size, self._kept_load, forms)
        _, L = self._forms(forms, value_size)
        self._kept_load = LoadForm.of(forms, self, None if _is_zero(L) else L)
        return self._load(L, self._perm.size, self._kept_load)

    @property
    def _where(self) -> str:
        return f"subdomain(s) {self._ids} (bodies {list(self.bodies)})"

    def _forms(self, forms, value_size: int):
        """The user's (a, L) on this subdomain's space, checked; the space's permutation kept."""
        if getattr(self, "_space", None) is None:
            self._space = compat.function_space(self.mesh, value_size, self.degree)
            # canonical dof bs*node + c  ←  DOLFINx dof bs*d + c
            node_of_dof = self._canonical_points(self._space)
            bs = value_size
            perm = np.empty(bs * node_of_dof.size, dtype=np.int64)
            for c in range(bs):
                perm[bs * node_of_dof + c] = bs * np.arange(node_of_dof.size) + c
            self._perm = perm
        V = self._space
        result = forms(V, self)
        if not (isinstance(result, tuple | list) and len(result) == 2):
            raise InputError(f"{self._where}: forms(V, sub) returned {type(result).__name__}"
                             + (f" of length {len(result)}" if hasattr(result, "__len__") else "")
                             + ", not a pair (a, L)")
        a, L = result
        check_form_kinds(a, None if _is_zero(L) else L, self._where)
        self._check_space(((a, "bilinear"), (L, "linear")), V)
        for form, what in ((a, "bilinear"), (L, "linear")):
            check_finite_literals(form, f"subdomain(s) {self._ids} ({', '.join(self.bodies)}): "
                                   f"the {what} form")
        return a, L

    def _load(self, L, n: int, kept: LoadForm | None = None, forms=None) -> np.ndarray:
        """The assembled linear form in the canonical order (zeros for no form).

        With ``kept`` the vector comes from the kept compiled form, its constants set to the
        values of ``forms`` (by default: those ``L`` was built with).
        """
        if kept is not None:
            f = kept.assemble(None if forms is None else forms.load_values(self))
            if f is None:  # no load on this subdomain
                return np.zeros(n)
        elif _is_zero(L):
            return np.zeros(n)
        else:
            b = compat.assemble_vector(L)
            f = b.array.copy()
            b.destroy()
        f = f[self._perm]
        if not np.all(np.isfinite(f)):
            raise InputError(f"{self._where}: the assembled load has non-finite entries "
                             "(NaN/Inf in the data)")
        return f
