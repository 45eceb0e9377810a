"""Benchmark geometries as gmsh models (the problems B1–B5 of docs/benchmarks.md).

Each function adds a new model to the current gmsh session (the caller runs
``gmsh.initialize()`` and ``gmsh.finalize()``), meshes it with first-order simplices, names its
physical groups and leaves it current, ready for ``gmsh.write`` (format 4.1) or for reading into
DOLFINx. Every function returns the physical groups as ``{name: (dim, tag)}``.

Bodies that touch are separate entities with their own nodes on the contact interface: they
are meant to be different bodies (or subdomains) coupled by contact constraints.

Physical tags: bodies are numbered 1, 2, ... and boundary groups 11, 12, ... so that no two
groups of a model share a tag, whatever their dimension.

The structured meshes (:func:`membranes`, :func:`blocks3d`) are built directly as gmsh discrete
entities, so their triangulation is exactly the documented one: the Kuhn (Freudenthal)
subdivision of a grid of squares or cubes, every square (and every face of a cube) split along
its diagonal from the corner with the smallest coordinates to the one with the largest, and every
cube into six tetrahedra around that diagonal.
"""

from __future__ import annotations

import itertools
import math

import gmsh
import numpy as np

from ..mesh.topology import row_keys

#: gmsh element types of first-order simplices by topological dimension.
_SIMPLEX_TYPE = {1: 1, 2: 2, 3: 4}


def physical_groups() -> dict[str, tuple[int, int]]:
    """The named physical groups of the current gmsh model.

    Returns:
        ``{name: (dim, tag)}`` for every physical group that has a name.
    """
    groups = {}
    for dim, tag in gmsh.model.getPhysicalGroups():
        name = gmsh.model.getPhysicalName(dim, tag)
        if name:
            groups[name] = (dim, tag)
    return groups


def add_group(dim: int, entities: list[int], tag: int, name: str) -> None:
    """A named physical group of the current gmsh model."""
    gmsh.model.addPhysicalGroup(dim, entities, tag)
    gmsh.model.setPhysicalName(dim, tag, name)


def set_output_options() -> None:
    """First-order elements and the .msh 4.1 format for the files these generators write."""
    gmsh.option.setNumber("Mesh.ElementOrder", 1)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)


# ------------------------------------------------------------------------------------------------
# Structured boxes as discrete entities
# ------------------------------------------------------------------------------------------------


def _kuhn_simplices(cells: tuple[int, ...]) -> np.ndarray:
    """Positively oriented Kuhn simplices of a structured grid, as lexicographic node indices.

    Args:
        cells: Number of cells along each axis (2 or 3 axes); node (i, j[, k]) has index
            ``i + (nx + 1) * (j + (ny + 1) * k)``.

    Returns:
        Array (d! * prod(cells), d + 1) of node indices.
    """
    d = len(cells)
    nodes_per_axis = np.array(cells) + 1
    strides = np.concatenate(([1], np.cumprod(nodes_per_axis[:-1])))
    origins = np.stack(np.meshgrid(*[np.arange(c) for c in cells], indexing="ij"), axis=-1)
    origin_index = (origins.reshape(-1, d) * strides).sum(axis=1)
    blocks = []
    for perm in itertools.permutations(range(d)):
        # Walk from the cell's lowest corner to its highest one, one axis at a time.
        offsets = np.concatenate(([0], np.cumsum(strides[list(perm)])))
        inversions = sum(perm[a] > perm[b] for a in range(d) for b in range(a + 1, d))
        if inversions % 2:  # odd permutation: negatively oriented, swap the last two vertices
            offsets[[-2, -1]] = offsets[[-1, -2]]
        blocks.append(origin_index[:, None] + offsets[None, :])
    return np.concatenate(blocks)


def _boundary_facets(simplices: np.ndarray) -> np.ndarray:
    """The facets that belong to one simplex only, oriented with outward normals."""
    d = simplices.shape[1] - 1
    facets = []
    for m in range(d + 1):
        f = np.delete(simplices, m, axis=1)
        if m % 2:  # removing an odd-numbered vertex reverses the orientation
            f[:, [0, 1]] = f[:, [1, 0]]
        facets.append(f)
    facets = np.concatenate(facets)
    # One int64 key per facet (its sorted nodes) and one sort, not np.unique on rows (a sort of
    # row views, the slowest step of building the seed's 2 M-triangle mesh).
    keys = row_keys(facets, int(simplices.max()) + 1)
    order = np.argsort(keys)
    sk = keys[order]
    lone = np.ones(sk.size, dtype=bool)
    lone[1:] &= sk[1:] != sk[:-1]
    lone[:-1] &= sk[:-1] != sk[1:]
    return facets[np.sort(order[lone])]


