"""gmsh generators of soft bodies for large-deformation contact (rubber cylinder, hemisphere)."""

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


__all__ = ["quarter_disk"]
