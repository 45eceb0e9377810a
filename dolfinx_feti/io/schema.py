"""The problem file's schema: the keys each table accepts, the faults, the checks of values.

The keys of the condition tables (``[[dirichlet]]``, ``[[contact]]``, ``[[tie]]`` and the
friction laws and obstacle shapes inside them) are not listed here: each condition class
declares its own table (:mod:`dolfinx_feti.problem.conditions.file_table`), read by
:mod:`.condition_tables`. The reader is :mod:`.problemfile`.
"""

from __future__ import annotations

import difflib
import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..fem import Elasticity
from ..fem.hyperelastic import NeoHookean, SaintVenantKirchhoff
from ..mesh import MeshData
from ..options import DECLARED
from ..problem.conditions.file_table import FILE_TABLES, file_keys

# ------------------------------------------------------------------------------------------
# The schema: the keys each table accepts (the reference in docs/index.md lists them all)
# ------------------------------------------------------------------------------------------

#: Top-level keys.
TOP_KEYS = ("mesh", "title", "method", "model", "dirichlet", "contact", "tie",
            "decomposition", "solver", "output", "loading")
#: ``[model]`` keys by model type.
MODEL_KEYS = {"elasticity": ("type", "E", "nu", "tractions", "body_force"),
              "neo-hookean": ("type", "E", "nu", "tractions", "body_force"),
              "svk": ("type", "E", "nu", "tractions", "body_force"),
              "poisson": ("type", "source", "k", "flux", "source_boxes")}
#: The solid models of ``[model] type``: small strain, and hyperelastic (solved by Newton).
SOLIDS = {"elasticity": Elasticity, "neo-hookean": NeoHookean, "svk": SaintVenantKirchhoff}
#: Keys of an affine traction ``model.tractions.<group> = {value, gradient}``.
AFFINE_KEYS = ("value", "gradient")
#: ``[[model.source_boxes]]`` keys.
BOX_KEYS = ("min", "max", "value")
#: ``[decomposition]`` keys by decomposition type.
DECOMPOSITION_KEYS = {"tags": ("type", "gluing"),
                      "parts": ("type", "n", "method", "balance", "gluing"),
                      "grid": ("type", "size", "origin", "gluing")}
#: ``[output]`` keys.
OUTPUT_KEYS = ("directory", "xdmf", "report", "nodal_values", "pressure_plot")
#: ``[loading]`` keys.
LOADING_KEYS = ("factors", "values", "translations", "friction", "history")
#: ``[output.pressure_plot]`` keys.
PLOT_KEYS = ("file", "surface", "along")
#: ``[solver]`` keys: the fields of :class:`~dolfinx_feti.SolverOptions`.
SOLVER_KEYS = tuple(DECLARED)

#: ``output.pressure_plot.along`` values.
ALONG = ("x", "y", "z", "arclength")
#: ``decomposition.gluing`` values.
GLUING = ("orthonormal", "redundant", "nonredundant")
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


# ------------------------------------------------------------------------------------------
# Faults
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Fault:
    """One fault of a problem file: where (a key path such as ``contact[1].master``) and what."""

    key: str
    message: str

    def __str__(self) -> str:
        return f"{self.key}: {self.message}" if self.key else self.message


class ProblemFileError(InputError):
    """A problem file that cannot be solved as written; ``faults`` lists every fault found.

    The message has one line per fault, ``<file>: <key>: <what is wrong, what was expected>``.
    """

    def __init__(self, path: str | Path, faults: Sequence[Fault]) -> None:
        self.path = str(path)
        self.faults = list(faults)
        n = len(self.faults)
        lines = [f"{self.path}: {n} error{'s' if n != 1 else ''} in the problem file"]
        lines += [f"{self.path}: {f}" for f in self.faults]
        super().__init__("\n".join(lines))


def key_path(parent: str, name: str | int) -> str:
    """The key path of ``name`` inside ``parent`` (``contact[1].master``)."""
    if isinstance(name, int):
        return f"{parent}[{name}]"
    part = name if _BARE_KEY.fullmatch(name) else json.dumps(name)
    return f"{parent}.{part}" if parent else part


def describe(value: Any) -> str:
    """What a TOML value is, for a message (``a string ('x')``, ``an array of 3 item(s)``)."""
    if isinstance(value, bool):
        return f"a boolean ({str(value).lower()})"
    if isinstance(value, int | float):
        return f"the number {value}"
    if isinstance(value, str):
        return f"a string ({value!r})"
    if isinstance(value, list):
        return f"an array of {len(value)} item(s)"
    if isinstance(value, dict):
        return "a table"
    return f"a {type(value).__name__}"