def add_structured_box(
    lo: tuple[float, ...], hi: tuple[float, ...], cells: tuple[int, ...], first_node_tag: int
) -> tuple[int, dict[tuple[int, int], int], int]:
    """Add a box meshed by Kuhn simplices as discrete gmsh entities.

    The box becomes one discrete entity of dimension d = len(lo) (2 or 3) with one boundary
    entity of dimension d - 1 per side. Nodes on the boundary are classified on the first side
    (in the order x-low, x-high, y-low, ...) that holds them, all others on the box.

    Args:
        lo: The lowest corner.
        hi: The highest corner.
        cells: Number of cells along each axis.
        first_node_tag: The tag of the box's first node; its nodes are numbered consecutively.

    Returns:
        The box's entity tag, its sides as ``{(axis, 0 or 1): entity tag}`` (0 for the low side,
        1 for the high one), and the next free node tag.
    """
    d = len(lo)
    nodes_per_axis = np.array(cells) + 1
    # Multi-index of every node, lexicographic with x running fastest.
    index = np.indices(nodes_per_axis[::-1]).reshape(d, -1)[::-1].T
    coords = np.zeros((index.shape[0], 3))
    for a in range(d):
        coords[:, a] = lo[a] + (hi[a] - lo[a]) * index[:, a] / cells[a]
        coords[index[:, a] == cells[a], a] = hi[a]  # exact end coordinates
    tags = first_node_tag + np.arange(index.shape[0])

    simplices = _kuhn_simplices(tuple(cells))
    facets = _boundary_facets(simplices)

    # Nodes first (each on one entity), then the elements that refer to them. NumPy arrays go
    # to gmsh as they are (its API copies them with ascontiguousarray; lists would be converted
    # element by element).
    sides, side_facets = {}, {}
    unclassified = np.ones(index.shape[0], dtype=bool)
    for a in range(d):
        for s, value in ((0, 0), (1, cells[a])):
            on_side = index[:, a] == value
            nodes = np.flatnonzero(on_side & unclassified)
            unclassified &= ~on_side
            sides[a, s] = gmsh.model.addDiscreteEntity(d - 1)
            gmsh.model.mesh.addNodes(
                d - 1, sides[a, s], tags[nodes], coords[nodes].ravel()
            )
            side_facets[a, s] = facets[on_side[facets].all(axis=1)]
    body = gmsh.model.addDiscreteEntity(d, -1, list(sides.values()))
    gmsh.model.mesh.addNodes(
        d, body, tags[unclassified], coords[unclassified].ravel()
    )
    gmsh.model.mesh.addElementsByType(body, _SIMPLEX_TYPE[d], [], tags[simplices].ravel())
    for key, entity in sides.items():
        gmsh.model.mesh.addElementsByType(
            entity, _SIMPLEX_TYPE[d - 1], [], tags[side_facets[key]].ravel()
        )
    return body, sides, int(tags[-1]) + 1


def membranes(n: int) -> dict[str, tuple[int, int]]:
    """Two unit squares side by side: Dostál's two-membrane problem (benchmark B1).

    "left" = (0,1)² and "right" = (1,2)×(0,1), each an n×n grid of squares, every square split
    into two triangles along its diagonal from (i, j) to (i+1, j+1). Each membrane has its own nodes
    on x = 1, at the same positions.

    Physical groups (dim, tag): "left" (2, 1), "right" (2, 2), "dirichlet" (1, 11) = {0}×[0,1],
    "contact_left" (1, 12) = the x = 1 side of left, "contact_right" (1, 13) = the x = 1 side of
    right.

    Args:
        n: Number of squares along each side of each membrane.

    Returns:
        The physical groups, ``{name: (dim, tag)}``.

    Raises:
        ValueError: If n < 1.
    """
    if n < 1:
        raise ValueError(f"membranes: n must be >= 1, got {n}")
    gmsh.model.add(f"membranes_{n}")
    set_output_options()
    left, left_sides, next_tag = add_structured_box((0.0, 0.0), (1.0, 1.0), (n, n), 1)
    right, right_sides, _ = add_structured_box((1.0, 0.0), (2.0, 1.0), (n, n), next_tag)
    add_group(2, [left], 1, "left")
    add_group(2, [right], 2, "right")
    add_group(1, [left_sides[0, 0]], 11, "dirichlet")
    add_group(1, [left_sides[0, 1]], 12, "contact_left")
    add_group(1, [right_sides[0, 0]], 13, "contact_right")
    return physical_groups()


