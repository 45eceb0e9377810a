"""What every QP solver object shares: declared options, read from PETSc's database by prefix.

A solver is set up once (its variants and options) and then solves any number of QPs
(:class:`.problem.QP`), as PERMON's QPS objects do. Its options are declared on the class as
an :class:`~dolfinx_feti.validation.OptionSet` (default, check, meaning); the option ``gamma``
of the set named ``mprgp`` is ``-<prefix>mprgp_gamma`` in PETSc's options database, the same
name as the field ``mprgp_gamma`` of :class:`~dolfinx_feti.SolverOptions`. A solver that owns
another (SMALBE its inner solver) hands it the same prefix, as a PETSc KSP does its PC.

Precedence: the declared defaults < the options database under the prefix (read only when a
prefix is given) < the keyword arguments of the constructor (None meaning "not given").
A new solver is a subclass beside its twins: declare ``options``, take them in ``__init__``
through :meth:`QPSolver._set_options`, implement ``solve(qp, x) -> QPResult``.
"""

from __future__ import annotations

from typing import Any, ClassVar

from petsc4py import PETSc

from ..validation import OptionSet
from .problem import QP
from .result import QPResult


def database_options(options: OptionSet, prefix: str) -> dict[str, Any]:
    """The options of ``options`` set in PETSc's database as ``-<prefix><name>_<option>``.

    Read, never written; each value typed and checked by its declaration.

    Raises:
        InputError: For a value of the wrong type or out of range, naming the option.
    """
    db = PETSc.Options(prefix)
    out = {}
    for k, opt in options.options.items():
        key = options.key(k)
        if db.hasName(key):
            out[k] = opt.check(opt.from_text(db.getString(key), key), f"solver option {key}")
    return out


class QPSolver:
    """Base of the QP solvers: the declared options and the solve of a :class:`.problem.QP`.

    Attributes:
        options: The declared options of the class (the set's name is the nested prefix).
        name: The solver's name in messages and reports.
        inner_capable: Whether it can be SMALBE's inner solver.
        options_prefix: The prefix the options were read under, or None.
    """

    options: ClassVar[OptionSet] = OptionSet("", "no options")
    name: ClassVar[str] = "qp"
    #: Whether ``solve(qp, x)`` also takes ``stop``, ``b_norm``, ``g``, ``g_valid``, ``rtol``,
    #: ``atol`` and ``max_it`` (a warm-started solve under the caller's test): what SMALBE
    #: needs of its inner solver.
    inner_capable: ClassVar[bool] = False

    def _set_options(self, options_prefix: str | None, **given: Any) -> None:
        """Set each declared option as an attribute: default < database < ``given``.

        Raises:
            InputError: For a given value that its declaration refuses, naming it.
        """
        values = {k: o.default for k, o in self.options.options.items()}
        if options_prefix is not None:
            values.update(database_options(self.options, options_prefix))
        for k, v in given.items():
            if v is not None:
                opt = self.options.options[k]
                values[k] = opt.check(v, f"{self.name} {k}")
        self.options_prefix = options_prefix
        for k, v in values.items():
            setattr(self, k, v)

    def option_values(self) -> dict[str, Any]:
        """The declared options by name, as this solver holds them."""
        return {k: getattr(self, k) for k in self.options.options}

    def solve(self, qp: QP, x: PETSc.Vec) -> QPResult:
        """Minimize ``qp`` from the start ``x`` (overwritten with the solution; collective)."""
        raise NotImplementedError

    def __repr__(self) -> str:
        opts = ", ".join(f"{k}={v!r}" for k, v in self.option_values().items())
        return f"{type(self).__name__}({opts})"


__all__ = ["QPSolver", "database_options"]
