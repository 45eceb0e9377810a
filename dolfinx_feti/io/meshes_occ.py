"""Models of independently meshed bodies, built the way a gmsh user builds them (OCC kernel).

Each body is its own OCC entity, not fragmented against the others, so each is meshed on its
own by one ``generate`` call: the meshes of two touching bodies do not match on their common
surface. This is what :class:`~dolfinx_feti.Mortar` contact and :class:`~dolfinx_feti.Tie`
gluing are for. Like :mod:`dolfinx_feti.io.meshes`, each function adds a model to the current gmsh
session, names its physical groups, meshes it with first-order simplices, leaves it current
and returns the groups as ``{name: (dim, tag)}``.
"""

from __future__ import annotations

import gmsh
import numpy as np

from .meshes import add_group, physical_groups, set_output_options

_EPS = 1e-7


def _in_box(dim: int, lo, hi) -> list[int]:
    """Entities of dimension ``dim`` inside the box [lo, hi] (padded by a small tolerance)."""
    lo = [*lo, 0.0][:3] if len(lo) == 2 else list(lo)
    hi = [*hi, 0.0][:3] if len(hi) == 2 else list(hi)
    box = [v - _EPS for v in lo] + [v + _EPS for v in hi]
    return [tag for _, tag in gmsh.model.getEntitiesInBoundingBox(*box, dim)]


def _size_in(entities: list[tuple[int, int]], h: float) -> None:
    """Mesh size ``h`` at every point of the given entities."""
    pts = gmsh.model.getBoundary(entities, combined=False, recursive=True)
    gmsh.model.mesh.setSize(pts, h)


def _sizes_from_points() -> None:
    """Mesh sizes from the points only (another model of the session may have changed this)."""
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 1)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 1e22)


def _graded_sizes(bodies: list[tuple[int, float]], dim: int, h_far: float, refine: float) -> None:
    """Per body: size h within ``refine`` of the origin, growing to h_far (slope 0.2)."""
    origin = [t for _, t in gmsh.model.getEntitiesInBoundingBox(
        -_EPS, -_EPS, -_EPS, _EPS, _EPS, _EPS, 0)]
    field = gmsh.model.mesh.field
    fields = []
    for ent, h in bodies:
        dist = field.add("Distance")
        field.setNumbers(dist, "PointsList", origin)
        thr = field.add("Threshold")
        field.setNumber(thr, "InField", dist)
        field.setNumber(thr, "SizeMin", h)
        field.setNumber(thr, "SizeMax", h_far)
        field.setNumber(thr, "DistMin", refine)
        field.setNumber(thr, "DistMax", refine + 5 * (h_far - h))
        restrict = field.add("Restrict")
        field.setNumber(restrict, "InField", thr)
        below = gmsh.model.getBoundary([(dim, ent)], combined=False, oriented=False,
                                       recursive=False)
        if dim == 2:
            field.setNumbers(restrict, "SurfacesList", [ent])
            field.setNumbers(restrict, "CurvesList", [abs(t) for _, t in below])
        else:
            field.setNumbers(restrict, "VolumesList", [ent])
            field.setNumbers(restrict, "SurfacesList", [abs(t) for _, t in below])
            curves = gmsh.model.getBoundary(below, combined=False, oriented=False)
            field.setNumbers(restrict, "CurvesList", sorted({abs(t) for _, t in curves}))
        fields.append(restrict)
    mini = field.add("Min")
    field.setNumbers(mini, "FieldsList", fields)
    field.setAsBackgroundMesh(mini)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h_far)