def blocks3d(
    n: int = 4,
    top_size: tuple[float, float, float] = (1.0, 1.0, 0.5),
    bottom_size: tuple[float, float, float] = (1.0, 1.0, 0.5),
) -> dict[str, tuple[int, int]]:
    """Two stacked boxes meshed by structured tetrahedra (the 3D contact patch test).

    "lower" = [0,Lx]×[0,Ly]×[0,Hb] and "upper" = [0,Lx]×[0,Ly]×[Hb,Hb+Ht] with (Lx, Ly, Hb) =
    bottom_size and (Lx, Ly, Ht) = top_size (defaults: [0,1]²×[0,0.5] and [0,1]²×[0.5,1]). Each
    box has max(1, round(n·L)) cells along an edge of length L, every cube split into six Kuhn
    tetrahedra; both contact faces z = Hb therefore carry the same triangulation, with separate
    nodes at the same positions.

    Physical groups (dim, tag): "lower" (3, 1), "upper" (3, 2), "bottom" (2, 11) = z = 0,
    "top" (2, 12) = z = Hb + Ht, "contact_lower" (2, 13) = the z = Hb face of lower,
    "contact_upper" (2, 14) = the z = Hb face of upper, "sides_upper" (2, 15) and
    "sides_lower" (2, 16) = the four lateral faces of each box.

    Args:
        n: Number of cells per unit length.
        top_size: (Lx, Ly, height) of the upper box.
        bottom_size: (Lx, Ly, height) of the lower box.

    Returns:
        The physical groups, ``{name: (dim, tag)}``.

    Raises:
        ValueError: If n < 1, a size is not positive, or the boxes' footprints differ (the
            contact faces would not match).
    """
    if n < 1:
        raise ValueError(f"blocks3d: n must be >= 1, got {n}")
    if min(*top_size, *bottom_size) <= 0:
        raise ValueError(f"blocks3d: sizes must be positive, got {top_size}, {bottom_size}")
    if tuple(top_size[:2]) != tuple(bottom_size[:2]):
        raise ValueError(
            "blocks3d: the boxes must have the same footprint (Lx, Ly) for matching contact "
            f"faces, got {top_size[:2]} and {bottom_size[:2]}"
        )
    lx, ly, hb = (float(s) for s in bottom_size)
    ht = float(top_size[2])

    def cells(length: float) -> int:
        return max(1, round(n * length))

    gmsh.model.add("blocks3d")
    set_output_options()
    lower, lower_sides, next_tag = add_structured_box(
        (0.0, 0.0, 0.0), (lx, ly, hb), (cells(lx), cells(ly), cells(hb)), 1
    )
    upper, upper_sides, _ = add_structured_box(
        (0.0, 0.0, hb), (lx, ly, hb + ht), (cells(lx), cells(ly), cells(ht)), next_tag
    )
    lateral = [(0, 0), (0, 1), (1, 0), (1, 1)]
    add_group(3, [lower], 1, "lower")
    add_group(3, [upper], 2, "upper")
    add_group(2, [lower_sides[2, 0]], 11, "bottom")
    add_group(2, [upper_sides[2, 1]], 12, "top")
    add_group(2, [lower_sides[2, 1]], 13, "contact_lower")
    add_group(2, [upper_sides[2, 0]], 14, "contact_upper")
    add_group(2, [upper_sides[k] for k in lateral], 15, "sides_upper")
    add_group(2, [lower_sides[k] for k in lateral], 16, "sides_lower")
    return physical_groups()


# ------------------------------------------------------------------------------------------------
# CAD-based, unstructured meshes
# ------------------------------------------------------------------------------------------------