class Checker:
    """Collects faults while reading values; each reader returns None for a bad value."""

    def __init__(self) -> None:
        self.faults: list[Fault] = []

    def fault(self, key: str, message: str) -> None:
        """Collect a fault at ``key``."""
        self.faults.append(Fault(key, message))

    def table(self, value: Any, key: str, allowed: Sequence[str] | None,
              required: Sequence[str] = (), what: str = "a table") -> dict | None:
        """A table with only ``allowed`` keys (any key when None) and all ``required`` ones."""
        if not isinstance(value, dict):
            self.fault(key, f"expected {what}, got {describe(value)}")
            return None
        for k in value:
            if allowed is not None and k not in allowed:
                close = difflib.get_close_matches(k, allowed, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                self.fault(key_path(key, k), f"unknown key{hint}; expected one of: "
                           f"{', '.join(allowed)}")
        for k in required:
            if k not in value:
                self.fault(key_path(key, k), "missing: this key is required")
        return value

    def array_of_tables(self, value: Any, key: str) -> list:
        """The tables of ``[[key]]`` sections (none when absent)."""
        if value is None:
            return []
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            self.fault(key, f"expected an array of tables ([[{key}]] sections), got "
                       f"{describe(value)}")
            return []
        return value

    def number(self, value: Any, key: str, expected: str = "a number", ok=None,
               integer: bool = False) -> float | None:
        """A finite number (an integer when ``integer``) for which ``ok(value)`` holds."""
        kind = "an integer" if integer else "a number"
        if isinstance(value, bool) or not isinstance(value, int | float) or \
                (integer and not isinstance(value, int)):
            self.fault(key, f"expected {expected if expected != 'a number' else kind}, got "
                       f"{describe(value)}")
            return None
        if not math.isfinite(value):
            self.fault(key, f"expected {expected}, got {value} (not a finite number)")
            return None
        if ok is not None and not ok(value):
            self.fault(key, f"expected {expected}, got {value}")
            return None
        return value

    def string(self, value: Any, key: str, choices: Sequence[str] | None = None) -> str | None:
        """A string (one of ``choices`` when given)."""
        if not isinstance(value, str):
            what = "a string" if choices is None else "one of " + ", ".join(map(repr, choices))
            self.fault(key, f"expected {what}, got {describe(value)}")
            return None
        if choices is not None and value not in choices:
            close = difflib.get_close_matches(value, choices, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            self.fault(key, f"expected one of {', '.join(map(repr, choices))}, got "
                       f"{value!r}{hint}")
            return None
        return value

    def vector(self, value: Any, key: str, length: int | None, what: str = "numbers"
               ) -> list[float] | None:
        """An array of ``length`` finite numbers (any length when None)."""
        n = "" if length is None else f"{length} "
        if not isinstance(value, list) or any(isinstance(v, bool) or
                                              not isinstance(v, int | float) for v in value):
            self.fault(key, f"expected an array of {n}{what}, got {describe(value)}")
            return None
        if length is not None and len(value) != length:
            self.fault(key, f"expected an array of {n}{what} (the mesh is {length}D), got "
                       f"{len(value)}")
            return None
        if not all(math.isfinite(v) for v in value):
            self.fault(key, f"expected finite {what}, got {value}")
            return None
        return [float(v) for v in value]

    def per_body(self, value: Any, key: str, mesh: MeshData | None, expected: str, ok,
                 complete: bool = True) -> float | dict[str, float] | None:
        """A number, or a table body name → number (covering every body when ``complete``)."""
        if not isinstance(value, dict):
            return self.number(value, key, f"{expected}, or a table of one per body", ok)
        out, good = {}, True
        for body, v in value.items():
            v = self.number(v, key_path(key, body), expected, ok)
            good &= v is not None
            out[body] = v
            if mesh is not None and body not in mesh.body_names:
                self.fault(key_path(key, body), f"unknown body; the mesh's bodies are "
                           f"{list(mesh.body_names)}")
                good = False
        if mesh is not None and complete:
            missing = [b for b in mesh.body_names if b not in value]
            if missing:
                self.fault(key, f"no value for bodies {missing}: give a number for every body "
                           f"of {list(mesh.body_names)}, or one number for all")
                good = False
        return out if good else None

    def group(self, value: Any, key: str, mesh: MeshData | None) -> str | None:
        """The name of a non-empty boundary group of the mesh."""
        name = self.string(value, key)
        if name is None or mesh is None:
            return name
        if name not in mesh.facet_groups:
            if name in mesh.body_names:
                self.fault(key, f"{name!r} is a body (a physical group of dimension "
                           f"{mesh.tdim}), not a boundary group; the boundary groups are "
                           f"{sorted(mesh.facet_groups)}")
            else:
                close = difflib.get_close_matches(name, list(mesh.facet_groups), n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                self.fault(key, f"unknown boundary group {name!r}{hint}; the mesh's boundary "
                           f"groups (dimension {mesh.tdim - 1}) are {sorted(mesh.facet_groups)}")
            return None
        if mesh.facet_groups[name].shape[0] == 0:
            self.fault(key, f"boundary group {name!r} holds no facet")
            return None
        return name


def condition_keys() -> dict[tuple[str, str | None], tuple[str, ...]]:
    """The keys of every condition table, by (section, type), from the classes' own tables."""
    return {st: tuple(k.name for k in file_keys(cls)) for st, cls in FILE_TABLES.items()}
