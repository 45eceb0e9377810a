"""The ``[loading]`` table of a problem file: a load path's steps.

Per step: a factor on the file's loads (``factors``), a value per Dirichlet group (``values``)
and a translation per rigid obstacle (``translations``: a punch pressed and slid, a cylinder
rolled). Read into a :class:`Loading`; :meth:`~.problemfile.ProblemFile.problem_at` makes the
step's problem from it (:func:`~dolfinx_feti.drivers.scaled.scaled`,
:func:`~dolfinx_feti.drivers.scaled.moved`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .schema import LOADING_KEYS, SOLIDS, Checker, describe, key_path


@dataclass(frozen=True)
class Loading:
    """The steps of a ``[loading]`` table.

    Attributes:
        factors: Per step, the factor of the file's tractions, body force and Dirichlet values.
        values: Dirichlet group → its value at each step (in place of the value times the
            factor).
        translations: Contact group of a rigid obstacle → the obstacle's translation at each
            step, from its position in the file.
    """

    factors: tuple[float, ...]
    values: dict[str, tuple] = field(default_factory=dict)
    translations: dict[str, tuple] = field(default_factory=dict)


def read_loading(c: Checker, table: Any, model: str | None, dirichlet: list, contact: list,
                 value_size: int | None, gdim: int | None) -> Loading | None:
    """The ``[loading]`` table (None without one, or on a fault, which ``c`` records)."""
    if table is None:
        return None
    t = c.table(table, "loading", LOADING_KEYS)
    if t is None:
        return None
    if not {"factors", "values", "translations"} & set(t):
        c.fault("loading", "expected factors = [...] (the loads' factor per step), values = "
                "{ <dirichlet group> = [[...], ...] } (a group's value per step), translations "
                "= { <obstacle's contact group> = [[...], ...] } (its position per step), or "
                "several of them")
        return None
    if model is not None and model not in SOLIDS:
        c.fault("loading", f"a load path needs a solid model.type ({', '.join(SOLIDS)}: "
                f"its tractions, body force and Dirichlet values are scaled), got {model!r}")
        return None
    steps = None
    factors = None
    if "factors" in t:
        factors = c.vector(t["factors"], "loading.factors", None, "load factors")
        if factors is not None and len(factors) == 0:
            c.fault("loading.factors", "expected at least one load factor")
            factors = None
        if factors is None:
            return None
        steps = len(factors)
    values = _values(c, t.get("values", {}), dirichlet, value_size, steps)
    if values is None:
        return None
    steps = steps if not values else len(next(iter(values.values())))
    translations = _translations(c, t.get("translations", {}), contact, gdim, steps,
                                 small=model == "elasticity")
    if translations is None:
        return None
    if factors is None and not values and not translations:
        c.fault("loading", "expected at least one Dirichlet group (values) or obstacle "
                "(translations)")
        return None
    if factors is None:  # the loads as given at every step
        steps = len(next(iter((values or translations).values())))
        factors = [1.0] * steps
    return Loading(tuple(float(v) for v in factors), values, translations)


def _per_step(c: Checker, key: str, rows: Any) -> list | None:
    """A non-empty array, one entry per step (None on a fault)."""
    if not isinstance(rows, list) or not rows:
        c.fault(key, f"expected an array of one value per step, got {describe(rows)}")
        return None
    return rows


def _same_steps(c: Checker, key: str, entries: list, steps: int | None) -> bool:
    """Whether ``entries`` has the number of steps the other keys gave (a fault if not)."""
    if steps is not None and len(entries) != steps:
        c.fault(key, f"expected {steps} values (one per step, as the other keys give), got "
                f"{len(entries)}")
        return False
    return True


def _values(c: Checker, v: Any, dirichlet: list, value_size: int | None,
            steps: int | None) -> dict[str, tuple] | None:
    """``[loading] values``: Dirichlet group → one value per step (None on a fault)."""
    key = "loading.values"
    if not isinstance(v, dict):
        c.fault(key, f"expected a table {{ <dirichlet group> = [[...], ...] }}, got "
                f"{describe(v)}")
        return None
    out, good = {}, True
    for group, rows in v.items():
        gkey = key_path(key, group)
        conds = [d for d in dirichlet if d.group == group]
        if not conds:
            c.fault(gkey, f"not the group of a [[dirichlet]] condition (those are "
                    f"{sorted({d.group for d in dirichlet})})")
            good = False
            continue
        n = {len(d.components) if d.components is not None else value_size for d in conds}
        rows = _per_step(c, gkey, rows)
        if rows is None:
            good = False
            continue
        vals = [c.vector(r, key_path(gkey, i), None) if isinstance(r, list) else
                c.number(r, key_path(gkey, i), "a number or an array of one per component")
                for i, r in enumerate(rows)]
        if any(x is None for x in vals):
            good = False
            continue
        bad = [i for i, x in enumerate(vals) if isinstance(x, list)
               and len(x) != 1 and len(x) not in n]
        if bad:
            c.fault(key_path(gkey, bad[0]), f"expected one number or {sorted(n)} (one per "
                    f"constrained component), got {len(vals[bad[0]])}")
            good = False
            continue
        if not _same_steps(c, gkey, vals, steps):
            good = False
            continue
        steps = len(vals)
        out[group] = tuple(tuple(x) if isinstance(x, list) else x for x in vals)
    return out if good else None


def _translations(c: Checker, v: Any, contact: list, gdim: int | None,
                  steps: int | None, small: bool) -> dict[str, tuple] | None:
    """``[loading] translations``: obstacle's group → one vector per step (None on a fault).

    ``small``: a small-deformation model, whose friction rows cannot follow a moving curved
    obstacle (its normals change under the nodes): refused here rather than at its second
    step.
    """
    key = "loading.translations"
    if not isinstance(v, dict):
        c.fault(key, f"expected a table {{ <obstacle's contact group> = [[...], ...] }}, got "
                f"{describe(v)}")
        return None
    movable = sorted(cond.group for cond in contact
                     if hasattr(getattr(cond, "obstacle", None), "translated"))
    out, good = {}, True
    for group, rows in v.items():
        gkey = key_path(key, group)
        if group not in movable:
            c.fault(gkey, f"not the group of a [[contact]] condition with a rigid obstacle "
                    f"(those are {movable})")
            good = False
            continue
        cond = next(cond for cond in contact if getattr(cond, "group", None) == group)
        if small and cond.friction is not None and \
                not getattr(cond.obstacle, "keeps_normals", False):
            c.fault(gkey, f"a {type(cond.obstacle).__name__.lower()} with friction cannot move "
                    "in small deformation (its normals change under the nodes): a plane can, "
                    "or a hyperelastic model.type (Newton) can")
            good = False
            continue
        rows = _per_step(c, gkey, rows)
        if rows is None:
            good = False
            continue
        vecs = [c.vector(r, key_path(gkey, i), gdim, "coordinates")
                for i, r in enumerate(rows)]
        if any(x is None for x in vecs) or not _same_steps(c, gkey, vecs, steps):
            good = False
            continue
        steps = len(vecs)
        out[group] = tuple(tuple(float(a) for a in x) for x in vecs)
    return out if good else None


__all__ = ["Loading", "read_loading"]