def _contact_zone_sizes(contact_curves: list[int], zone_points: list[int],
                        contact_width: float, h_contact: float, h_far: float) -> None:
    """Matching contact nodes and a graded mesh around the contact zone (the Hertz models).

    One element per contact segment, so the nodes are exactly the given points on both
    sides; size h_contact within 0.2 contact_width of the zone, then growing with the distance
    to it (slope 0.2) up to h_far.
    """
    for curve in contact_curves:
        gmsh.model.mesh.setTransfiniteCurve(curve, 2)
    _threshold_field(
        zone_points,
        size_min=h_contact,
        size_max=h_far,
        dist_min=0.2 * contact_width,
        dist_max=0.2 * contact_width + 5 * (h_far - h_contact),
    )


def _threshold_field(
    points: list[int], size_min: float, size_max: float, dist_min: float, dist_max: float
) -> int:
    """A mesh size field: size_min within dist_min of the points, growing to size_max."""
    field = gmsh.model.mesh.field
    distance = field.add("Distance")
    field.setNumbers(distance, "PointsList", points)
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", size_min)
    field.setNumber(threshold, "SizeMax", size_max)
    field.setNumber(threshold, "DistMin", dist_min)
    field.setNumber(threshold, "DistMax", dist_max)
    field.setAsBackgroundMesh(threshold)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size_max)
    return threshold


def _contact_abscissae(h_contact: float, contact_width: float) -> np.ndarray:
    """x_k = k·h_contact for x_k <= contact_width, then contact_width itself if not yet there."""
    k = math.floor(contact_width / h_contact + 1e-9)
    x = h_contact * np.arange(k + 1)
    if contact_width - x[-1] > 1e-9 * h_contact:
        x = np.append(x, contact_width)
    else:
        x[-1] = contact_width
    return x


def hertz2d(
    h_contact: float = 0.05,
    h_far: float = 1.0,
    R: float = 8.0,
    width: float = 20.0,
    height: float = 20.0,
    contact_width: float = 2.5,
) -> dict[str, tuple[int, int]]:
    """A disk on a block, half model by symmetry about x = 0 (2D Hertz contact, benchmark B2).

    "disk" is the quarter disk {x >= 0, y <= R} of the disk with centre (0, R), which touches
    the block's top y = 0 at the origin; "block" = [0, width/2] × [-height, 0]. In the contact
    zone 0 <= x <= contact_width both bodies have nodes at the same abscissae x_k = k·h_contact
    (and at x = contact_width): on the block's top at (x_k, 0), on the disk's arc exactly on the
    circle, (x_k, R - sqrt(R² - x_k²)). Each body has its own nodes. Away from the contact zone
    the arc and the block's top are meshed more coarsely; the element size grows from h_contact
    near the contact zone to h_far.

    Physical groups (dim, tag): "disk" (2, 1), "block" (2, 2), "disk_contact" (1, 11) = the arc
    with 0 <= x <= contact_width, "block_contact" (1, 12) = the block's top with
    0 <= x <= contact_width, "load" (1, 13) = the disk's flat top y = R, "symmetry" (1, 14) = the
    x = 0 edges of both bodies, "bottom" (1, 15) = y = -height.

    Args:
        h_contact: Node spacing (in x) in the contact zone.
        h_far: Largest element size.
        R: Disk radius.
        width: Width of the full block (the model has half of it).
        height: Height of the block.
        contact_width: Extent in x of the contact zone with matching nodes.

    Returns:
        The physical groups, ``{name: (dim, tag)}``.

    Raises:
        ValueError: If the sizes are inconsistent.
    """
    if not 0 < h_contact <= contact_width < min(R, width / 2):
        raise ValueError(
            "hertz2d: need 0 < h_contact <= contact_width < min(R, width/2), got "
            f"h_contact={h_contact}, contact_width={contact_width}, R={R}, width={width}"
        )
    if h_far < h_contact or height <= 0:
        raise ValueError(f"hertz2d: need h_far >= h_contact and height > 0, got {h_far}, {height}")
    gmsh.model.add("hertz2d")
    set_output_options()
    geo = gmsh.model.geo
    xs = _contact_abscissae(h_contact, contact_width)
    half = width / 2

    # Disk, counter-clockwise: contact arcs, outer arc, flat top, symmetry line.
    centre = geo.addPoint(0.0, R, 0.0)  # also the corner between the flat top and x = 0
    arc_points = [geo.addPoint(x, R - math.sqrt(R * R - x * x), 0.0) for x in xs]
    disk_far = geo.addPoint(R, R, 0.0)
    disk_contact = [
        geo.addCircleArc(a, centre, b) for a, b in zip(arc_points[:-1], arc_points[1:], strict=True)
    ]
    disk_arc = geo.addCircleArc(arc_points[-1], centre, disk_far)
    load = geo.addLine(disk_far, centre)
    disk_symmetry = geo.addLine(centre, arc_points[0])
    disk_loop = geo.addCurveLoop([*disk_contact, disk_arc, load, disk_symmetry])
    disk = geo.addPlaneSurface([disk_loop])

    # Block, counter-clockwise: top (right to left), symmetry line, bottom, right side.
    top_points = [geo.addPoint(x, 0.0, 0.0) for x in xs]
    top_far = geo.addPoint(half, 0.0, 0.0)
    bottom_left = geo.addPoint(0.0, -height, 0.0)
    bottom_right = geo.addPoint(half, -height, 0.0)
    block_top = geo.addLine(top_far, top_points[-1])
    block_contact = [
        geo.addLine(top_points[k + 1], top_points[k]) for k in reversed(range(len(xs) - 1))
    ]
    block_symmetry = geo.addLine(top_points[0], bottom_left)
    bottom = geo.addLine(bottom_left, bottom_right)
    block_side = geo.addLine(bottom_right, top_far)
    block_loop = geo.addCurveLoop([block_top, *block_contact, block_symmetry, bottom, block_side])
    block = geo.addPlaneSurface([block_loop])
    geo.synchronize()

    _contact_zone_sizes(disk_contact + block_contact, arc_points + top_points, contact_width,
                        h_contact, h_far)

    add_group(2, [disk], 1, "disk")
    add_group(2, [block], 2, "block")
    add_group(1, disk_contact, 11, "disk_contact")
    add_group(1, block_contact, 12, "block_contact")
    add_group(1, [load], 13, "load")
    add_group(1, [disk_symmetry, block_symmetry], 14, "symmetry")
    add_group(1, [bottom], 15, "bottom")
    gmsh.model.mesh.generate(2)
    return physical_groups()


