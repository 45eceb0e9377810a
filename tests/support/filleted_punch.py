"""A flat punch with filleted corners on a block (2D), each body meshed on its own.

The punch [−w/2, w/2] × [0, H] with corners rounded by the radius r (gmsh OCC), sitting on
the block [−W/2, W/2] × [−D, 0]: its flat bottom touches the block's top y = 0; the fillets
rise off it. Under a normal load with shear the contact zone holds the flat and part of the
fillets, where a slave node's averaged normal tilts off the vertical.

Physical groups: "punch" (2, 1), "block" (2, 2), "punch_contact" (1, 11) = the bottom line and
the two lower fillets, "block_contact" (1, 12) = the block's top, "load" (1, 13) = the punch's
top line, "bottom" (1, 14) = y = −D.
"""

from __future__ import annotations

import gmsh

from dolfinx_feti.io.meshes import add_group, physical_groups, set_output_options


def filleted_punch(h_punch: float = 0.05, h_block: float = 0.085, w: float = 2.0,
                   H: float = 1.0, r: float = 0.4, W: float = 6.0, D: float = 2.0) -> dict:
    """The model in gmsh's current session (see the module's text); returns its groups."""
    gmsh.model.add("filleted_punch")
    set_output_options()
    occ = gmsh.model.occ
    punch = occ.addRectangle(-w / 2, 0.0, 0.0, w, H, roundedRadius=r)
    block = occ.addRectangle(-W / 2, -D, 0.0, W, D)
    occ.synchronize()
    tol = 1e-9 * W

    def curves(body):
        return [abs(t) for _, t in gmsh.model.getBoundary([(2, body)], oriented=False)]

    def centre(c):
        return gmsh.model.occ.getCenterOfMass(1, c)[:2]

    contact = [c for c in curves(punch) if centre(c)[1] < r - tol]  # flat and lower fillets
    load = [c for c in curves(punch) if abs(centre(c)[1] - H) < tol]
    top = [c for c in curves(block) if abs(centre(c)[1]) < tol]
    bottom = [c for c in curves(block) if abs(centre(c)[1] + D) < tol]
    for body, h in ((punch, h_punch), (block, h_block)):
        pts = gmsh.model.getBoundary([(2, body)], combined=False, recursive=True)
        gmsh.model.mesh.setSize(pts, h)
    add_group(2, [punch], 1, "punch")
    add_group(2, [block], 2, "block")
    add_group(1, contact, 11, "punch_contact")
    add_group(1, top, 12, "block_contact")
    add_group(1, load, 13, "load")
    add_group(1, bottom, 14, "bottom")
    gmsh.model.mesh.generate(2)
    return physical_groups()