def _transfinite(dim: int, body: int, h: float) -> None:
    """A structured grid of quadrilaterals/hexahedra of about size h in a box-shaped body."""
    faces = gmsh.model.getBoundary([(dim, body)], combined=False, oriented=False)
    surfaces = [t for _, t in faces] if dim == 3 else [body]
    curves = {abs(t) for _, t in gmsh.model.getBoundary(
        [(2, s) for s in surfaces], combined=False, oriented=False)}
    for c in sorted(curves):
        length = gmsh.model.occ.getMass(1, c)
        gmsh.model.mesh.setTransfiniteCurve(c, max(int(round(length / h)), 1) + 1)
    for s_ in surfaces:
        gmsh.model.mesh.setTransfiniteSurface(s_)
        gmsh.model.mesh.setRecombine(2, s_)
    if dim == 3:
        gmsh.model.mesh.setTransfiniteVolume(body)


def _graded_hexahedra(box: int, h0: float, ratio: float) -> None:
    """A box of hexahedra, its edges graded geometrically from h0 at the coordinate planes.

    Each edge starts at size h0 at its end nearer the plane x = 0, y = 0 or z = 0 it is
    normal to (boxes with a corner at the origin) and grows by ``ratio`` per element.
    """
    mesh = gmsh.model.mesh
    faces = gmsh.model.getBoundary([(3, box)], combined=False, oriented=False)
    curves = sorted({abs(t) for _, t in gmsh.model.getBoundary(faces, combined=False,
                                                               oriented=False)})
    for c in curves:
        a, b = (gmsh.model.getValue(0, abs(t), []) for _, t in
                gmsh.model.getBoundary([(1, c)], combined=False, oriented=True))
        axis = int(np.argmax(np.abs(b - a)))
        length = abs(b[axis] - a[axis])
        n = max(int(np.ceil(np.log(1.0 + length * (ratio - 1.0) / h0) / np.log(ratio))), 1)
        coef = ratio if abs(a[axis]) < abs(b[axis]) else 1.0 / ratio  # small at the plane
        mesh.setTransfiniteCurve(c, n + 1, "Progression", coef)
    for _, f in faces:
        mesh.setTransfiniteSurface(f)
        mesh.setRecombine(2, f)
    mesh.setTransfiniteVolume(box)


def stacked_blocks(dim: int = 2, h_lower: float = 0.1, h_upper: float = 0.17,
                   width: float = 1.0, height: float = 1.0, gap: float = 0.0,
                   recombine: bool | str = False) -> dict:
    """Two boxes, one on top of the other, meshed independently (non-matching interface).

    "lower" = [0, width]^(dim−1) × [0, height], "upper" the same box shifted up by
    height + gap (the last coordinate is vertical). Unstructured simplices of size h_lower and
    h_upper, or with ``recombine`` structured (transfinite) quadrilaterals or hexahedra of
    about those sizes.

    Physical groups: bodies "lower" (tag 1) and "upper" (2); boundary groups "bottom" (11, the
    lower box's base), "lower_top" (12), "upper_bottom" (13), "top" (14, the upper box's top),
    "sym0" (15, the faces x = 0 of both boxes) and in 3D "sym1" (16, the faces y = 0).

    Args:
        dim: 2 or 3.
        h_lower: Element size of the lower box.
        h_upper: Element size of the upper box.
        width: Horizontal size of the boxes.
        height: Vertical size of the boxes.
        gap: Initial gap between the boxes.
        recombine: Quadrilaterals (2D) or hexahedra (3D) instead of simplices; a body's
            name (``"lower"`` or ``"upper"``) for that body only (a model of two cell types).
    """
    if dim not in (2, 3) or min(h_lower, h_upper, width, height) <= 0 or gap < 0:
        raise ValueError(f"stacked_blocks: bad sizes dim={dim}, h={h_lower}/{h_upper}, "
                         f"width={width}, height={height}, gap={gap}")
    gmsh.model.add("stacked_blocks")
    set_output_options()
    occ = gmsh.model.occ
    z1 = height + gap
    if dim == 2:
        lower = occ.addRectangle(0.0, 0.0, 0.0, width, height)
        upper = occ.addRectangle(0.0, z1, 0.0, width, height)
    else:
        lower = occ.addBox(0.0, 0.0, 0.0, width, width, height)
        upper = occ.addBox(0.0, 0.0, z1, width, width, height)
    occ.synchronize()
    # Sizes from the points only (another model of the session may have changed the options).
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 1)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 1e22)
    _size_in([(dim, lower)], h_lower)
    _size_in([(dim, upper)], h_upper)
    if recombine not in (False, True, "lower", "upper"):
        raise ValueError(f"stacked_blocks: recombine={recombine!r}: expected a bool, "
                         "'lower' or 'upper'")
    for name, body, h in (("lower", lower, h_lower), ("upper", upper, h_upper)):
        if recombine is True or recombine == name:
            _transfinite(dim, body, h)
    top = z1 + height
    w = [width] * (dim - 1)
    z = [0.0] * (dim - 1)

    def at(level: float) -> tuple[list[float], list[float]]:
        return [*z, level], [*w, level]

    add_group(dim, [lower], 1, "lower")
    add_group(dim, [upper], 2, "upper")
    add_group(dim - 1, _in_box(dim - 1, *at(0.0)), 11, "bottom")
    add_group(dim - 1, [e for e in _in_box(dim - 1, *at(height))
                         if (dim - 1, e) in gmsh.model.getBoundary([(dim, lower)])
                         or (dim - 1, -e) in gmsh.model.getBoundary([(dim, lower)])],
               12, "lower_top")
    add_group(dim - 1, [e for e in _in_box(dim - 1, *at(z1))
                         if abs(e) in [abs(t) for _, t in gmsh.model.getBoundary([(dim, upper)])]],
               13, "upper_bottom")
    add_group(dim - 1, _in_box(dim - 1, *at(top)), 14, "top")
    lo, hi = [0.0] * dim, [0.0] + [width] * (dim - 2) + [top]
    add_group(dim - 1, _in_box(dim - 1, lo, hi), 15, "sym0")
    if dim == 3:
        add_group(2, _in_box(2, [0.0, 0.0, 0.0], [width, 0.0, top]), 16, "sym1")
    gmsh.model.mesh.generate(dim)
    return physical_groups()


