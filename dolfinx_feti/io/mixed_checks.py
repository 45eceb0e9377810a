"""Problem files on bodies of several cell types: what the checks read, and what is refused.

A :class:`~dolfinx_feti.MixedMesh` holds one mesh per cell type. The checks of a problem file
(groups, bodies, contact pairs, decompositions) read one mesh's arrays; :func:`checking_view`
gives them the meshes as one: the nodes numbered mesh after mesh, the cells and facets padded
to the widest (by repeating their last vertex, which changes no node set), the bodies in the
mixed mesh's order. It is for the checks only; the problem is built on the mixed mesh.

:func:`mixed_faults` names, by their keys, the parts of a problem file that the solve of a
mixed problem (:func:`~dolfinx_feti.drivers.mixed_solve.solve_mixed`) refuses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mesh.mixed import MixedMesh

#: The FETI methods of the mixed solve (``solve_mixed``).
MIXED_METHODS = ("tfeti", "feti1", "auto")


@dataclass(frozen=True)
class CheckingView:
    """The meshes of a :class:`MixedMesh` as one mesh, for the problem-file checks."""

    x: np.ndarray
    cells: np.ndarray
    cell_body: np.ndarray
    body_names: tuple[str, ...]
    facet_groups: dict[str, np.ndarray]
    gdim: int
    tdim: int

    @property
    def num_nodes(self) -> int:
        """Number of nodes of all meshes."""
        return self.x.shape[0]


def _padded(blocks: list[np.ndarray]) -> np.ndarray:
    """Rows of several widths as one array, each row padded with its last entry."""
    width = max(b.shape[1] for b in blocks)
    return np.vstack([np.hstack([b, np.repeat(b[:, -1:], width - b.shape[1], axis=1)])
                      for b in blocks]).astype(np.int64)


def checking_view(mesh: MixedMesh) -> CheckingView:
    """The meshes as one (module docstring)."""
    start = np.cumsum([0] + [p.num_nodes for p in mesh.parts])
    body = [np.array([mesh.body_names.index(b) for b in p.body_names], dtype=np.int64)
            for p in mesh.parts]
    groups: dict[str, list[np.ndarray]] = {}
    for k, p in enumerate(mesh.parts):
        for name, f in p.facet_groups.items():
            groups.setdefault(name, []).append(np.asarray(f, dtype=np.int64) + start[k])
    return CheckingView(
        x=np.vstack([p.x for p in mesh.parts]),
        cells=_padded([p.cells + start[k] for k, p in enumerate(mesh.parts)]),
        cell_body=np.concatenate([body[k][p.cell_body] for k, p in enumerate(mesh.parts)]),
        body_names=tuple(mesh.body_names),
        facet_groups={n: _padded(fs) for n, fs in groups.items()},
        gdim=mesh.gdim, tdim=mesh.tdim)


def mixed_faults(mesh: MixedMesh, data: dict, model: str | None, contact: list,
                 ties: list) -> list[tuple[str, str]]:
    """(key, message) of each part of the file that a problem on several cell types refuses.

    Args:
        mesh: The mixed mesh.
        data: The problem file's tables.
        model: ``model.type``.
        contact: The checked ``[[contact]]`` conditions (in file order).
        ties: The checked ``[[tie]]`` conditions.
    """
    what = f"bodies of several cell types ({mesh.describe()})"
    out = []
    if model in ("neo-hookean", "svk"):
        out.append(("model.type", f"{model!r} (large deformation, solved by Newton) on {what} "
                    "is not implemented; use 'elasticity' or 'poisson'"))
    if "loading" in data:
        out.append(("loading", f"a load path on {what} is not implemented: give one load"))
    out_table = data.get("output", {})
    if isinstance(out_table, dict) and out_table.get("pressure_plot", False) is not False:
        out.append(("output.pressure_plot", f"a pressure plot on {what} is not implemented; "
                    "the contact forces between meshes are in the report"))
    for name, conds in (("contact", contact), ("tie", ties)):
        for i, c in enumerate(conds):
            if len(c.groups) != 2:  # one surface (against an obstacle): no pair to join
                continue
            slave, master = mesh.parts_of_group(c.slave), mesh.parts_of_group(c.master)
            if slave == master and len(slave) == 1:
                continue  # both surfaces on one mesh: that mesh's own condition
            key = f"{name}[{i}]"
            if len(slave) > 1 or len(master) > 1:
                out.append((key, "a surface lies on bodies of several cell types; name one "
                            "surface per body"))
            elif name == "contact" and not c.mortar:
                out.append((key, f"{c.slave!r} and {c.master!r} lie on meshes of different "
                            f"cell types ({mesh.describe()}): only type = 'mortar' contact and "
                            "[[tie]] join bodies of different types"))
            elif getattr(c, "friction", None) is not None:
                out.append((_sub(key, "friction"), "friction between bodies of different cell "
                            "types is not implemented"))
            elif getattr(c, "normals", "slave") != "slave":
                out.append((_sub(key, "normals"), "normals = 'flatter' between bodies of "
                            "different cell types is not implemented"))
    return out


def method_fault(method: str, key: str) -> tuple[str, str] | None:
    """The fault of a FETI method the mixed solve refuses (None when it takes it)."""
    if method in MIXED_METHODS:
        return None
    return (key, f"method {method!r}: a problem on bodies of several cell types is solved by "
            f"Total FETI or FETI-1 (one of {', '.join(map(repr, MIXED_METHODS))})")


def _sub(key: str, name: str) -> str:
    return f"{key}.{name}"


__all__ = ["MIXED_METHODS", "CheckingView", "checking_view", "method_fault", "mixed_faults"]
