"""The conditions of a problem file, built from the tables the condition classes declare.

``[[dirichlet]]``, ``[[contact]]`` (by its ``type``), ``[[tie]]`` and the tables inside them
(a friction law, an obstacle's shape) are read through one registry
(:data:`dolfinx_feti.problem.conditions.file_table.FILE_TABLES`): the keys, their types and
defaults are each class's fields and ``@checked`` specs. The value of a key is read by the
kind of its check (a ``Text`` field names a boundary group of the mesh, a ``Real`` a number
in its range, a ``Vector`` gdim numbers, an ``Instance`` of classes with tables a nested
table); what a table declares beyond that (a pair of surfaces, the problem's components, an
elasticity model, the dimensions) is checked by its flags. No code here names a condition
class: a new one is read without an edit of this module.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any

import numpy as np

from ..errors import InputError
from ..mesh import MeshData
from ..problem.conditions.file_table import FileTable, classes_of, file_keys, nested_section
from ..validation import Check, Choice, Either, Integer, Maybe, Real, SequenceOf, Text, Vector
from .schema import Checker, describe, key_path


class ConditionReader:
    """Builds the conditions of one problem file, collecting the faults in ``checker``.

    Args:
        checker: The reader's fault collector.
        mesh: The mesh (its groups and dimension), or None when it could not be read.
        model: The ``[model] type``, or None.
        value_size: The number of components of the problem, or None when unknown.
    """

    def __init__(self, checker: Checker, mesh: MeshData | None, model: str | None,
                 value_size: int | None) -> None:
        self.c, self.mesh, self.model, self.value_size = checker, mesh, model, value_size
        self.gdim = None if mesh is None else mesh.gdim

    def section(self, data: dict, section: str) -> list:
        """The conditions of the top-level array of tables ``[[section]]`` that are sound."""
        out = []
        for i, t in enumerate(self.c.array_of_tables(data.get(section), section)):
            condition = self.table(t, key_path(section, i), section)
            if condition is not None:
                out.append(condition)
        return out

    def table(self, t: Any, key: str, section: str) -> Any:
        """One condition of ``section`` from its table (its class by ``type``), or None."""
        if not isinstance(t, dict):
            self.c.fault(key, f"expected a table, got {describe(t)}")
            return None
        cls = self._class_of(t, key, section)
        return None if cls is None else self.build(cls, t, key)

    def _class_of(self, t: dict, key: str, section: str) -> type | None:
        classes = classes_of(section)
        if None in classes:  # the section's only class
            return classes[None]
        types = tuple(classes)
        if "type" in t:
            kind = self.c.string(t["type"], key_path(key, "type"), types)
            return None if kind is None else classes[kind]
        for cls in classes.values():
            if any(k in t for k in cls.file_table.infer_from):
                return cls
        inferred = [f"{t_!r} when {' or '.join(c.file_table.infer_from)} is given"
                    for t_, c in classes.items() if c.file_table.infer_from]
        self.c.fault(key_path(key, "type"), "missing: expected one of "
                     f"{', '.join(map(repr, types))}"
                     + (f" (left out, it is {'; '.join(inferred)})" if inferred else ""))
        return None

    def build(self, cls: type, t: Any, key: str) -> Any:
        """The condition of class ``cls`` from its table ``t``, or None (faults collected)."""
        c, table = self.c, cls.file_table
        keys = file_keys(cls)
        t = c.table(t, key, [k.name for k in keys], required=[k.name for k in keys if k.required])
        if t is None:
            return None
        good = all(k.name in t for k in keys if k.required)
        if table.needs_elasticity and self.model == "poisson":
            c.fault(key, f"{table.needs_elasticity} needs an elasticity model (model.type = "
                    "'elasticity')")
            good = False
        if self.gdim is not None and self.gdim not in table.dims:
            dims = " or ".join(f"{d}D" for d in table.dims)
            c.fault(key, f"a {table.type} {table.section} needs a {dims} mesh (this one is "
                    f"{self.gdim}D)" + (f"; {table.hint}" if table.hint else ""))
            return None
        kw = {}
        taken = {k.name for k in keys}
        for f in fields(cls):
            if f.name not in taken and f.name not in table.one_of:
                continue  # not a key of the file: its default
            if f.name in table.one_of:
                kw[f.name] = self._one_of(t, key, table.one_of[f.name])
            elif f.name in t:
                length = None if f.name == table.per_component else self.gdim
                kw[f.name] = self.value(table.keys.get(f.name, cls.checks[f.name]), t[f.name],
                                        key_path(key, f.name), length)
            else:
                continue
            good &= kw[f.name] is not None
        if table.pair:
            good &= self._pair(t, key, table, kw.get("slave"), kw.get("master"))
        if table.components:
            good &= self._components(t, key, table, kw)
        if not good:
            return None
        try:
            return cls(**kw)
        except InputError as e:
            c.fault(key, str(e))
            return None

    def value(self, check: Check, raw: Any, key: str, length: int | None = None) -> Any:
        """The value of one key by the kind of its check, or None (a fault collected).

        ``length``: the number of items of a vector (the mesh's dimension; None: any).
        """
        c = self.c
        if isinstance(check, Maybe):  # TOML has no None: a key left out is the default
            check = check.check
        section = nested_section(check)
        if section is not None:
            return self.table(raw, key, section)
        if isinstance(check, Either):  # a number or an array of numbers
            arrays = [x for x in check.checks if isinstance(x, Vector | SequenceOf)]
            numbers = [x for x in check.checks if isinstance(x, Real | Integer)]
            choice = (arrays or numbers) if isinstance(raw, list) else (numbers or arrays)
            if not choice:
                c.fault(key, "this key cannot be given in a problem file")
                return None
            check = choice[0]
        if isinstance(check, Text):  # every name of a condition is a boundary group's
            return c.group(raw, key, self.mesh)
        if isinstance(check, Choice):
            return c.string(raw, key, check.choices)
        if isinstance(check, Real | Integer):
            if isinstance(check, Real) and check.inf and isinstance(raw, float) and raw == math.inf:
                return math.inf
            what = check.what.replace("a finite number", "a number")
            return c.number(raw, key, what, lambda v: check.ok(v)[0],
                            integer=isinstance(check, Integer))
        if isinstance(check, Vector):
            v = c.vector(raw, key, check.length or length)
            if v is not None and check.nonzero and not any(v):
                c.fault(key, "expected a non-zero vector")
                return None
            return v
        if isinstance(check, SequenceOf):
            good, out = check.ok(raw)
            if not isinstance(raw, list) or not good:
                c.fault(key, f"expected {check.what.replace('list of', 'array of')}, got "
                        f"{describe(raw)}")
                return None
            return out
        c.fault(key, "this key cannot be given in a problem file")
        return None

    def _one_of(self, t: dict, key: str, section: str) -> Any:
        """The field given as exactly one key naming a class of ``section`` (a shape)."""
        classes = classes_of(section)
        given = [name for name in classes if name in t]
        if len(given) != 1:
            shapes = [f"{name} = {{{', '.join(k.name for k in file_keys(cls))}}}"
                      for name, cls in classes.items()]
            self.c.fault(key, f"expected exactly one {section}: {', '.join(shapes)}; got "
                         f"{given or 'none'}")
            return None
        return self.build(classes[given[0]], t[given[0]], key_path(key, given[0]))

    def _pair(self, t: dict, key: str, table: FileTable, slave: str | None,
              master: str | None) -> bool:
        """The slave and master are two surfaces (of two bodies, for ``pair="contact"``)."""
        c, mesh = self.c, self.mesh
        if "slave" in t and t.get("slave") == t.get("master"):
            if table.self_contact:
                return True
            selfish = [ty for ty, cls in classes_of("contact").items()
                       if cls.file_table.self_contact]
            c.fault(key, f"a {table.section} of the group {t['slave']!r} with itself: slave and "
                    "master must be two different surfaces"
                    + (f" (self-contact is type = {selfish[0]!r})" if selfish else ""))
            return False
        if table.pair != "contact" or slave is None or master is None or mesh is None:
            return True
        shared = np.intersect1d(mesh.facet_groups[slave], mesh.facet_groups[master])
        if shared.size:
            c.fault(key, f"slave {slave!r} and master {master!r} share {shared.size} nodes: the "
                    "bodies are glued there (common nodes), not in contact; bodies in contact "
                    "need their own nodes on the surfaces")
            return False
        both = _bodies_of(mesh, slave) & _bodies_of(mesh, master)
        if both:
            c.fault(key, f"slave {slave!r} and master {master!r} both lie on body "
                    f"{mesh.body_names[min(both)]!r}: contact is between two bodies")
            return False
        return True

    def _components(self, t: dict, key: str, table: FileTable, kw: dict) -> bool:
        """The components exist; a value per component has one number per constrained one."""
        comps, n = kw.get(table.components), self.value_size
        ckey = key_path(key, table.components)
        if comps is not None and n is not None and any(not 0 <= v < n for v in comps):
            self.c.fault(ckey, f"expected indices in 0..{n - 1} (the problem has {n} "
                         f"component(s)), got {list(comps)}")
            return False
        ncomp = len(comps) if comps is not None else n
        value = kw.get(table.per_component)
        if isinstance(value, list) and ncomp is not None and len(value) not in (1, ncomp):
            self.c.fault(key_path(key, table.per_component), f"expected one number or {ncomp} "
                         f"(one per constrained component), got {len(value)}")
            return False
        return True


def _bodies_of(mesh: MeshData, group: str) -> set[int]:
    """The bodies with a cell that touches a node of the group."""
    nodes = np.unique(mesh.facet_groups[group])
    return set(np.unique(mesh.cell_body[np.isin(mesh.cells, nodes).any(axis=1)]).tolist())