def disk_on_block(h_contact_disk: float = 0.1, h_contact_block: float = 0.17,
                  h_far: float = 1.0, R: float = 8.0, width: float = 20.0,
                  height: float = 20.0, refine: float = 2.5,
                  recombine: str | None = None) -> dict:
    """2D Hertz, half model: a quarter disk on a block, each meshed on its own.

    The geometry of :func:`dolfinx_feti.io.meshes.hertz2d` (disk of radius R centred at (0, R)
    touching the block's top y = 0 at the origin; symmetry about x = 0), but with no matching
    nodes: each body is an OCC surface meshed with its own size near the contact
    (h_contact_disk, h_contact_block within ``refine`` of the origin, growing to h_far).

    Physical groups: "disk" (2, 1), "block" (2, 2), "disk_contact" (1, 11) = the whole arc,
    "block_contact" (1, 12) = the whole top of the block, "load" (1, 13) = the disk's flat top
    y = R, "symmetry" (1, 14) = the x = 0 edges, "bottom" (1, 15) = y = −height.

    ``recombine``: ``"block"`` or ``"disk"`` meshes that body with quadrilaterals (a model of
    two cell types), None both with triangles.
    """
    if not 0 < max(h_contact_disk, h_contact_block) <= h_far or refine <= 0:
        raise ValueError("disk_on_block: need 0 < h_contact <= h_far and refine > 0")
    if recombine not in (None, "block", "disk"):
        raise ValueError(f"disk_on_block: recombine={recombine!r}: expected None, 'block' or "
                         "'disk'")
    gmsh.model.add("disk_on_block")
    set_output_options()
    occ = gmsh.model.occ
    disk_full = occ.addDisk(0.0, R, 0.0, R, R)
    quarter = occ.addRectangle(0.0, 0.0, 0.0, R, R)
    (disk_dt, _) = occ.intersect([(2, disk_full)], [(2, quarter)])
    disk = disk_dt[0][1]
    block = occ.addRectangle(0.0, -height, 0.0, width / 2, height)
    occ.synchronize()
    disk_curves = [abs(t) for _, t in gmsh.model.getBoundary([(2, disk)], oriented=False)]
    block_curves = [abs(t) for _, t in gmsh.model.getBoundary([(2, block)], oriented=False)]

    def centre(c: int) -> tuple[float, float]:
        cx, cy, _ = gmsh.model.occ.getCenterOfMass(1, c)
        return cx, cy

    tol = 1e-6 * max(R, width, height)
    load = [c for c in disk_curves if abs(centre(c)[1] - R) < tol]
    disk_sym = [c for c in disk_curves if abs(centre(c)[0]) < tol]
    arc = [c for c in disk_curves if c not in load + disk_sym]
    top = [c for c in block_curves if abs(centre(c)[1]) < tol]
    block_sym = [c for c in block_curves if abs(centre(c)[0]) < tol]
    bottom = [c for c in block_curves if abs(centre(c)[1] + height) < tol]
    _graded_sizes([(disk, h_contact_disk), (block, h_contact_block)], 2, h_far, refine)
    add_group(2, [disk], 1, "disk")
    add_group(2, [block], 2, "block")
    add_group(1, arc, 11, "disk_contact")
    add_group(1, top, 12, "block_contact")
    add_group(1, load, 13, "load")
    add_group(1, disk_sym + block_sym, 14, "symmetry")
    add_group(1, bottom, 15, "bottom")
    if recombine is not None:  # all quadrilaterals (Blossom's full-quad recombination)
        gmsh.option.setNumber("Mesh.RecombinationAlgorithm", 3)
        gmsh.model.mesh.setRecombine(2, block if recombine == "block" else disk)
    gmsh.model.mesh.generate(2)
    return physical_groups()