def rigid_sphere_cube(
    h: float = 0.05, h_far: float = 0.25, refine_radius: float = 0.2
) -> dict[str, tuple[int, int]]:
    """The quarter cube [0,1]²×[-1,0] of the rigid-sphere indentation case of benchmark B2.

    Unstructured tetrahedra of size h within refine_radius of the origin (the centre of the
    contact on the top face), growing to h_far.

    Physical groups (dim, tag): "cube" (3, 1), "bottom" (2, 11) = z = -1, "symmetry_x" (2, 12)
    = x = 0, "symmetry_y" (2, 13) = y = 0, "top" (2, 14) = z = 0 (the contact surface).

    Args:
        h: Element size near the origin.
        h_far: Largest element size.
        refine_radius: Radius of the refined zone around the origin.

    Returns:
        The physical groups, ``{name: (dim, tag)}``.

    Raises:
        ValueError: If the sizes are not positive or h > h_far.
    """
    if not 0 < h <= h_far or refine_radius <= 0:
        raise ValueError(
            f"rigid_sphere_cube: need 0 < h <= h_far, refine_radius > 0, got "
            f"{h}, {h_far}, {refine_radius}"
        )
    gmsh.model.add("rigid_sphere_cube")
    set_output_options()
    occ = gmsh.model.occ
    cube = occ.addBox(0.0, 0.0, -1.0, 1.0, 1.0, 1.0)
    occ.synchronize()

    eps = 1e-6

    def entities_in(dim: int, lo: tuple[float, ...], hi: tuple[float, ...]) -> list[int]:
        box = (lo[0] - eps, lo[1] - eps, lo[2] - eps, hi[0] + eps, hi[1] + eps, hi[2] + eps)
        return [tag for _, tag in gmsh.model.getEntitiesInBoundingBox(*box, dim)]

    origin = entities_in(0, (0, 0, 0), (0, 0, 0))
    _threshold_field(origin, h, h_far, refine_radius, refine_radius + 4 * (h_far - h))

    add_group(3, [cube], 1, "cube")
    add_group(2, entities_in(2, (0, 0, -1), (1, 1, -1)), 11, "bottom")
    add_group(2, entities_in(2, (0, 0, -1), (0, 1, 0)), 12, "symmetry_x")
    add_group(2, entities_in(2, (0, 0, -1), (1, 0, 0)), 13, "symmetry_y")
    add_group(2, entities_in(2, (0, 0, 0), (1, 1, 0)), 14, "top")
    gmsh.model.mesh.generate(3)
    return physical_groups()


