"""Declarative checks of public arguments: type, finiteness and range, refused by name.

Each public class states what its arguments must be, next to its definition::

    @dataclass(frozen=True)
    @checked(slave=Text(), match_tol=Real(gt=0, lt=1), gap=Maybe(Real()))
    class NodeToNode: ...

and an unsuitable value is refused when the object is made, before any heavy work, with an
:class:`~dolfinx_feti.InputError` that names the argument and the value::

    NodeToNode.match_tol must be a finite number > 0 and < 1, got nan

The checks know nothing of meshes: what depends on the mesh (a group exists, a vector has gdim
components) is checked where the mesh is known (:class:`~dolfinx_feti.ContactProblem`).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from .errors import InputError

#: Material constants beyond this (or below its inverse) overflow or underflow in the solver's
#: products (K K⁺ K, norms): E = 1e±150 solves the B1 plane-strain pair, E = 1e±200 does not.
SAFE_MAGNITUDE = 1e100


class Check:
    """A condition on one value; ``check(value, name)`` returns it (normalized) or raises."""

    what = "a value"

    def ok(self, value: Any) -> tuple[bool, Any]:
        """Whether ``value`` passes, and its normalized form."""
        raise NotImplementedError

    def __call__(self, value: Any, name: str) -> Any:
        """``value`` normalized, or an InputError ``<name> must be <what>, got <value>``."""
        good, out = self.ok(value)
        if not good:
            raise InputError(f"{name} must be {self.what}, got {_show(value)}")
        return out


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def _range(gt=None, ge=None, lt=None, le=None) -> str:
    def num(v):
        return str(v) if isinstance(v, int) else f"{v:g}"

    parts = [f"{op} {num(v)}" for op, v in ((">", gt), (">=", ge), ("<", lt), ("<=", le))
             if v is not None]
    return " and ".join(parts)


class Real(Check):
    """A real number (not a bool or a string), finite unless ``inf`` allows +inf, in range."""

    def __init__(self, gt=None, ge=None, lt=None, le=None, inf: bool = False,
                 finite: bool = True) -> None:
        self.bounds = (gt, ge, lt, le)
        self.inf, self.finite = inf, finite
        rng = _range(gt, ge, lt, le)
        self.what = ("a finite number" if finite else "a number") + (f" {rng}" if rng else "") \
            + (" (or inf)" if inf else "")

    def ok(self, value):  # noqa: D102
        if not _is_number(value):
            return False, value
        v = float(value)
        if math.isnan(v):
            return not self.finite, v
        if math.isinf(v):
            return (v > 0 and self.inf) or not self.finite, v
        gt, ge, lt, le = self.bounds
        good = ((gt is None or v > gt) and (ge is None or v >= ge) and (lt is None or v < lt)
                and (le is None or v <= le))
        return good, v


class Integer(Check):
    """An integer in range; an integral float (``1e4``) is taken as the integer it is."""

    def __init__(self, ge=None, le=None) -> None:
        self.bounds = (ge, le)
        rng = _range(ge=ge, le=le)
        self.what = "an integer" + (f" {rng}" if rng else "")

    def ok(self, value):  # noqa: D102
        if not _is_number(value):
            return False, value
        if isinstance(value, numbers.Integral):
            v = int(value)
        elif math.isfinite(float(value)) and float(value).is_integer():
            v = int(value)
        else:
            return False, value
        ge, le = self.bounds
        return (ge is None or v >= ge) and (le is None or v <= le), v


class Flag(Check):
    """A boolean (``True``/``False``; from text: true/false, yes/no, 1/0, on/off)."""

    what = "a boolean (true or false)"
    _TEXT = {"true": True, "yes": True, "1": True, "on": True,
             "false": False, "no": False, "0": False, "off": False}

    def ok(self, value):  # noqa: D102
        if isinstance(value, bool | np.bool_):
            return True, bool(value)
        if isinstance(value, str) and value.lower() in self._TEXT:
            return True, self._TEXT[value.lower()]
        return False, value


class Choice(Check):
    """One of a few strings."""

    def __init__(self, *choices: str) -> None:
        self.choices = choices
        self.what = "one of " + ", ".join(map(repr, choices))

    def ok(self, value):  # noqa: D102
        return isinstance(value, str) and value in self.choices, value


class Text(Check):
    """A non-empty string (a group or body name)."""

    what = "a non-empty string (a name)"

    def ok(self, value):  # noqa: D102
        return isinstance(value, str) and bool(value), value


class Function(Check):
    """A callable."""

    def __init__(self, what: str = "a function") -> None:
        self.what = what

    def ok(self, value):  # noqa: D102
        return callable(value), value


class Instance(Check):
    """An instance of one of some classes (or an object with the given methods)."""

    def __init__(self, *types: type, methods: Sequence[str] = (), what: str = "") -> None:
        self.types, self.methods = types, tuple(methods)
        self.what = what or " or ".join(t.__name__ for t in types)

    def ok(self, value):  # noqa: D102
        if self.types and isinstance(value, self.types):
            return True, value
        return bool(self.methods) and all(callable(getattr(value, m, None))
                                          for m in self.methods), value


class Vector(Check):
    """A sequence of finite numbers (of ``length`` items), returned as a tuple of floats."""

    def __init__(self, length: int | None = None, nonzero: bool = False) -> None:
        self.length, self.nonzero = length, nonzero
        self.what = (f"a sequence of {length} finite numbers" if length else
                     "a sequence of finite numbers (one per coordinate)") + \
            (", not all zero" if nonzero else "")

    def ok(self, value):  # noqa: D102
        if isinstance(value, str | bytes | Mapping) or not isinstance(value, Sequence | np.ndarray):
            return False, value
        items = list(np.asarray(value, dtype=object).ravel()) if isinstance(value, np.ndarray) \
            else list(value)
        if not items or not all(_is_number(v) and math.isfinite(float(v)) for v in items):
            return False, value
        out = tuple(float(v) for v in items)
        if self.length is not None and len(out) != self.length:
            return False, value
        if self.nonzero and not any(out):
            return False, value
        return True, out


class Maybe(Check):
    """None, or what ``check`` accepts."""

    def __init__(self, check: Check) -> None:
        self.check = check
        self.what = f"None or {check.what}"

    def ok(self, value):  # noqa: D102
        return (True, None) if value is None else self.check.ok(value)


class Either(Check):
    """What the first of ``checks`` that passes accepts."""

    def __init__(self, *checks: Check, what: str = "") -> None:
        self.checks = checks
        self.what = what or ", or ".join(c.what for c in checks)

    def ok(self, value):  # noqa: D102
        for c in self.checks:
            good, out = c.ok(value)
            if good:
                return True, out
        return False, value


class SequenceOf(Check):
    """A list or tuple whose items pass ``item`` (distinct when ``unique``)."""

    def __init__(self, item: Check, unique: bool = False, nonempty: bool = False) -> None:
        self.item, self.unique, self.nonempty = item, unique, nonempty
        self.what = ("a non-empty " if nonempty else "a ") + f"list of {item.what}" + \
            (" (distinct)" if unique else "")

    def ok(self, value):  # noqa: D102
        if isinstance(value, str | bytes | Mapping) or not isinstance(value, Sequence | np.ndarray):
            return False, value
        items = [self.item.ok(v) for v in value]
        out = [v for _, v in items]
        good = all(g for g, _ in items) and (not self.nonempty or bool(out))
        if good and self.unique:
            good = len(set(out)) == len(out)
        return good, out


class MappingOf(Check):
    """A mapping whose keys and values pass ``key`` and ``value``; returned as a dict."""

    def __init__(self, key: Check, value: Check, what: str = "") -> None:
        self.key, self.value = key, value
        self.what = what or f"a mapping of {key.what} to {value.what}"

    def ok(self, value):  # noqa: D102
        if not isinstance(value, Mapping):
            return False, value
        out = {}
        for k, v in value.items():
            gk, k2 = self.key.ok(k)
            gv, v2 = self.value.ok(v)
            if not (gk and gv):
                return False, value
            out[k2] = v2
        return True, out


def per_body(check: Check) -> Either:
    """A value for every body: one value, or a mapping body name → value."""
    return Either(check, MappingOf(Text(), check), what=f"{check.what}, or a mapping body name "
                  f"→ {check.what}")


def evaluate(fn: Callable, x: np.ndarray, what: str, shapes: Sequence[tuple[int, ...]]
             ) -> np.ndarray:
    """Call a user function of the node coordinates ``x`` and check the shape of its result.

    Args:
        fn: The user's function.
        x: The node coordinates (n, gdim).
        what: The function as the user knows it, for messages (``Dirichlet('top').value``).
        shapes: The shapes the result may have.

    Raises:
        InputError: Naming the function, when it raises or returns another shape.
    """
    try:
        out = np.asarray(fn(x), dtype=float)
    except InputError:
        raise
    except Exception as e:  # the user's code: say which function failed
        raise InputError(f"{what}(x) raised {type(e).__name__}: {e}") from e
    if out.shape not in shapes:
        raise InputError(f"{what}(x) must return an array of shape "
                         f"{' or '.join(map(str, shapes))} for x of shape {x.shape}, got "
                         f"{out.shape}")
    return out


def check_arguments(owner: str, specs: Mapping[str, Check], values: Mapping[str, Any]
                    ) -> dict[str, Any]:
    """Check ``values[name]`` against ``specs[name]``; the normalized values by name.

    Raises:
        InputError: ``<owner>.<name> must be <what>, got <value>`` for the first bad value.
    """
    return {name: spec(values[name], f"{owner}.{name}") for name, spec in specs.items()}


def checked(label: str | None = None, /, **specs: Check) -> Callable[[type], type]:
    """Class decorator for a dataclass: check the fields named in ``specs`` when it is made.

    Put it below ``@dataclass`` (it adds the ``__post_init__`` that the dataclass's
    ``__init__`` then calls). The checks run first in ``__post_init__`` (before the class's
    own, if any); normalized values (e.g. a list of coordinates as a tuple of floats) replace
    the given ones, also in a frozen dataclass. Messages name ``<Class>.<field>``, or
    ``<label> <field>`` when a ``label`` is given.
    """

    def decorate(cls: type) -> type:
        own = cls.__dict__.get("__post_init__")

        names = [n for n, c in specs.items() if isinstance(c, Text)]

        def __post_init__(self) -> None:
            # the object named by its names, e.g. Dirichlet('top'), when they are names
            ids = [getattr(self, n) for n in names]
            owner = cls.__name__ + (f"({', '.join(map(repr, ids))})"
                                    if ids and all(isinstance(i, str) for i in ids) else "")
            given = {name: getattr(self, name) for name in specs}
            values = check_arguments(owner, specs, given) if label is None else \
                {name: spec(given[name], f"{label} {name}") for name, spec in specs.items()}
            for name, value in values.items():
                if value is not getattr(self, name):
                    object.__setattr__(self, name, value)
            if own is not None:
                own(self)

        __post_init__.__doc__ = f"Check {', '.join(specs)} (:mod:`dolfinx_feti.validation`)."
        cls.__post_init__ = __post_init__
        cls.checks = dict(specs)
        return cls

    return decorate



class Option:
    """A setting of a solver: its default, its check and what it does (for docs and messages)."""

    def __init__(self, default: Any, check: Check, doc: str) -> None:
        self.default, self.check, self.doc = default, check, doc

    def from_text(self, text: str, name: str) -> Any:
        """The value written as ``text`` (command line, options database), typed, not checked.

        Numbers become int or float by the check, ``none`` is None where None is allowed;
        strings and flags are returned as they are (the check reads them).

        Raises:
            InputError: ``solver option <name> must be <what>`` for a text of the wrong type.
        """
        check = self.check
        if isinstance(check, Maybe):
            if text.lower() == "none":
                return None
            check = check.check
        try:
            if isinstance(check, Integer):
                value = float(text)
                return int(value) if value.is_integer() else value
            if isinstance(check, Real):
                return float(text)
        except ValueError:
            raise InputError(f"solver option {name} must be {check.what}, got {text!r}"
                             ) from None
        return text


class OptionSet:
    """The options of one solver, declared next to it, read under a nested prefix.

    ``OptionSet("smalbe", rho=Option(...))`` is the option ``-<prefix>smalbe_rho`` of the PETSc
    options database and the field ``smalbe_rho`` of :class:`~dolfinx_feti.SolverOptions`;
    an empty ``name`` puts the options at the top level (``-<prefix>rtol``).
    """

    def __init__(self, name: str, doc: str, **options: Option) -> None:
        self.name, self.doc, self.options = name, doc, options

    def key(self, option: str) -> str:
        """The flat name of an option: ``<name>_<option>`` (or ``<option>`` at the top)."""
        return f"{self.name}_{option}" if self.name else option

    def keys(self) -> dict[str, str]:
        """Flat name → option name."""
        return {self.key(k): k for k in self.options}


__all__ = ["SAFE_MAGNITUDE", "Check", "Choice", "Either", "Flag", "Function", "Instance",
           "Integer", "MappingOf", "Maybe", "Option", "OptionSet", "Real", "SequenceOf", "Text",
           "Vector", "check_arguments", "checked", "evaluate", "per_body"]