def sphere_on_block(h_contact_sphere: float = 0.15, h_contact_block: float = 0.25,
                    h_far: float = 2.0, R: float = 8.0, width: float = 16.0,
                    height: float = 8.0, refine: float = 1.5,
                    recombine: str | None = None) -> dict:
    """3D Hertz, quarter model: a hemisphere on a block, each meshed on its own.

    The lower half of the ball of radius R centred at (0, 0, R), cut to x, y >= 0, touches the
    top z = 0 of the block [0, width/2]² × [−height, 0] at the origin. Each body is an OCC
    volume meshed with its own size near the contact (within ``refine`` of the origin),
    growing to h_far; the meshes do not match.

    Physical groups: "sphere" (3, 1), "block" (3, 2), "sphere_contact" (2, 11) = the whole
    spherical surface, "block_contact" (2, 12) = the whole top of the block, "load" (2, 13) =
    the flat top z = R of the hemisphere, "sym_x" (2, 14) = the faces x = 0, "sym_y" (2, 15)
    = the faces y = 0, "bottom" (2, 16) = z = −height.

    ``recombine="block"``: the block of hexahedra instead (a model of two cell types), a
    structured grid graded from h_contact_block at the planes x = 0, y = 0 and z = 0 by a
    factor 1.15 per element.
    """
    if not 0 < max(h_contact_sphere, h_contact_block) <= h_far or refine <= 0:
        raise ValueError("sphere_on_block: need 0 < h_contact <= h_far and refine > 0")
    if recombine not in (None, "block"):
        raise ValueError(f"sphere_on_block: recombine={recombine!r}: expected None or "
                         "'block'")
    gmsh.model.add("sphere_on_block")
    set_output_options()
    occ = gmsh.model.occ
    ball = occ.addSphere(0.0, 0.0, R, R)
    box = occ.addBox(0.0, 0.0, 0.0, R, R, R)
    (dt, _) = occ.intersect([(3, ball)], [(3, box)])
    sphere = dt[0][1]
    block = occ.addBox(0.0, 0.0, -height, width / 2, width / 2, height)
    occ.synchronize()
    tol = 1e-6 * max(R, width, height)

    def faces(body: int) -> list[int]:
        return [abs(t) for _, t in gmsh.model.getBoundary([(3, body)], oriented=False)]

    def centre(f: int) -> tuple[float, float, float]:
        return gmsh.model.occ.getCenterOfMass(2, f)

    sym_x = [f for b in (sphere, block) for f in faces(b) if abs(centre(f)[0]) < tol]
    sym_y = [f for b in (sphere, block) for f in faces(b) if abs(centre(f)[1]) < tol]
    load = [f for f in faces(sphere) if abs(centre(f)[2] - R) < tol]
    curved = [f for f in faces(sphere) if f not in sym_x + sym_y + load]
    top = [f for f in faces(block) if abs(centre(f)[2]) < tol]
    bottom = [f for f in faces(block) if abs(centre(f)[2] + height) < tol]
    _graded_sizes([(sphere, h_contact_sphere), (block, h_contact_block)], 3, h_far, refine)
    add_group(3, [sphere], 1, "sphere")
    add_group(3, [block], 2, "block")
    add_group(2, curved, 11, "sphere_contact")
    add_group(2, top, 12, "block_contact")
    add_group(2, load, 13, "load")
    add_group(2, sym_x, 14, "sym_x")
    add_group(2, sym_y, 15, "sym_y")
    add_group(2, bottom, 16, "bottom")
    if recombine == "block":
        _graded_hexahedra(block, h_contact_block, 1.15)
    gmsh.model.mesh.generate(3)
    return physical_groups()


