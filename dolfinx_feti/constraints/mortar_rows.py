"""Rows of B from a mortar coupling: non-penetration (one bound per slave node) and ties.

With the dual multiplier basis the coupling of slave node j is the weighted master point
Σ_k w_jk x_k (w_jk = M_jk / C_j, see :mod:`.mortar`), so a mortar row looks like a node-to-node
row whose master node is replaced by that weighted combination::

    contact:  s_j · n_j·(Σ_k w_jk u_k − u_j) <= s_j · n_j·(x_j − Σ_k w_jk x_k)
    tie:      s_j · (u_j,c − Σ_k w_jk u_k,c) = 0        for each component c

with n_j the averaged slave normal turned toward the slave (the direction of the master's
outward normal, as in node-to-node rows) and s_j = 1/√(1 + Σ_k w_jk²) the factor that gives
the row unit norm; so the physical multiplier s_j λ_j is the nodal contact force, as for
node-to-node rows, and with matching meshes (w_jk = δ) the rows are the node-to-node rows.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..mesh.checks import boundary_facets
from ..mesh.data import MeshData
from ..mesh.dofpoints import DofPoints
from ..problem.conditions import Mortar, Tie
from .contact import surface
from .mortar import (
    COVERAGE_FULL_TOL,
    MortarCoupling,
    default_search_distance,
    mean_facet_size,
    mortar_coupling,
    open_rim,
    same_way_pairs,
)
from .mortar_normals import with_normals
from .mortar_p2 import quadratic_coupling
from .rows import Kind, Rows

#: A tie whose rows bridge a gap wider than this times the surfaces' facet size gets a warning:
#: two surfaces that are one interface coincide up to the discretization of a curved surface
#: (about h²/(8R), below h/16 for facets up to half the radius).
TIE_GAP_FACETS = 0.25
#: A tie within one body across a gap wider than this times the facet size is refused: that
#: is two faces of the body (e.g. its top and bottom), not an interface of two meshed pieces.
SAME_BODY_GAP_FACETS = 1.0
#: Contact rows bridging a gap wider than this times the facet size, and wider than the default
#: search distance, get a warning (a large search_distance reaching across a body).
CONTACT_GAP_FACETS = 4.0
#: Weighted gaps below this times eps times the largest coordinate of the surfaces are
#: round-off of the geometry (touching surfaces), and taken as exactly 0.
GAP_ROUNDOFF = 64.0


@dataclass
class MortarInfo:
    """What the search found for one mortar condition (for the report and the checks).

    Attributes:
        spec: Index of the condition (in the problem's contact list, or its ties).
        slave, master: The boundary groups.
        coupling: The mortar coupling.
        rows: Number of rows (coupled slave nodes).
        uncoupled: Slave nodes with no master facet in range (no row).
        rim_nodes: The coupled slave nodes on the rim of a candidate surface.
        tie: A :class:`~dolfinx_feti.Tie` (equality rows), else a contact condition.
        warnings: Notes on the pair found before the solve (rows bridging a wide gap, no
            row at all), for the report.
    """

    spec: int
    slave: str
    master: str
    coupling: MortarCoupling
    rows: int
    uncoupled: int
    rim_nodes: np.ndarray
    tie: bool = False
    warnings: list[str] = field(default_factory=list)

    def summary(self) -> dict:
        """Plain data for the report."""
        return {"type": "tie" if self.tie else "mortar", "slave": self.slave,
                "master": self.master, "rows": self.rows,
                "uncoupled_slave_nodes": self.uncoupled, "rim_rows": int(self.rim_nodes.size),
                "facet_pairs": self.coupling.pairs,
                "search_distance": self.coupling.search_distance}


def _coupling(mesh: MeshData, name: str, slave: str, master: str, search_distance,
              points: DofPoints | None = None) -> MortarCoupling:
    """The coupling at the vertices (degree 1), or at the dof points of 3-node segments.

    Two surfaces that face the same way are refused by name (one surface with itself,
    self-contact, is not such a pair).
    """
    surface(mesh, slave)  # a surface that is no boundary of a body is refused by name here
    surface(mesh, master)
    args = (mesh.x, mesh.cells, mesh.facets(slave), mesh.facets(master))
    self_contact = slave == master
    if points is not None and points.degree == 2:
        coupling = quadratic_coupling(*args, points, search_distance, mesh.cell_type,
                                      self_contact=self_contact)
    else:
        coupling = mortar_coupling(*args, search_distance, mesh.cell_type,
                                   self_contact=self_contact)
    if not self_contact and not np.any(coupling.coupled):
        same = same_way_pairs(*args, coupling.search_distance, mesh.cell_type)
        if same:
            raise InputError(f"{name}: inconsistent normals: the two surfaces face the same "
                             f"way (their outward normals agree at all {same} facet pairs "
                             "within the search distance), so no slave node is coupled; "
                             "the surfaces of an interface must face each other (did you "
                             "name a surface of the wrong body, or the far side of one?)")
    return coupling


def _point_x(mesh: MeshData, points: DofPoints | None) -> np.ndarray:
    """The coordinates of the points the rows are at (the vertices for degree 1)."""
    return mesh.x if points is None or points.degree == 1 else points.x


def _pair_checks(mesh: MeshData, name: str, slave: str, master: str,
                 coupling: MortarCoupling, gap: np.ndarray, tie: bool,
                 px: np.ndarray) -> list[str]:
    """Rows that bridge a gap much wider than the facets: warned, or refused within a body.

    Args:
        mesh: The mesh.
        name: The condition, for messages.
        slave: The slave group.
        master: The master group.
        coupling: Their coupling.
        gap: Per coupled slave node, the distance its row bridges (ties: to the weighted
            master point; contact: along the normal, signed).
        tie: Whether the rows are a tie's.
        px: The coordinates the coupling's slave nodes index (the dof points of degree 2).
    """
    S, M = mesh.facets(slave), mesh.facets(master)
    h = max(mean_facet_size(mesh.x, S), mean_facet_size(mesh.x, M))
    slave_nodes = coupling.slave_nodes[coupling.coupled]
    if slave_nodes.size == 0:
        return [f"{name}: no row: no slave node has a master facet within the search "
                f"distance {coupling.search_distance:.3g} (the surfaces are out of each "
                "other's reach), so the condition does nothing"]
    k = int(np.argmax(np.abs(gap)))
    worst = float(abs(gap[k]))
    where = np.round(px[slave_nodes[k]], 6).tolist()
    what = (f"{name}: its rows bridge gaps up to {worst:.3g} between the surfaces "
            f"({worst / h:.1f} times their mean facet size {h:.3g}; e.g. at the slave node at "
            f"{where})")
    if tie:
        if worst <= TIE_GAP_FACETS * h:
            return []
        common = _bodies(mesh, slave) & _bodies(mesh, master)
        if common and worst > SAME_BODY_GAP_FACETS * h:
            raise InputError(f"{what}, and both surfaces belong to body "
                             f"{mesh.body_names[min(common)]!r}: these are two faces of one "
                             "body, not an interface; a tie glues surfaces that coincide")
        return [f"{what}: a tie glues surfaces that coincide; the bodies are glued across "
                "the gap as if it were not there (check the groups, or mesh the bodies "
                "touching)"]
    reach = max(CONTACT_GAP_FACETS * h, default_search_distance(mesh.x, S, M))
    if worst <= reach:
        return []
    return [f"{what}: a search_distance this large may couple the slave surface to a far "
            "part of the master (e.g. across a body); give a smaller search_distance"]


def snap_roundoff(gap: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The gaps with those below the round-off of the coordinates ``x`` set to exactly 0.

    Two surfaces that touch exactly get weighted gaps of a few eps times the coordinates'
    size; taken as data they turn a zero load into a QP with a tiny non-zero solution that
    costs dozens of iterations.
    """
    scale = float(np.abs(x).max(initial=0.0))
    return np.where(np.abs(gap) <= GAP_ROUNDOFF * np.finfo(float).eps * scale, 0.0, gap)



def _rim_rows(mesh: MeshData, slave: str, master: str, coupling: MortarCoupling) -> np.ndarray:
    """The coupled slave nodes on an open rim (:func:`.mortar.open_rim`) of either surface.

    A slave node is on the master's open rim when its support is only partly covered and it
    is coupled to a node of that rim.
    """
    boundary, _ = boundary_facets(mesh)
    s_rim = open_rim(mesh.x, mesh.cells, mesh.facets(slave), boundary, mesh.cell_type)
    m_rim = open_rim(mesh.x, mesh.cells, mesh.facets(master), boundary, mesh.cell_type)
    keep = coupling.coupled
    nodes = coupling.slave_nodes
    partial = coupling.coverage < 1.0 - COVERAGE_FULL_TOL
    M = coupling.M.tocsr()
    touches = np.asarray(M[:, m_rim].getnnz(axis=1) > 0).ravel() if m_rim.size else \
        np.zeros(nodes.size, dtype=bool)
    rim = np.isin(nodes, s_rim) | (partial & touches)
    return nodes[keep & rim]


def _bodies(mesh: MeshData, group: str) -> set[int]:
    nodes = np.unique(mesh.facets(group))
    return set(np.unique(mesh.cell_body[np.isin(mesh.cells, nodes).any(axis=1)]).tolist())


def coupled_rows(coupling: MortarCoupling, first: np.ndarray, bs: int, dirs: np.ndarray
                  ) -> tuple[np.ndarray, ...]:
    """Entries of rows s_j (dir_j·u_j − Σ_k w_jk dir_j·u_k), one row per coupled node.

    ``dirs`` (rows, bs) is the direction each row measures (a normal, or a unit vector e_c).
    """
    W = coupling.weights().tocoo()
    slave = coupling.slave_nodes[coupling.coupled]
    nr = slave.size
    s = 1.0 / np.sqrt(1.0 + np.asarray(W.multiply(W).sum(axis=1)).ravel())
    comps = np.arange(bs)
    e_row = np.concatenate([np.repeat(np.arange(nr), bs), np.repeat(W.row, bs)])
    e_node = np.concatenate([np.repeat(slave, bs), np.repeat(W.col, bs)])
    e_comp = np.concatenate([np.tile(comps, nr), np.tile(comps, W.nnz)])
    e_coef = np.concatenate([(s[:, None] * dirs).ravel(),
                             (-(s[W.row] * W.data)[:, None] * dirs[W.row]).ravel()])
    keep = e_coef != 0.0
    return (e_row[keep], first[e_node[keep]].astype(np.int32), e_node[keep],
            e_comp[keep].astype(np.int8), e_coef[keep], s, slave)


def mortar_contact_rows(mesh: MeshData, spec: Mortar, index: int, node_ptr: np.ndarray,
                        node_subs: np.ndarray, bs: int, points: DofPoints | None = None
                        ) -> tuple[Rows, MortarInfo]:
    """Non-penetration rows of a :class:`~dolfinx_feti.Mortar` condition, one per coupled node.

    ``points``: the space's dof points (rows at the dof points of 3-node segments for
    degree 2); the vertices when None.
    """
    name = f"mortar contact {spec.slave!r} (slave) / {spec.master!r} (master)"
    common = _bodies(mesh, spec.slave) & _bodies(mesh, spec.master)
    if common and spec.slave != spec.master:  # one group with itself: self-contact
        raise InputError(f"{name}: both surfaces belong to body "
                         f"{mesh.body_names[min(common)]!r}; contact is between two bodies")
    coupling = _coupling(mesh, name, spec.slave, spec.master, spec.search_distance, points)
    coupling = with_normals(mesh, spec.slave, spec.master, coupling, spec.normals, points)
    keep = coupling.coupled
    n = -coupling.normals[keep]  # toward the slave: the master's outward direction
    first = node_subs[node_ptr[:-1]]  # the smallest subdomain holding each node
    nodes = np.unique(np.concatenate([mesh.facets(spec.slave).ravel(),
                                      mesh.facets(spec.master).ravel()]))
    gap = snap_roundoff(coupling.weighted_gap(_point_x(mesh, points)), mesh.x[nodes])
    warnings = _pair_checks(mesh, name, spec.slave, spec.master, coupling, gap, tie=False,
                            px=_point_x(mesh, points))
    if bs > 1:
        dirs = -n  # the row is s·n·(Σ w u_m − u_s): slave direction −n
    else:
        gap = np.zeros(int(keep.sum()))
        dirs = np.ones((int(keep.sum()), 1))
    e_row, e_sub, e_node, e_comp, e_coef, s, slave = coupled_rows(coupling, first, bs, dirs)
    nr = slave.size
    rows = Rows(e_row=e_row, e_sub=e_sub, e_node=e_node, e_comp=e_comp, e_coef=e_coef,
                rhs=s * gap, kind=np.full(nr, Kind.CONTACT, dtype=np.int8), scale=s, node=slave,
                partner=np.full(nr, -1), normal=n if bs > 1 else np.zeros((nr, mesh.gdim)),
                spec=np.full(nr, index, dtype=np.int32))
    info = MortarInfo(spec=index, slave=spec.slave, master=spec.master, coupling=coupling,
                      rows=nr, uncoupled=int((~keep).sum()),
                      rim_nodes=_rim_rows(mesh, spec.slave, spec.master, coupling),
                      warnings=warnings)
    return rows, info


def tie_rows(mesh: MeshData, spec: Tie, index: int, node_ptr: np.ndarray, node_subs: np.ndarray,
             fixed: np.ndarray, bs: int, points: DofPoints | None = None
             ) -> tuple[Rows, MortarInfo]:
    """Equality rows u_j,c = Σ_k w_jk u_k,c of a :class:`~dolfinx_feti.Tie`, per component.

    Components with a Dirichlet condition at the slave node are skipped (its Dirichlet row
    already holds them), as in the gluing of matching subdomains. ``points`` as for
    :func:`mortar_contact_rows`.
    """
    name = f"tie {spec.slave!r} (slave) / {spec.master!r} (master)"
    coupling = _coupling(mesh, name, spec.slave, spec.master, spec.search_distance, points)
    if not np.any(coupling.coupled):
        raise InputError(f"{name}: no slave node has a master facet within the search "
                         f"distance {coupling.search_distance:.3g}: the surfaces are out of "
                         "each other's reach (not an interface, or a search_distance too "
                         "small for the gap between them)")
    keep = np.flatnonzero(coupling.coupled)
    px = _point_x(mesh, points)
    bridged = np.linalg.norm(coupling.weights() @ px - px[coupling.slave_nodes[keep]], axis=1)
    warnings = _pair_checks(mesh, name, spec.slave, spec.master, coupling, bridged, tie=True,
                            px=px)
    first = node_subs[node_ptr[:-1]]
    blocks = []
    slave = coupling.slave_nodes[coupling.coupled]
    for c in range(bs):
        dirs = np.zeros((slave.size, bs))
        dirs[:, c] = 1.0
        e_row, e_sub, e_node, e_comp, e_coef, s, _ = coupled_rows(coupling, first, bs, dirs)
        free = ~fixed[slave, c]
        sel = np.flatnonzero(free)
        new = np.full(slave.size, -1)
        new[sel] = np.arange(sel.size)
        ke = free[e_row]
        nr = sel.size
        blocks.append(Rows(
            e_row=new[e_row[ke]], e_sub=e_sub[ke], e_node=e_node[ke], e_comp=e_comp[ke],
            e_coef=e_coef[ke], rhs=np.zeros(nr), kind=np.full(nr, Kind.GLUE, dtype=np.int8),
            scale=s[sel], node=slave[sel], partner=np.full(nr, -1),
            normal=np.zeros((nr, mesh.gdim)), spec=np.full(nr, -1, dtype=np.int32)))
    rows = Rows.concatenate(blocks)
    comp = np.zeros(rows.size, dtype=np.int64)
    comp[rows.e_row] = rows.e_comp
    rows = rows.permuted(np.lexsort((comp, rows.node)))  # node-major, like the gluing rows
    info = MortarInfo(spec=index, slave=spec.slave, master=spec.master, coupling=coupling,
                      rows=rows.size, uncoupled=int((~coupling.coupled).sum()),
                      rim_nodes=_rim_rows(mesh, spec.slave, spec.master, coupling), tie=True,
                      warnings=warnings)
    return rows, info


def self_contact_areas(mesh: MeshData, spec: Mortar, points: DofPoints | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """The slave nodes of a self-contact condition and their areas D_j = ∫ N_j on its zones.

    The area of a node is taken over the facets of the zones the search paired, not over the
    whole group, which goes round the corners of the body (a contact pressure is the nodal
    force divided by it, as for two surfaces).
    """
    coupling = _coupling(mesh, f"self-contact {spec.slave!r}", spec.slave, spec.master,
                         spec.search_distance, points)
    return coupling.slave_nodes, coupling.D
