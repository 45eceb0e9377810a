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
        friction: A contact condition's first group → its friction value at each step
            (Tresca's slip bound, Coulomb's coefficient).
    """

    factors: tuple[float, ...]
    values: dict[str, tuple] = field(default_factory=dict)
    translations: dict[str, tuple] = field(default_factory=dict)
    friction: dict[str, tuple] = field(default_factory=dict)


def read_loading(c: Checker, table: Any, model: str | None, dirichlet: list, contact: list,
                 value_size: int | None, gdim: int | None) -> Loading | None:
    """The ``[loading]`` table (None without one, or on a fault, which ``c`` records)."""
    if table is None:
        return None
    t = c.table(table, "loading", LOADING_KEYS)
    if t is None:
        return None
    if not {"factors", "values", "translations", "friction"} & set(t):
        c.fault("loading", "expected factors = [...] (the loads' factor per step), values = "
                "{ <dirichlet group> = [[...], ...] } (a group's value per step), translations "
                "= { <obstacle's contact group> = [[...], ...] } (its position per step), "
                "friction = { <contact group> = [...] } (its friction value per step), or "
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
    steps = _steps(values, steps)
    translations = _translations(c, t.get("translations", {}), contact, gdim, steps,
                                 small=model == "elasticity")
    if translations is None:
        return None
    steps = _steps(translations, steps)
    friction = _friction(c, t.get("friction", {}), contact, steps)
    if friction is None:
        return None
    steps = _steps(friction, steps)
    if steps is None:
        c.fault("loading", "expected at least one Dirichlet group (values), obstacle "
                "(translations) or friction value (friction)")
        return None
    if factors is None:  # the loads as given at every step
        factors = [1.0] * steps
    return Loading(tuple(float(v) for v in factors), values, translations, friction)


def _steps(table: dict[str, tuple], steps: int | None) -> int | None:
    """The number of steps a per-group table gives (its groups agree), else ``steps``."""
    return len(next(iter(table.values()))) if table else steps


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


def _per_group(c: Checker, key: str, v: Any, shape: str, conds: dict, known: str, parse,
               steps: int | None, refuse=None) -> dict[str, tuple] | None:
    """A table ``group → [entry per step]`` (None on a fault, which ``c`` records).

    Args:
        c: The checker.
        key: The table's key path.
        v: The table as read.
        shape: How the table looks (for the fault of a value that is not a table).
        conds: The groups it may name → what ``parse`` and ``refuse`` take.
        known: What those groups are (for the fault of another group).
        parse: ``parse(cond, key, entry)`` → the step's value (None after a fault).
        steps: The number of steps the other keys gave (None: any).
        refuse: ``refuse(cond)`` → why the group cannot be given (None: it can).
    """
    if not isinstance(v, dict):
        c.fault(key, f"expected a table {shape}, got {describe(v)}")
        return None
    out, good = {}, True
    for group, rows in v.items():
        gkey = key_path(key, group)
        if group not in conds:
            c.fault(gkey, f"not {known} (those are {sorted(conds)})")
            good = False
            continue
        why = None if refuse is None else refuse(conds[group])
        if why is not None:
            c.fault(gkey, why)
            good = False
            continue
        rows = _per_step(c, gkey, rows)
        if rows is None:
            good = False
            continue
        vals = [parse(conds[group], key_path(gkey, i), r) for i, r in enumerate(rows)]
        if any(x is None for x in vals) or not _same_steps(c, gkey, vals, steps):
            good = False
            continue
        steps = len(vals)
        out[group] = tuple(vals)
    return out if good else None


def _values(c: Checker, v: Any, dirichlet: list, value_size: int | None,
            steps: int | None) -> dict[str, tuple] | None:
    """``[loading] values``: Dirichlet group → one value per step (None on a fault)."""
    sizes = {}
    for d in dirichlet:
        sizes.setdefault(d.group, set()).add(len(d.components) if d.components is not None
                                             else value_size)

    def parse(n: set, key: str, r: Any):
        if not isinstance(r, list):
            return c.number(r, key, "a number or an array of one per component")
        x = c.vector(r, key, None)
        if x is not None and len(x) != 1 and len(x) not in n:
            c.fault(key, f"expected one number or {sorted(n)} (one per constrained "
                    f"component), got {len(x)}")
            return None
        return None if x is None else tuple(x)

    return _per_group(c, "loading.values", v, "{ <dirichlet group> = [[...], ...] }", sizes,
                      "the group of a [[dirichlet]] condition", parse, steps)


def _translations(c: Checker, v: Any, contact: list, gdim: int | None,
                  steps: int | None, small: bool) -> dict[str, tuple] | None:
    """``[loading] translations``: obstacle's group → one vector per step (None on a fault).

    ``small``: a small-deformation model, whose friction rows cannot follow a moving curved
    obstacle (its normals change under the nodes): refused here rather than at its second
    step.
    """
    movable = {cond.group: cond for cond in contact
               if hasattr(getattr(cond, "obstacle", None), "translated")}

    def refuse(cond) -> str | None:
        if small and cond.friction is not None and \
                not getattr(cond.obstacle, "keeps_normals", False):
            return (f"a {type(cond.obstacle).__name__.lower()} with friction cannot move in "
                    "small deformation (its normals change under the nodes): a plane can, or "
                    "a hyperelastic model.type (Newton) can")
        return None

    def parse(cond, key: str, r: Any):
        x = c.vector(r, key, gdim, "coordinates")
        return None if x is None else tuple(x)

    return _per_group(c, "loading.translations", v, "{ <obstacle's contact group> = "
                      "[[...], ...] }", movable, "the group of a [[contact]] condition with a "
                      "rigid obstacle", parse, steps, refuse)


def _friction(c: Checker, v: Any, contact: list, steps: int | None
              ) -> dict[str, tuple] | None:
    """``[loading] friction``: a condition's first group → its friction value per step."""
    with_friction = {cond.groups[0]: cond for cond in contact
                     if getattr(cond, "friction", None) is not None}

    def parse(cond, key: str, r: Any):
        return c.number(r, key, "a friction value >= 0 (Tresca's slip bound, Coulomb's "
                        "coefficient)", ok=lambda x: x >= 0)

    return _per_group(c, "loading.friction", v, "{ <contact group> = [...] }", with_friction,
                      "the (first) group of a [[contact]] condition with friction", parse,
                      steps)


__all__ = ["Loading", "read_loading"]
