"""A slider (flat or with a rounded bottom) on a wider block, meshed apart (gmsh, rank 0).

For mortar friction under large deformation: the slider's bottom stays on the block's top
while it slides over several elements, and the two meshes do not match.
"""

from __future__ import annotations

import gmsh

from dolfinx_feti.io.meshes import physical_groups


def _group(dim: int, ents: list[int], tag: int, name: str) -> None:
    gmsh.model.addPhysicalGroup(dim, ents, tag)
    gmsh.model.setPhysicalName(dim, tag, name)


def slider_on_block(length: float = 3.0, height: float = 1.0, x0: float = 0.5,
                    width: float = 1.0, slider_height: float = 0.5, radius: float = 0.0,
                    h_block: float = 0.2, h_slider: float = 0.13) -> dict:
    """A block [0, length] × [0, height] and a slider on it, meshed apart with triangles.

    The slider spans [x0, x0 + width] × [height, height + slider_height]; with ``radius`` > 0
    its bottom is the circular arc of that radius through (x0, height + sag) and
    (x0 + width, height + sag) touching y = height at its middle (a die), else flat.

    Groups: "block" (2, 1), "slider" (2, 2); "bottom" (11, y = 0), "block_top" (12),
    "slider_bottom" (13, the flat or rounded bottom), "slider_top" (14).
    """
    gmsh.model.add("slider_on_block")
    occ = gmsh.model.occ
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 1)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 1)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 1e22)
    block = occ.addRectangle(0.0, 0.0, 0.0, length, height)
    x1, top = x0 + width, height + slider_height
    if radius > 0:
        half = 0.5 * width
        if radius <= half:
            raise ValueError("slider_on_block: the radius must exceed half the width")
        sag = radius - (radius ** 2 - half ** 2) ** 0.5
        pts = [occ.addPoint(x0, height + sag, 0), occ.addPoint(x0 + half, height, 0),
               occ.addPoint(x1, height + sag, 0), occ.addPoint(x1, top, 0),
               occ.addPoint(x0, top, 0)]
        centre = occ.addPoint(x0 + half, height + radius, 0)
        arcs = [occ.addCircleArc(pts[0], centre, pts[1]), occ.addCircleArc(pts[1], centre, pts[2])]
        lines = [occ.addLine(pts[2], pts[3]), occ.addLine(pts[3], pts[4]),
                 occ.addLine(pts[4], pts[0])]
        slider = occ.addPlaneSurface([occ.addCurveLoop([*arcs, *lines])])
    else:
        slider = occ.addRectangle(x0, height, 0.0, width, slider_height)
    occ.synchronize()
    for body, h in ((block, h_block), (slider, h_slider)):
        pts = gmsh.model.getBoundary([(2, body)], recursive=True)
        gmsh.model.mesh.setSize(pts, h)
    eps = 1e-7 * (height + slider_height)

    def curves(body: int, pick) -> list[int]:
        """The curves of ``body`` whose centre of mass (x, y) and extent in x ``pick`` takes."""
        out = []
        for _, c in gmsh.model.getBoundary([(2, body)], oriented=False):
            x, y, _ = occ.getCenterOfMass(1, abs(c))
            xmin, _, _, xmax, _, _ = gmsh.model.getBoundingBox(1, abs(c))
            if pick(x, y, xmax - xmin > 1e-3 * width):
                out.append(abs(c))
        return out

    mid = height + 0.5 * slider_height
    _group(2, [block], 1, "block")
    _group(2, [slider], 2, "slider")
    _group(1, curves(block, lambda x, y, wide: wide and y < eps), 11, "bottom")
    _group(1, curves(block, lambda x, y, wide: wide and y > height - eps), 12, "block_top")
    _group(1, curves(slider, lambda x, y, wide: wide and y < mid), 13, "slider_bottom")
    _group(1, curves(slider, lambda x, y, wide: wide and y > top - eps), 14, "slider_top")
    gmsh.model.mesh.generate(2)
    return physical_groups()
