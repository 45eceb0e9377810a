"""A problem on bodies of different cell types: one problem per mesh, and what joins them.

A :class:`~dolfinx_feti.mesh.mixed.MixedMesh` holds one mesh per cell type. The problem on it
is split into one :class:`~dolfinx_feti.ContactProblem` per mesh — its bodies, the Dirichlet
conditions and contact conditions on its boundary groups (a group on several meshes, such as
a symmetry plane through two bodies, goes to each with its facets there) — and the conditions
between surfaces of two meshes: :class:`~dolfinx_feti.Mortar` contact and
:class:`~dolfinx_feti.Tie`, whose rows couple the two meshes' dofs
(:mod:`dolfinx_feti.drivers.mixed_solve`).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass, replace

from ..errors import InputError

#: Attributes of the forms helpers that map boundary groups to loads.
_GROUP_LOADS = ("tractions", "flux")
#: Attributes of the forms helpers that may map body names to values (materials).
_BODY_VALUES = ("E", "nu", "k")


@dataclass
class Across:
    """A mortar condition between surfaces of two meshes of a mixed problem.

    Attributes:
        spec: The condition (:class:`~dolfinx_feti.Mortar` or :class:`~dolfinx_feti.Tie`).
        index: Its index in the problem's contact list (or ties).
        slave: The part (mesh) of its slave surface.
        master: The part of its master surface.
        tie: Whether it is a tie (equality rows), else contact.
    """

    spec: object
    index: int
    slave: int
    master: int
    tie: bool


@dataclass
class MixedParts:
    """A problem on a mixed mesh, split.

    Attributes:
        problems: One problem per part of the mesh.
        across: The conditions between surfaces of two parts.
    """

    problems: list
    across: list[Across]


def split_problem(problem) -> MixedParts:
    """Split a :class:`~dolfinx_feti.ContactProblem` on a mixed mesh (see the module doc).

    Raises:
        InputError: A condition between two meshes that is not :class:`Mortar` or
            :class:`Tie`, friction or ``normals="flatter"`` on one, a surface spread over two
            meshes, or a degree-2 space.
    """
    mesh = problem.mesh
    degree = problem.degree if problem.degree is not None else \
        getattr(problem.forms, "degree", None)
    if degree not in (None, 1):
        raise InputError(f"a problem on bodies of several cell types ({mesh.describe()}) is "
                         f"solved with degree 1, not {degree}")
    n = len(mesh.parts)
    dirichlet: list[list] = [[] for _ in range(n)]
    conditions: dict[str, list[list]] = {"contact": [[] for _ in range(n)],
                                         "ties": [[] for _ in range(n)]}
    across = []
    for bc in problem.dirichlet:
        for k in mesh.parts_of_group(bc.group):
            dirichlet[k].append(bc)
    for what in ("ties", "contact"):
        for i, c in enumerate(getattr(problem, what)):
            where = [mesh.parts_of_group(g) for g in c.groups]
            if len(where) == 1:  # one surface (a rigid obstacle): on each of its meshes
                for k in where[0]:
                    conditions[what][k].append(c)
                continue
            if all(w == where[0] and len(w) == 1 for w in where):
                conditions[what][where[0][0]].append(c)
                continue
            name = f"{type(c).__name__}({c.groups[0]!r}, {c.groups[1]!r})"
            if not c.mortar or c.self_contact:
                raise InputError(f"{name} joins surfaces on meshes of different cell types "
                                 f"({mesh.describe()}): only Mortar contact and Tie couple "
                                 "bodies of different types")
            if any(len(w) > 1 for w in where):
                raise InputError(f"{name}: a surface lies on bodies of several cell types; "
                                 "name one surface per body")
            if getattr(c, "friction", None) is not None or getattr(c, "normals", "slave") \
                    != "slave":
                raise InputError(f"{name} between bodies of different cell types: friction "
                                 "and normals='flatter' are not implemented there")
            across.append(Across(c, i, where[0][0], where[1][0], what == "ties"))
    problems = [type(problem)(part, _forms_on(problem.forms, part), problem.value_size,
                              dirichlet=dirichlet[k], contact=conditions["contact"][k],
                              ties=conditions["ties"][k],
                              decomposition=_decomposition_on(problem.decomposition, part),
                              gluing=problem.gluing, degree=1)
                for k, part in enumerate(mesh.parts)]
    return MixedParts(problems, across)


def _forms_on(forms, mesh):
    """The forms as one mesh's problem sees them: their own copy, loads on its groups only.

    A copy, because a helper's check fills per-body values for the mesh it checks (each mesh
    has other bodies); the loads of groups on other meshes are left out of the copy.
    """
    if not hasattr(forms, "check"):
        return forms  # a plain function: no state, no check
    out = copy.copy(forms)
    for name in _GROUP_LOADS:
        loads = getattr(forms, name, None)
        if isinstance(loads, Mapping):
            setattr(out, name, {g: v for g, v in loads.items() if g in mesh.facet_groups})
    for name in _BODY_VALUES:  # a value per body: those of this mesh's bodies
        values = getattr(forms, name, None)
        if isinstance(values, Mapping):
            setattr(out, name, {b: v for b, v in values.items() if b in mesh.body_names})
    return out


def _decomposition_on(decomposition, mesh):
    """The decomposition as one mesh sees it: ``Parts(n={body: ...})`` of its bodies only."""
    n = getattr(decomposition, "n", None)
    if not isinstance(n, Mapping):
        return decomposition
    return replace(decomposition, n={b: v for b, v in n.items() if b in mesh.body_names})


__all__ = ["Across", "MixedParts", "split_problem"]