def hertz2d_full(
    h_contact: float = 0.05,
    h_far: float = 1.0,
    R: float = 8.0,
    width: float = 20.0,
    height: float = 20.0,
    contact_width: float = 2.5,
) -> dict[str, tuple[int, int]]:
    """A disk on a block, the full (not symmetric) model of :func:`hertz2d`, for friction.

    "disk" is the lower half {y <= R} of the disk with centre (0, R), which touches the block's
    top y = 0 at the origin; "block" = [-width/2, width/2] × [-height, 0]. In the contact zone
    |x| <= contact_width both bodies have nodes at the same abscissae x_k = ±k·h_contact (and
    at ±contact_width): on the block's top at (x_k, 0), on the disk's arc exactly on the circle.
    The element size grows from h_contact near the contact zone to h_far, as in
    :func:`hertz2d`. A tangential load can be carried (by friction): there is no symmetry line.

    Physical groups (dim, tag): "disk" (2, 1), "block" (2, 2), "disk_contact" (1, 11) = the arc
    with |x| <= contact_width, "block_contact" (1, 12) = the block's top with
    |x| <= contact_width, "load" (1, 13) = the disk's flat top y = R (from x = -R to R),
    "bottom" (1, 14) = y = -height.

    Args:
        h_contact: Node spacing (in x) in the contact zone.
        h_far: Largest element size.
        R: Disk radius.
        width: Width of the block.
        height: Height of the block.
        contact_width: Half-extent in x of the contact zone with matching nodes.

    Returns:
        The physical groups, ``{name: (dim, tag)}``.

    Raises:
        ValueError: If the sizes are inconsistent.
    """
    if not 0 < h_contact <= contact_width < min(R, width / 2):
        raise ValueError(
            "hertz2d_full: need 0 < h_contact <= contact_width < min(R, width/2), got "
            f"h_contact={h_contact}, contact_width={contact_width}, R={R}, width={width}"
        )
    if h_far < h_contact or height <= 0:
        raise ValueError(
            f"hertz2d_full: need h_far >= h_contact and height > 0, got {h_far}, {height}"
        )
    gmsh.model.add("hertz2d_full")
    set_output_options()
    geo = gmsh.model.geo
    half = _contact_abscissae(h_contact, contact_width)
    xs = np.concatenate([-half[:0:-1], half])  # -cw ... 0 ... cw, symmetric
    w2 = width / 2

    # Disk, counter-clockwise: left outer arc, contact arcs (left to right), right outer arc,
    # flat top (right to left).
    centre = geo.addPoint(0.0, R, 0.0)
    left = geo.addPoint(-R, R, 0.0)
    right = geo.addPoint(R, R, 0.0)
    arc_points = [geo.addPoint(x, R - math.sqrt(R * R - x * x), 0.0) for x in xs]
    arc_left = geo.addCircleArc(left, centre, arc_points[0])
    disk_contact = [
        geo.addCircleArc(a, centre, b) for a, b in zip(arc_points[:-1], arc_points[1:], strict=True)
    ]
    arc_right = geo.addCircleArc(arc_points[-1], centre, right)
    load = geo.addLine(right, left)
    disk_loop = geo.addCurveLoop([arc_left, *disk_contact, arc_right, load])
    disk = geo.addPlaneSurface([disk_loop])

    # Block, counter-clockwise: bottom, right side, top (right to left, contact zone inside).
    bl = geo.addPoint(-w2, -height, 0.0)
    br = geo.addPoint(w2, -height, 0.0)
    tr = geo.addPoint(w2, 0.0, 0.0)
    tl = geo.addPoint(-w2, 0.0, 0.0)
    top_points = [geo.addPoint(x, 0.0, 0.0) for x in xs]
    bottom = geo.addLine(bl, br)
    side_r = geo.addLine(br, tr)
    top_r = geo.addLine(tr, top_points[-1])
    block_contact = [
        geo.addLine(top_points[k + 1], top_points[k]) for k in reversed(range(len(xs) - 1))
    ]
    top_l = geo.addLine(top_points[0], tl)
    side_l = geo.addLine(tl, bl)
    block_loop = geo.addCurveLoop([bottom, side_r, top_r, *block_contact, top_l, side_l])
    block = geo.addPlaneSurface([block_loop])
    geo.synchronize()

    _contact_zone_sizes(disk_contact + block_contact, arc_points + top_points, contact_width,
                        h_contact, h_far)

    add_group(2, [disk], 1, "disk")
    add_group(2, [block], 2, "block")
    add_group(1, disk_contact, 11, "disk_contact")
    add_group(1, block_contact, 12, "block_contact")
    add_group(1, [load], 13, "load")
    add_group(1, [bottom], 14, "bottom")
    gmsh.model.mesh.generate(2)
    return physical_groups()