def slab_with_inclusions(h_matrix: float = 0.05, h_inclusion: float = 0.03,
                         h_foundation: float = 0.08, conforming: bool = False,
                         length: float = 2.0, thickness: float = 0.6, load_length: float = 0.8,
                         inclusions: tuple[tuple[float, float, float], ...] = (
                             (0.4, 0.3, 0.18), (1.0, 0.3, 0.18), (1.6, 0.3, 0.18)),
                         foundation: tuple[float, float] = (3.0, 1.0)) -> dict:
    """2D, half model: a composite slab (a matrix with disk inclusions) on a foundation block.

    The slab [0, length] × [0, thickness] holds round inclusions (x, y, radius); it lies on
    the block [0, foundation[0]] × [−foundation[1], 0], which is meshed on its own (the contact
    surfaces do not match). With ``conforming=False`` the matrix has holes cut out of it and
    each inclusion is a disk added afterwards, not fragmented against the matrix: the holes and
    the inclusions are meshed independently (sizes h_matrix and h_inclusion), a non-conforming
    interface to glue with :class:`~dolfinx_feti.Tie`. With ``conforming=True`` the slab is
    fragmented instead: inclusions and matrix share their boundary curves and nodes (the
    reference for a tie; the inclusions are then meshed with h_matrix on their boundary).

    Physical groups: bodies "matrix" (2, 1), "inclusions" (2, 2), "foundation" (2, 3);
    boundaries "load" (1, 11) = the slab's top on [0, load_length], "slab_bottom" (1, 12),
    "foundation_top" (1, 13), "symmetry" (1, 14) = the x = 0 edges of the slab and of the
    block, "bottom" (1, 15) = the block's base, and with ``conforming=False`` "holes" (1, 16)
    = the matrix's hole boundaries and "inclusion_surface" (1, 17) = the inclusions' own
    boundaries.
    """
    if min(h_matrix, h_inclusion, h_foundation, length, thickness, *foundation) <= 0 or \
            not 0 < load_length < length:
        raise ValueError("slab_with_inclusions: need positive sizes and 0 < load_length < length")
    for xc, yc, r in inclusions:
        if not (r < xc < length - r and r < yc < thickness - r):
            raise ValueError(f"slab_with_inclusions: inclusion {(xc, yc, r)} is not inside the "
                             "slab")
    gmsh.model.add("slab_with_inclusions")
    set_output_options()
    occ = gmsh.model.occ
    # The outline as a polygon whose top is two curves: the loaded part and the rest.
    corners = [(0.0, 0.0), (length, 0.0), (length, thickness), (load_length, thickness),
               (0.0, thickness)]
    pts = [occ.addPoint(x, y, 0.0) for x, y in corners]
    lines = [occ.addLine(pts[k], pts[(k + 1) % len(pts)]) for k in range(len(pts))]
    slab = occ.addPlaneSurface([occ.addCurveLoop(lines)])
    disks = [(2, occ.addDisk(xc, yc, 0.0, r, r)) for xc, yc, r in inclusions]
    if conforming:
        out, _ = occ.fragment([(2, slab)], disks)
    else:
        out, _ = occ.cut([(2, slab)], disks)  # holes; the disks are removed with the tool
        disks = [(2, occ.addDisk(xc, yc, 0.0, r, r)) for xc, yc, r in inclusions]
    block = occ.addRectangle(0.0, -foundation[1], 0.0, foundation[0], foundation[1])
    occ.synchronize()
    tol = 1e-6 * max(length, *foundation)

    def centre(dim: int, tag: int) -> tuple[float, float, float]:
        return gmsh.model.occ.getCenterOfMass(dim, tag)

    def curves(surfaces: list[int]) -> list[int]:
        return sorted({abs(t) for s in surfaces
                       for _, t in gmsh.model.getBoundary([(2, s)], oriented=False)})

    def is_inclusion(tag: int, dim: int = 2) -> bool:
        # by the bounding box: a centroid is ambiguous (the matrix may have the same)
        x0, y0, _, x1, y1, _ = gmsh.model.getBoundingBox(dim, tag)
        return any(abs(x0 - (xc - r)) < tol and abs(x1 - (xc + r)) < tol
                   and abs(y0 - (yc - r)) < tol and abs(y1 - (yc + r)) < tol
                   for xc, yc, r in inclusions)

    slab_faces = [t for _, t in gmsh.model.getEntities(2) if t != block]
    inc = [t for t in slab_faces if is_inclusion(t)]
    matrix = [t for t in slab_faces if t not in inc]
    m_curves, i_curves, b_curves = curves(matrix), curves(inc), curves([block])
    holes = [c for c in m_curves if is_inclusion(c, 1)]
    straight = [c for c in m_curves if c not in holes]

    def on(cs: list[int], axis: int, value: float) -> list[int]:
        return [c for c in cs if abs(centre(1, c)[axis] - value) < tol]

    load = [c for c in on(straight, 1, thickness) if centre(1, c)[0] < load_length]
    _sizes_from_points()
    if conforming:
        _size_in([(2, t) for t in matrix + inc], h_matrix)
        _size_in([(2, t) for t in inc], h_matrix)
    else:
        _size_in([(2, t) for t in matrix], h_matrix)
        _size_in([(2, t) for t in inc], h_inclusion)
    _size_in([(2, block)], h_foundation)
    add_group(2, matrix, 1, "matrix")
    add_group(2, inc, 2, "inclusions")
    add_group(2, [block], 3, "foundation")
    add_group(1, load, 11, "load")
    add_group(1, on(straight, 1, 0.0), 12, "slab_bottom")
    add_group(1, on(b_curves, 1, 0.0), 13, "foundation_top")
    add_group(1, on(straight, 0, 0.0) + on(b_curves, 0, 0.0), 14, "symmetry")
    add_group(1, on(b_curves, 1, -foundation[1]), 15, "bottom")
    if not conforming:
        add_group(1, holes, 16, "holes")
        add_group(1, i_curves, 17, "inclusion_surface")
    gmsh.model.mesh.generate(2)
    return physical_groups()




