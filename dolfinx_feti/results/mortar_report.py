"""After a solve with mortar conditions: the search summary and the checks of the result.

The mortar rows hold the non-penetration condition in a weighted (integral) sense and only at
the slave nodes that the contact search coupled. So after the solve every node of both
surfaces of each :class:`~dolfinx_feti.Mortar` condition is checked against the other
deformed surface, and the report warns, naming the groups, when

- a node penetrates the other surface by more than :data:`PENETRATION_RTOL` times the mean
  facet size (the contact zone reaches nodes the rows do not hold: the candidate surfaces or
  the search distance are too small), or
- a row on the rim of a candidate surface is active (the contact zone may extend beyond the
  surfaces that were named).

For self-contact (one group as slave and master) the check runs on the zones the search
pairs (:mod:`.constraints.self_contact`) on the initial and on the deformed surface, each side
against the other.
"""

from __future__ import annotations

import numpy as np

from ..constraints.mortar import mean_facet_size, mortar_coupling, penetration
from ..constraints.mortar_rows import MortarInfo
from ..mesh.topology import facets_in_cell_order, nodal_normals_and_areas

#: A penetration deeper than this times the mean facet size of the two surfaces gets a warning.
PENETRATION_RTOL = 1e-2
#: A row counts as active where its force exceeds this times the largest force of its condition.
ACTIVE_RTOL = 1e-6


def mortar_warnings(mesh, infos: list[MortarInfo], u: np.ndarray, spec: np.ndarray,
                    node: np.ndarray, force: np.ndarray) -> tuple[list[str], list[dict]]:
    """The warnings and the per-condition summaries of a solve.

    Args:
        mesh: The mesh (global arrays).
        infos: What the search found, per mortar condition.
        u: The nodal displacement (N, gdim) or (N, 1) for a scalar problem.
        spec: Per contact row: the index of its condition; ``node`` its slave node; ``force``
            its nodal force.
        node: See ``spec``.
        force: See ``spec``.
    """
    warnings, summaries = [], []
    for info in infos:
        summary = info.summary()
        summaries.append(summary)
        warnings.extend(info.warnings)  # found by the search, before the solve
        if info.tie:
            continue
        name = f"mortar contact {info.slave!r} (slave) / {info.master!r} (master)"
        mine = spec == info.spec
        f = force[mine]
        active = node[mine][f > ACTIVE_RTOL * max(float(np.abs(f).max(initial=0.0)), 1e-300)]
        rim_active = np.intersect1d(active, info.rim_nodes)
        if rim_active.size:
            warnings.append(
                f"{name}: {rim_active.size} active row(s) on the rim of a candidate surface "
                f"(e.g. the slave node at {np.round(mesh.x[rim_active[0]], 6).tolist()}): the "
                "contact zone may extend beyond the named surfaces; name larger candidate "
                "surfaces")
        summary["active_rows"] = int(active.size)
        if u.shape[1] != mesh.gdim:
            continue  # a scalar problem has no deformed geometry to check
        xd = mesh.x + u[: mesh.x.shape[0]]  # the vertices (the first dof points for degree 2)
        if info.coupling.zones is not None:
            # Self-contact: the zones that face each other, before and after the
            # deformation, not the whole surface (whose nodes lie behind its own facets
            # across every thin wall).
            after = mortar_coupling(xd, mesh.cells, mesh.facets(info.slave),
                                    mesh.facets(info.slave), info.coupling.search_distance,
                                    mesh.cell_type, self_contact=True).zones
            S, M = (np.unique(np.concatenate([a, b]), axis=0)
                    for a, b in zip(info.coupling.zones, after, strict=True))
        else:
            S = facets_in_cell_order(mesh.cells, mesh.facets(info.slave), mesh.cell_type)
            M = facets_in_cell_order(mesh.cells, mesh.facets(info.master), mesh.cell_type)
        h = max(mean_facet_size(mesh.x, S), mean_facet_size(mesh.x, M))
        tol = PENETRATION_RTOL * h
        count, worst = _through([(xd, mesh.cells, S, mesh.cell_type),
                                 (xd, mesh.cells, M, mesh.cell_type)],
                                info.coupling.search_distance, tol)
        summary["max_penetration"] = worst
        if count:
            warnings.append(
                f"{name}: {count} node(s) of the two surfaces penetrate the other one by up to "
                f"{worst:.3g} (tolerance {tol:.3g}): the contact zone reaches nodes that no row "
                "holds; name larger candidate surfaces or a larger search_distance")
    return warnings, summaries


