"""gmsh models of the Total BETI tests and benchmarks (structured triangles, no volume loads).

Run them through :func:`dolfinx_feti.build_mesh`.
"""

from __future__ import annotations

import gmsh

from ..io.meshes import add_group, add_structured_box, physical_groups, set_output_options


def two_squares(n: int, m: int | None = None, *, stacked: bool = False
                ) -> dict[str, tuple[int, int]]:
    """Two unit squares with their own nodes on the common side, n (and m) cells a side.

    Side by side (default): "left" = (0,1)², "right" = (1,2)×(0,1), groups "dirichlet" (x = 0),
    "contact_left", "contact_right" (x = 1 of each), "top_left", "top_right" (y = 1), "end"
    (x = 2). Stacked: "lower" = (0,1)², "upper" = (0,1)×(1,2), groups "bottom" (y = 0),
    "contact_lower", "contact_upper" (y = 1 of each), "top" (y = 2), "left" (x = 0 of both).

    Args:
        n: Cells along a side of the first square.
        m: Cells along a side of the second square (default n; m ≠ n: non-matching meshes).
        stacked: Whether the second square is above the first.
    """
    m = n if m is None else m
    if min(n, m) < 1:
        raise ValueError(f"two_squares: cell counts must be >= 1, got {n}, {m}")
    gmsh.model.add(f"two_squares_{n}_{m}")
    set_output_options()
    a, sa, tag = add_structured_box((0.0, 0.0), (1.0, 1.0), (n, n), 1)
    hi = (1.0, 2.0) if stacked else (2.0, 1.0)
    lo = (0.0, 1.0) if stacked else (1.0, 0.0)
    b, sb, _ = add_structured_box(lo, hi, (m, m), tag)
    if stacked:
        add_group(2, [a], 1, "lower")
        add_group(2, [b], 2, "upper")
        add_group(1, [sa[1, 0]], 11, "bottom")
        add_group(1, [sa[1, 1]], 12, "contact_lower")
        add_group(1, [sb[1, 0]], 13, "contact_upper")
        add_group(1, [sb[1, 1]], 14, "top")
        add_group(1, [sa[0, 0], sb[0, 0]], 15, "left")
    else:
        add_group(2, [a], 1, "left")
        add_group(2, [b], 2, "right")
        add_group(1, [sa[0, 0]], 11, "dirichlet")
        add_group(1, [sa[0, 1]], 12, "contact_left")
        add_group(1, [sb[0, 0]], 13, "contact_right")
        add_group(1, [sa[1, 1]], 14, "top_left")
        add_group(1, [sb[1, 1]], 15, "top_right")
        add_group(1, [sb[0, 1]], 16, "end")
    return physical_groups()


def split_square(cells: int) -> dict[str, tuple[int, int]]:
    """The unit square as two bodies, "left" = (0,½)×(0,1) and "right" = (½,1)×(0,1).

    Each body has its own nodes on x = ½; ``cells`` (even) cells along a unit length. Groups:
    "dirichlet" (x = 0), "contact_left", "contact_right" (x = ½ of each), "top_left",
    "top_right" (y = 1), "end" (x = 1).
    """
    if cells < 2 or cells % 2:
        raise ValueError(f"split_square: cells must be even and >= 2, got {cells}")
    gmsh.model.add(f"split_square_{cells}")
    set_output_options()
    half = cells // 2
    a, sa, tag = add_structured_box((0.0, 0.0), (0.5, 1.0), (half, cells), 1)
    b, sb, _ = add_structured_box((0.5, 0.0), (1.0, 1.0), (half, cells), tag)
    add_group(2, [a], 1, "left")
    add_group(2, [b], 2, "right")
    for dim_tag, (side, name) in enumerate(((sa[0, 0], "dirichlet"), (sa[0, 1], "contact_left"),
                                            (sb[0, 0], "contact_right"), (sa[1, 1], "top_left"),
                                            (sb[1, 1], "top_right"), (sb[0, 1], "end"))):
        add_group(1, [side], 11 + dim_tag, name)
    return physical_groups()


__all__ = ["split_square", "two_squares"]