def punch_on_block(h_punch: float = 0.15, h_block: float = 0.25, R: float = 1.0,
                   height: float = 1.0, fillet: float = 0.25, width: float = 4.0,
                   depth: float = 1.5, half: bool = False) -> dict:
    """A cylinder (axis z) with a filleted bottom edge on the top z = 0 of a block.

    The punch is the cylinder of radius R over [0, height] whose bottom edge is rounded with
    radius ``fillet`` (its flat bottom, of radius R − fillet, touches the block); the block is
    [−width/2, width/2]² × [−depth, 0]. With ``half`` both are cut to y >= 0: the half model
    with the symmetry plane y = 0 through the contact zone (a lateral load along x keeps that
    symmetry). Each body is meshed on its own with size h_punch or h_block.

    Physical groups: bodies "punch" (3, 1), "block" (3, 2); "punch_contact" (2, 11) = the
    punch's flat bottom and fillet, "block_contact" (2, 12) = the block's top, "load" (2, 13)
    = the punch's top z = height, "bottom" (2, 14) = z = −depth, with ``half`` "symmetry"
    (2, 15) = the faces y = 0 of both bodies.
    """
    if not (0 < fillet < R and min(h_punch, h_block, height, depth) > 0 and width > 2 * R):
        raise ValueError(f"punch_on_block: need 0 < fillet < R, positive sizes and width > 2R "
                         f"(R={R}, fillet={fillet}, width={width})")
    gmsh.model.add("punch_on_block")
    set_output_options()
    occ = gmsh.model.occ
    cyl = occ.addCylinder(0.0, 0.0, 0.0, 0.0, 0.0, height, R)
    occ.synchronize()
    curves = [abs(t) for _, t in gmsh.model.getBoundary([(3, cyl)], combined=False,
                                                         oriented=False, recursive=False)]
    edges = {abs(t) for _, t in gmsh.model.getBoundary([(2, f) for f in curves],
                                                        combined=False, oriented=False)}
    bottom_edge = [e for e in edges if abs(occ.getCenterOfMass(1, e)[2]) < 1e-9
                   and occ.getMass(1, e) > 1e-9]
    punch = occ.fillet([cyl], bottom_edge, [fillet])[0][1]
    block = occ.addBox(-width / 2, -width / 2, -depth, width, width, depth)
    if half:
        # one cut per body: a boolean on both at once would make them share the contact face
        def halved(body: int) -> int:
            cut = occ.addBox(-width, -2 * width, -2 * depth, 2 * width, 2 * width,
                             2 * (depth + height))
            return occ.cut([(3, body)], [(3, cut)])[0][0][1]

        punch, block = halved(punch), halved(block)
    occ.synchronize()
    tol = 1e-6 * max(R, width, height, depth)

    def faces(body: int) -> list[int]:
        return [abs(t) for _, t in gmsh.model.getBoundary([(3, body)], oriented=False)]

    def bbox(f: int) -> tuple[float, ...]:
        return gmsh.model.getBoundingBox(2, f)

    sym = [f for b in (punch, block) for f in faces(b) if half and abs(bbox(f)[1]) < tol
           and abs(bbox(f)[4]) < tol]
    load = [f for f in faces(punch) if abs(bbox(f)[2] - height) < tol]
    contact = [f for f in faces(punch) if f not in sym + load and bbox(f)[5] < fillet + tol]
    top = [f for f in faces(block) if abs(bbox(f)[5]) < tol and abs(bbox(f)[2]) < tol]
    bottom = [f for f in faces(block) if abs(bbox(f)[2] + depth) < tol
              and abs(bbox(f)[5] + depth) < tol]
    _sizes_from_points()
    _size_in([(3, punch)], h_punch)
    _size_in([(3, block)], h_block)
    add_group(3, [punch], 1, "punch")
    add_group(3, [block], 2, "block")
    add_group(2, contact, 11, "punch_contact")
    add_group(2, top, 12, "block_contact")
    add_group(2, load, 13, "load")
    add_group(2, bottom, 14, "bottom")
    if half:
        add_group(2, sym, 15, "symmetry")
    gmsh.model.mesh.generate(3)
    return physical_groups()


__all__ = ["disk_on_block", "punch_on_block", "slab_with_inclusions", "sphere_on_block",
           "stacked_blocks"]
