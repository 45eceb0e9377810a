"""gmsh generators of soft bodies for large-deformation contact (cylinder, hemisphere, ironing)."""

from __future__ import annotations

import gmsh

from .meshes import add_group, physical_groups, set_output_options


def quarter_disk(R: float = 1.0, h_contact: float = 0.03, h_far: float = 0.15
                 ) -> dict[str, tuple[int, int]]:
    """The quarter disk {x >= 0, y <= 0, x² + y² <= R²}: half of a cylinder's lower half.

    The cylinder of radius R, centre at the origin, touches the plane y = −R at (0, −R); by
    symmetry the model is its part x >= 0 below its centre line. Elements of size
    ``h_contact`` at the lowest point, growing to ``h_far``.

    Physical groups: "body" (2, 1); "axis" (1, 11) the edge x = 0; "top" (1, 12) the edge
    y = 0; "arc" (1, 13) the circular arc.
    """
    if not 0 < h_contact <= h_far < R:
        raise ValueError(f"quarter_disk: need 0 < h_contact <= h_far < R, got {h_contact}, "
                         f"{h_far}, {R}")
    gmsh.model.add("quarter_disk")
    set_output_options()
    geo = gmsh.model.geo
    c = geo.addPoint(0, 0, 0, h_far)
    bottom = geo.addPoint(0, -R, 0, h_contact)
    right = geo.addPoint(R, 0, 0, h_far)
    axis = geo.addLine(c, bottom)
    arc = geo.addCircleArc(bottom, c, right)
    top = geo.addLine(right, c)
    loop = geo.addCurveLoop([axis, arc, top])
    surface = geo.addPlaneSurface([loop])
    geo.synchronize()
    add_group(2, [surface], 1, "body")
    add_group(1, [axis], 11, "axis")
    add_group(1, [top], 12, "top")
    add_group(1, [arc], 13, "arc")
    gmsh.model.mesh.generate(2)
    return physical_groups()


def quarter_hemisphere(R: float = 1.0, h_contact: float = 0.06, h_far: float = 0.25
                       ) -> dict[str, tuple[int, int]]:
    """A quarter of the lower half ball {x >= 0, y >= 0, z <= 0, |x| <= R} (tetrahedra).

    The ball of radius R, centre at the origin, touches the plane z = −R at (0, 0, −R).
    Elements of size ``h_contact`` at the lowest point, growing linearly to ``h_far`` at a
    distance R from it.

    Physical groups: "body" (3, 1); "x0" (2, 11) and "y0" (2, 12) the symmetry planes; "top"
    (2, 13) the face z = 0; "sphere" (2, 14) the spherical surface.
    """
    if not 0 < h_contact <= h_far < R:
        raise ValueError(f"quarter_hemisphere: need 0 < h_contact <= h_far < R, got "
                         f"{h_contact}, {h_far}, {R}")
    gmsh.model.add("quarter_hemisphere")
    set_output_options()
    occ = gmsh.model.occ
    ball = occ.addSphere(0, 0, 0, R)
    box = occ.addBox(0, 0, -R, R, R, R)
    (vol,), _ = occ.intersect([(3, ball)], [(3, box)])
    occ.synchronize()
    add_group(3, [vol[1]], 1, "body")
    faces = {"x0": [], "y0": [], "top": [], "sphere": []}
    for _, f in gmsh.model.getBoundary([vol], oriented=False):
        c = occ.getCenterOfMass(2, f)
        name = "x0" if abs(c[0]) < 1e-9 else "y0" if abs(c[1]) < 1e-9 else \
            "top" if abs(c[2]) < 1e-9 else "sphere"
        faces[name].append(f)
    for k, (name, ents) in enumerate(faces.items()):
        add_group(2, ents, 11 + k, name)
    field = gmsh.model.mesh.field
    dist = field.add("MathEval")
    field.setString(dist, "F", f"{h_contact} + ({h_far} - {h_contact}) * "
                    f"Min(1, Sqrt(x*x + y*y + (z + {R})*(z + {R})) / {R})")
    field.setAsBackgroundMesh(dist)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.model.mesh.generate(3)
    return physical_groups()


def ironing_block(lx: float = 9.0, ly: float = 3.0, h_top: float = 0.15, h_far: float = 0.6
                  ) -> dict[str, tuple[int, int]]:
    """The soft block of the ironing problem: [0, lx] × [0, ly], finer towards its top.

    Elements of size ``h_top`` along the top (where the die slides), growing linearly to
    ``h_far`` at the bottom.

    Physical groups: "body" (2, 1); "bottom" (1, 11), "right" (1, 12), "top" (1, 13),
    "left" (1, 14).
    """
    if not 0 < h_top <= h_far < min(lx, ly):
        raise ValueError(f"ironing_block: need 0 < h_top <= h_far < min(lx, ly), got {h_top}, "
                         f"{h_far}, {lx}, {ly}")
    gmsh.model.add("ironing_block")
    set_output_options()
    geo = gmsh.model.geo
    p = [geo.addPoint(x, y, 0, h_far if y == 0 else h_top)
         for x, y in ((0, 0), (lx, 0), (lx, ly), (0, ly))]
    lines = [geo.addLine(p[i], p[(i + 1) % 4]) for i in range(4)]
    surface = geo.addPlaneSurface([geo.addCurveLoop(lines)])
    geo.synchronize()
    add_group(2, [surface], 1, "body")
    for k, name in enumerate(("bottom", "right", "top", "left")):
        add_group(1, [lines[k]], 11 + k, name)
    gmsh.model.mesh.generate(2)
    return physical_groups()


__all__ = ["ironing_block", "quarter_disk", "quarter_hemisphere"]
