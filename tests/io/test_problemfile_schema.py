"""The condition tables of a problem file come from the classes' own declarations.

The registry (``problem/conditions/file_table.py``) gives every table's keys; the reader
(``io/condition_tables.py``) builds any registered class, a new one included, without an edit;
the reference in docs/index.md lists exactly the keys the reader accepts, table by table.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

import dolfinx_feti as df
from dolfinx_feti.io.condition_tables import ConditionReader
from dolfinx_feti.io.schema import Checker, condition_keys
from dolfinx_feti.problem.conditions.file_table import FILE_TABLES, file_table
from dolfinx_feti.validation import Integer, Maybe, Real, Text, checked

ROOT = Path(__file__).resolve().parents[2]
TOP = ("dirichlet", "contact", "tie")


def heading(section: str, kind: str | None) -> str:
    """The docs' heading of a condition table."""
    if section in TOP:
        return f"`[[{section}]]`" + (f', `type = "{kind}"`' if kind else "")
    if section == "friction":
        return f'Friction, `type = "{kind}"`'
    return f"{section.capitalize()} `{kind}`"


def documented_keys(docs: str, title: str) -> set[str]:
    """The keys in the first column of the table under ``### <title>``."""
    start = docs.index(f"### {title}\n")
    end = docs.find("\n### ", start + 1)
    block = docs[start:end if end > 0 else None]
    return set(re.findall(r"^\| `([A-Za-z_]+)` \|", block, flags=re.M))


def test_every_condition_table_is_documented_key_for_key():
    docs = (ROOT / "docs" / "index.md").read_text()
    docs = docs[docs.index("## Problem file reference"):]
    keys = condition_keys()
    assert {("contact", "mortar"), ("contact", "node_to_node"), ("contact", "obstacle"),
            ("dirichlet", None), ("tie", None), ("friction", "tresca"), ("friction", "coulomb"),
            ("obstacle", "plane"), ("obstacle", "sphere"), ("obstacle", "cylinder")} <= set(keys)
    for (section, kind), names in keys.items():
        title = heading(section, kind)
        assert f"### {title}\n" in docs, f"docs/index.md has no section '### {title}'"
        assert documented_keys(docs, title) == set(names), title


def test_keys_come_from_the_class_fields_and_checks():
    keys = condition_keys()
    assert keys[("contact", "obstacle")] == ("type", "group", "plane", "sphere", "cylinder",
                                             "friction")
    assert keys[("friction", "coulomb")] == ("type", "coefficient", "rtol", "max_steps")
    assert keys[("tie", None)] == ("slave", "master", "search_distance")
    assert keys[("obstacle", "cylinder")] == ("point", "axis", "radius")  # named, no type


@dataclass(frozen=True)
@checked(slave=Text(), depth=Real(gt=0), layers=Maybe(Integer(ge=1)))
class _Probe:
    """A condition the reader has never seen."""

    slave: str
    depth: float
    layers: int | None = None
    note: object = None  # no check: not a key of the file


@pytest.fixture
def probe():
    cls = file_table("contact", "probe_for_the_test")(_Probe)
    try:
        yield cls
    finally:
        del FILE_TABLES[("contact", "probe_for_the_test")]


def test_a_new_condition_class_is_read_without_an_edit_of_the_reader(probe):
    reader = ConditionReader(Checker(), None, "elasticity", 2)
    data = {"contact": [{"type": "probe_for_the_test", "slave": "top", "depth": 0.5},
                        {"type": "probe_for_the_test", "slave": "top", "depth": -1.0,
                         "layers": 0, "colour": 1},
                        {"type": "probe_for_the_test", "depth": 1.0},
                        {"type": "probe_for_the_test", "slave": "top", "depth": 1.0,
                         "note": "x"}]}
    out = reader.section(data, "contact")
    assert out == [probe("top", 0.5), probe("top", 1.0)]  # an unknown key: a fault, no more
    faults = {f.key: f.message for f in reader.c.faults}
    assert set(faults) == {"contact[1].depth", "contact[1].layers", "contact[1].colour",
                           "contact[2].slave", "contact[3].note"}, faults
    assert condition_keys()[("contact", "probe_for_the_test")] == ("type", "slave", "depth",
                                                                  "layers")
    assert "expected a number > 0, got -1.0" in faults["contact[1].depth"]
    assert "expected an integer >= 1" in faults["contact[1].layers"]
    assert "unknown key" in faults["contact[1].colour"]
    assert "unknown key" in faults["contact[3].note"]
    assert "missing" in faults["contact[2].slave"]


def test_nested_and_named_tables():
    """A friction law is a nested table by its type; an obstacle's shape a key naming it."""
    reader = ConditionReader(Checker(), None, "elasticity", 3)
    data = {"contact": [
        {"group": "top", "sphere": {"center": [0, 0, 1], "radius": 0.5},
         "friction": {"type": "tresca", "bound": math.inf}},
        {"group": "top", "plane": {"point": [0, 0, 0], "normal": [0, 0, 0]},
         "cylinder": {"point": [0, 0, 0], "axis": [1, 0, 0], "radius": 1.0}},
        {"type": "node_to_node", "slave": "a", "master": "b",
         "friction": {"type": "coulomb", "coefficient": 0.3, "rtol": 2.0}}]}
    out = reader.section(data, "contact")
    assert out == [df.RigidObstacle("top", df.Sphere((0.0, 0.0, 1.0), 0.5), df.Tresca(math.inf))]
    faults = {f.key: f.message for f in reader.c.faults}
    assert set(faults) == {"contact[1]", "contact[2].friction.rtol"}, faults
    assert "exactly one obstacle" in faults["contact[1]"]
    assert "expected a number > 0 and < 1" in faults["contact[2].friction.rtol"]