def tresca2d(
    n: int = 8,
    block: tuple[float, float] = (2.0, 1.0),
    foundation: tuple[float, float] | None = (4.0, 1.0),
) -> dict[str, tuple[int, int]]:
    """A block on a wider foundation, structured triangles (the friction benchmark B4).

    "block" = [x0, x0 + Lb] × [0, Hb] with (Lb, Hb) = block and x0 = (Lf − Lb)/2 centring it on
    "foundation" = [0, Lf] × [-Hf, 0] with (Lf, Hf) = foundation (without a foundation, x0 = 0).
    Both are grids of squares of side 1/n split along the diagonal from (i, j) to (i+1, j+1)
    (max(1, round(n·L)) squares along a side of length L), so the block's bottom nodes coincide
    with foundation top nodes when x0 is a multiple of 1/n; each body has its own nodes.

    Physical groups (dim, tag): "block" (2, 2), "top" (1, 12) = the block's top,
    "block_bottom" (1, 14) = its bottom, "block_sides" (1, 15); with a foundation also
    "foundation" (2, 1), "bottom" (1, 11) = y = -Hf, "foundation_top" (1, 13) = y = 0 of the
    foundation, "foundation_sides" (1, 16).

    Args:
        n: Squares per unit length.
        block: (width, height) of the block.
        foundation: (width, height) of the foundation, or None for the block alone.

    Returns:
        The physical groups, ``{name: (dim, tag)}``.

    Raises:
        ValueError: If n < 1, a size is not positive or the block is wider than the foundation.
    """
    if n < 1:
        raise ValueError(f"tresca2d: n must be >= 1, got {n}")
    sizes = [*block, *(foundation or ())]
    if min(sizes) <= 0:
        raise ValueError(f"tresca2d: sizes must be positive, got {block}, {foundation}")
    if foundation is not None and block[0] > foundation[0]:
        raise ValueError(f"tresca2d: the block {block} is wider than the foundation {foundation}")

    def cells(length: float) -> int:
        return max(1, round(n * length))

    gmsh.model.add("tresca2d")
    set_output_options()
    lb, hb = (float(s) for s in block)
    next_tag = 1
    x0 = 0.0
    if foundation is not None:
        lf, hf = (float(s) for s in foundation)
        x0 = 0.5 * (lf - lb)
        fnd, fsides, next_tag = add_structured_box(
            (0.0, -hf), (lf, 0.0), (cells(lf), cells(hf)), 1
        )
    blk, bsides, _ = add_structured_box((x0, 0.0), (x0 + lb, hb), (cells(lb), cells(hb)), next_tag)
    if foundation is not None:
        add_group(2, [fnd], 1, "foundation")
    add_group(2, [blk], 2, "block")
    if foundation is not None:
        add_group(1, [fsides[1, 0]], 11, "bottom")
    add_group(1, [bsides[1, 1]], 12, "top")
    if foundation is not None:
        add_group(1, [fsides[1, 1]], 13, "foundation_top")
    add_group(1, [bsides[1, 0]], 14, "block_bottom")
    add_group(1, [bsides[0, 0], bsides[0, 1]], 15, "block_sides")
    if foundation is not None:
        add_group(1, [fsides[0, 0], fsides[0, 1]], 16, "foundation_sides")
    return physical_groups()