def between_meshes_warnings(meshes, nodal: list[np.ndarray], across, coupled
                            ) -> tuple[list[str], list[dict]]:
    """The checks of :func:`mortar_warnings` for the conditions between two meshes.

    Every node of both surfaces of each contact condition between meshes of different cell
    types (:mod:`dolfinx_feti.drivers.mixed_solve`) against the other deformed surface.

    Args:
        meshes: The meshes, one per cell type.
        nodal: The displacement at the points of each mesh (degree 1: its vertices).
        across: The conditions between meshes (:class:`.problem.mixed_problem.Across`).
        coupled: Their rows (:class:`.results.mixed_solution.Coupled`).
    """
    warnings, summaries = [], []
    for a, c in zip(across, coupled, strict=True):
        summary = {"type": "tie" if a.tie else "mortar", "slave": a.spec.slave,
                   "master": a.spec.master, "rows": c.rows, "uncoupled_slave_nodes":
                   c.uncoupled, "facet_pairs": c.pairs, "search_distance": c.search_distance}
        summaries.append(summary)
        if a.tie or nodal[a.slave].shape[1] != meshes[a.slave].gdim:
            continue
        sides, h = [], 0.0
        for k, group in ((a.slave, a.spec.slave), (a.master, a.spec.master)):
            m = meshes[k]
            f = facets_in_cell_order(m.cells, m.facets(group), m.cell_type)
            sides.append((m.x + nodal[k][: m.x.shape[0]], m.cells, f, m.cell_type))
            h = max(h, mean_facet_size(m.x, f))
        tol = PENETRATION_RTOL * h
        try:
            count, worst = _through(sides, c.search_distance, tol)
        except ValueError:  # a deformed surface folds onto itself
            warnings.append(f"mortar contact {a.spec.slave!r} / {a.spec.master!r}: a deformed "
                            "surface folds onto itself (displacements as large as the "
                            "bodies: check the units); not checked")
            continue
        summary["max_penetration"] = worst
        if count:
            warnings.append(
                f"mortar contact {a.spec.slave!r} (slave) / {a.spec.master!r} (master): "
                f"{count} node(s) of the two surfaces penetrate the other one by up to "
                f"{worst:.3g} (tolerance {tol:.3g}): the contact zone reaches nodes that no "
                "row holds; name larger candidate surfaces or a larger search_distance")
    return warnings, summaries


def _through(sides: list[tuple], reach: float, tol: float) -> tuple[int, float]:
    """The nodes of two deformed surfaces behind each other: (how many past ``tol``, deepest).

    Args:
        sides: Two surfaces, each ``(deformed coordinates, cells, facets in cell order,
            cell type)`` of its mesh.
        reach: The largest depth that counts (:func:`.constraints.mortar.penetration`).
        tol: The depth that counts as penetration.
    """
    worst, count = 0.0, 0
    for (xa, ca, fa, ta), (xb, cb, fb, tb) in (sides, sides[::-1]):
        nodes, normals, _ = nodal_normals_and_areas(xa, ca, fa, ta)
        depth = penetration(xa[nodes], normals, xb, cb, fb, reach, tb)
        count += int((depth > tol).sum())
        worst = max(worst, float(depth.max(initial=0.0)))
    return count, worst
