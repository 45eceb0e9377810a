"""How a condition is written in a problem file: each class declares its table, one registry.

A condition class registers its table with ``@file_table(section, type, ...)``. The keys the
table accepts, their types and defaults are the class's own dataclass fields and their
``@checked`` specs (``keys`` overrides a spec where the file is stricter than the Python
API); the reader (:mod:`dolfinx_feti.io.condition_tables`) builds every condition from this
registry, and the problem-file reference in docs/index.md is checked against it
(tests/io/test_problemfile_schema.py). A new condition class is read from a problem file
without an edit of the reader.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import MISSING, dataclass, field, fields
from typing import Any

from ...validation import Check, Instance, Maybe

#: (section, type) → the condition class, in the order of registration.
FILE_TABLES: dict[tuple[str, str | None], type] = {}


@dataclass(frozen=True)
class FileTable:
    """The problem-file table of a condition class.

    Attributes:
        section: Where it is written: a top-level array of tables (``"dirichlet"``,
            ``"contact"``, ``"tie"``) or a table inside one (``"friction"``, ``"obstacle"``).
        type: The value of its ``type`` key among the section's classes; None when it is the
            section's only class (no ``type`` key).
        keys: Checks of the file that replace the class's ``@checked`` spec of a field.
        infer_from: Keys that give this type when ``type`` is left out.
        one_of: field → section: the field is written as exactly one key naming a class of
            that section, whose table is its value (an obstacle's ``plane = {...}``).
        needs_elasticity: What needs an elasticity model, for the message ("" if nothing).
        dims: The geometric dimensions it is defined in.
        hint: Appended to the message of a wrong dimension.
        pair: Its ``slave`` and ``master`` are two surfaces: ``"contact"`` (of two bodies,
            with their own nodes), ``"tie"`` (any two), ``""`` (not a pair).
        self_contact: One group as slave and master is allowed.
        components: The field that indexes the problem's components ("" if none).
        per_component: The field of one value, or one per constrained component ("" if none).
        python_only: Fields the file does not take (as do fields without a ``@checked``
            spec: the reader could not check them).
    """

    section: str
    type: str | None = None
    keys: Mapping[str, Check] = field(default_factory=dict)
    infer_from: tuple[str, ...] = ()
    one_of: Mapping[str, str] = field(default_factory=dict)
    needs_elasticity: str = ""
    dims: tuple[int, ...] = (2, 3)
    hint: str = ""
    pair: str = ""
    self_contact: bool = False
    components: str = ""
    per_component: str = ""
    python_only: tuple[str, ...] = ()


@dataclass(frozen=True)
class FileKey:
    """One key of a condition's table: its check, whether it is required, its default."""

    name: str
    check: Check
    required: bool
    default: Any = None


def file_table(section: str, type: str | None = None, **options: Any) -> Callable[[type], type]:
    """Class decorator: register the class's problem-file table (put it above ``@dataclass``)."""

    def register(cls: type) -> type:
        table = FileTable(section, type, **options)
        if (section, type) in FILE_TABLES:
            raise ValueError(f"two condition classes for the problem-file table {section}/{type}")
        cls.file_table = table
        FILE_TABLES[(section, type)] = cls
        return cls

    return register


def classes_of(section: str) -> dict[str | None, type]:
    """The registered classes of a section by their ``type``."""
    return {t: cls for (s, t), cls in FILE_TABLES.items() if s == section}


def file_keys(cls: type) -> list[FileKey]:
    """The keys of a condition class's table, from its fields and their ``@checked`` specs.

    A field written as one of several keys (``one_of``) is not a key itself: the names of
    its section's classes are, none of them required alone (and their tables have no
    ``type``). ``type`` is required unless a class of the section can be inferred. Fields
    without a check, and the table's ``python_only`` ones, keep their defaults.
    """
    table: FileTable = cls.file_table
    named = table.section in {s for c in FILE_TABLES.values() for s in c.file_table.one_of.values()}
    inferred = any(c.file_table.infer_from for c in classes_of(table.section).values())
    out = [] if table.type is None or named else [FileKey("type", Instance(str), not inferred)]
    for f in fields(cls):
        if f.name in table.python_only or (f.name not in cls.checks and
                                           f.name not in table.keys):
            continue
        if f.name in table.one_of:
            out += [FileKey(t, Instance(c), False) for t, c in
                    classes_of(table.one_of[f.name]).items()]
            continue
        check = table.keys.get(f.name, cls.checks[f.name])
        required = f.default is MISSING and f.default_factory is MISSING
        out.append(FileKey(f.name, check, required, None if required else f.default))
    return out


def nested_section(check: Check) -> str | None:
    """The section of the classes a field's check takes, when they have tables (friction)."""
    check = check.check if isinstance(check, Maybe) else check
    if not isinstance(check, Instance) or not check.types:
        return None
    sections = {getattr(t, "file_table", None) and t.file_table.section for t in check.types}
    return sections.pop() if len(sections) == 1 and None not in sections else None
