"""Solver options: declared next to each solver, read under nested prefixes, checked by name.

Each solver declares its options where it is defined (an :class:`~dolfinx_feti.validation.
OptionSet`: default, check, meaning): MPRGP and MPGP in :mod:`dolfinx_feti.qp.mpgp`
(``-feti_mprgp_gamma``, ``_expansion``, ``_alpha``), SMALBE in :mod:`dolfinx_feti.qp.smalbe`
(``-feti_smalbe_rho``, ``_M``, ...; the solver objects read the same declarations, see
:mod:`dolfinx_feti.qp.solver`), the dual penalty and the FETI solve itself here
(``-feti_rtol``, ``-feti_factor``, ...). :class:`SolverOptions` is made from these
declarations: one field per option, named ``<solver>_<option>`` (``smalbe_rho``), so the
keyword ``df.solve(..., smalbe_rho=2)``, the problem file's ``[solver] smalbe_rho = 2`` and the
command line's ``-feti_smalbe_rho 2`` name the same option.

Precedence: the declared defaults < the PETSc options database under ``-feti_`` (what the user
put there) < the command-line tokens the user hands over (``df.solve(..., options=sys.argv)``
or :meth:`SolverOptions.create` with ``argv``) < keyword arguments. Nothing is written into the
PETSc options database, and ``sys.argv`` is read only when it is passed.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from petsc4py import PETSc

from .errors import InputError
from .factor import check_factor, default_factor
from .qp.mprgp import OPTIONS as MPRGP
from .qp.smalbe import OPTIONS as SMALBE
from .validation import (
    Check,
    Choice,
    Flag,
    Integer,
    Maybe,
    Option,
    OptionSet,
    Real,
    checked,
)


class _Factor(Choice):
    """A package name of :mod:`dolfinx_feti.factor` that this PETSc has."""

    def __init__(self) -> None:
        super().__init__("cholmod", "mumps", "petsc")

    def __call__(self, value: Any, name: str) -> Any:  # noqa: D102
        value = super().__call__(value, name)
        check_factor(value)  # known, but not in this PETSc: say so, and what is
        return value


_TOL = Real(gt=0, lt=1)
_COUNT = Integer(ge=1, le=10**9)

#: The options of the FETI solve (no solver prefix: ``-feti_rtol``).
FETI = OptionSet(
    "", "the FETI solve",
    method=Option("auto", Choice("tfeti", "feti1", "fetidp", "auto", "tbeti"), "the FETI "
                  "method: 'auto' (the least measured time: 'feti1' without gluing rows or with "
                  "at most 16 subdomains per body in 2D, 4 in 3D, 'fetidp' with more; "
                  "setup.method_rule.method_by_time, docs/solvers.md), 'tfeti' (Total FETI: "
                  "Dirichlet conditions as rows of B, every subdomain floats), 'feti1' "
                  "(Dirichlet conditions eliminated, kernels only for the floating subdomains), "
                  "'fetidp' (FETI-DP: corner dofs primal too, no coarse space when every body "
                  "is held) or 'tbeti' (Total BETI: boundary element subdomains, 2D, no volume "
                  "loads; docs/beti.md)"),
    rtol=Option(1e-6, _TOL, "the accuracy: with stop_test 'kkt' every KKT residual of the "
                "solution is at most rtol (gluing, Dirichlet and non-penetration violations "
                "against max|u|, complementarity against max|λ| max|u|, the contact rows' "
                "violations times their stiffness against max|λ|, equilibrium against "
                "the load: docs/solvers.md, 'What rtol guarantees'); with 'dual' "
                "||g^P|| <= rtol ||b||"),
    stop_test=Option("kkt", Choice("kkt", "dual"), "'kkt' (stop on the KKT residuals of the "
                     "original problem in physical units: bounded during the iterations, "
                     "checked exactly at the end, continued if one is above rtol) or 'dual' "
                     "(||g^P|| <= rtol ||b|| on the dual QP alone; b depends on the method and "
                     "on gaps far out of reach). Friction uses 'dual'; with qp='penalty' a "
                     "failed check also raises ρ (the residuals fall like 1/ρ)"),
    eq_rtol=Option(None, Maybe(_TOL), "with stop_test 'dual': stop only when also "
                   "||Gλ − e|| <= eq_rtol ||b|| / ||PFP||; "
                   "None: rtol"),
    max_it=Option(5000, _COUNT, "the budget of inner iterations (all outer iterations "
                  "together)"),
    max_outer=Option(1000, _COUNT, "the budget of SMALBE outer iterations (an outer iteration "
                     "with no inner work costs no F-multiplication; 2D elasticity with 512 "
                     "subdomains needs 166, docs/benchmarks_history.md § 3)"),
    factor=Option(default_factor(), _Factor(), "the sparse Cholesky package of the subdomain "
                  "matrices; by default the best this PETSc has (CHOLMOD, else PETSc's own: "
                  "docs/solvers.md), and one it lacks is refused by name"),
    preconditioner=Option("lumped", Choice("none", "lumped", "dirichlet"), "'none', 'lumped' "
                          "(B K Bᵀ) or 'dirichlet' (B S Bᵀ), applied projected in CG and in the "
                          "face (free set) in MPRGP"),
    preconditioner_scaling=Option("stiffness", Choice("stiffness", "multiplicity"),
                                  "'stiffness' (Rixen–Farhat: Z B Δ K Δ Bᵀ Z, Δ = diag(K)⁻¹, "
                                  "Z = (B Δ Bᵀ)⁻¹; multiplicity scaling with a warning where "
                                  "B Δ Bᵀ is singular) or 'multiplicity' (the orthonormal rows "
                                  "of B as they are); measured in docs/solvers.md"),
    qp=Option("auto", Choice("auto", "penalty"), "'auto' (CG / SMALBE / MPRGP as the problem "
              "needs) or 'penalty' (the dual penalty FETI-NCG_ρ: MPRGP on PFP + ρQ, the "
              "equality only approximated: ||Gλ|| = O(1/ρ))"),
    dual_operator=Option("implicit", Choice("implicit", "explicit", "auto"), "how F = B K⁺ Bᵀ "
                         "is applied: 'implicit' (Bᵀ, the subdomain solves, B), 'explicit' "
                         "(one dense matrix B_s K_s⁺ B_sᵀ per subdomain, formed once) or "
                         "'auto' (explicit when its set-up pays within the expected "
                         "F-multiplications: the measured cost model of docs/solvers.md)"),
    norm_rtol=Option(1e-4, _TOL, "the relative tolerance of the Lanczos estimate of ||PFP||"),
    verbose=Option(0, Integer(ge=0, le=2), "0 quiet, 1 one line per phase, 2 also every "
                   "iteration (rank 0 only)"),
    error_if_not_converged=Option(False, Flag(), "raise df.NotConverged (on every rank) "
                                  "instead of returning a solution that did not converge"),
)

#: The dual penalty of ``qp="penalty"`` (``-feti_penalty_rho``).
PENALTY = OptionSet("penalty", "the dual penalty (qp='penalty')",
                    rho=Option(1e3, Real(gt=0), "ρ relative to ||PFP||"))

#: Every option set, in the order of SolverOptions' fields.
OPTION_SETS = (FETI, MPRGP, SMALBE, PENALTY)

#: Flat name → (set, option name, declaration).
DECLARED: dict[str, tuple[OptionSet, str, Option]] = {
    s.key(k): (s, k, o) for s in OPTION_SETS for k, o in s.options.items()}


def option_value(tokens: Sequence[str], i: int) -> str | None:
    """The value of the option at ``tokens[i]``, or None if it has none.

    That is the next token, unless there is none or it is itself an option (it starts with "-"
    and is not a number such as ``-1e-3``).
    """
    value = tokens[i + 1] if i + 1 < len(tokens) else None
    if value is not None and value.startswith("-"):
        try:
            float(value)
        except ValueError:
            return None
    return value


def parse_text(name: str, text: str) -> Any:
    """The value of the option ``name`` written as text (command line, options database).

    Raises:
        InputError: For an unknown name or a text that is not of the option's type.
    """
    if name not in DECLARED:
        close = difflib.get_close_matches(name, list(DECLARED), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise InputError(f"unknown solver option {name!r}{hint}; the options are "
                         f"{', '.join(DECLARED)}")
    return DECLARED[name][2].from_text(text, name)


def kind(name: str) -> str:
    """``'int'``, ``'float'``, ``'bool'`` or ``'str'``: what the option ``name`` holds."""
    check = DECLARED[name][2].check
    check = check.check if isinstance(check, Maybe) else check
    return {Integer: "int", Real: "float", Flag: "bool"}.get(type(check), "str")


def command_line_options(argv: Sequence[str], prefix: str = "-feti_") -> dict[str, Any]:
    """The ``-feti_<name> value`` options among command-line tokens, by name, parsed.

    Other tokens (the program, its own arguments) are skipped; a flag without a value is "1"
    (true, or verbose level 1).

    Raises:
        InputError: For an unknown ``-feti_`` name or a value of the wrong type.
    """
    out = {}
    for i, token in enumerate(argv):
        if not token.startswith(prefix):
            continue
        name = token[len(prefix):]
        value = option_value(argv, i)
        out[name] = parse_text(name, "1" if value is None else value)
    return out


def _database(prefix: str) -> dict[str, Any]:
    """The options set in PETSc's options database under ``prefix`` (read, never written)."""
    db = PETSc.Options(prefix)
    return {name: parse_text(name, db.getString(name)) for name in DECLARED if db.hasName(name)}


class _Methods:
    """The methods of :class:`SolverOptions` (its fields come from the option sets)."""

    @classmethod
    def create(cls, prefix: str = "feti_", *, argv: Sequence[str] | None = None,
               defaults: Mapping[str, Any] | None = None, **kwargs) -> SolverOptions:
        """The options, each source over the previous ones.

        The declared defaults < ``defaults`` < the PETSc options database under ``prefix`` <
        the ``-<prefix><name> value`` tokens of ``argv`` < ``kwargs``. Keyword values that
        are None are ignored (not given). Pass ``argv=sys.argv`` to let the command line of a
        script set options; nothing reads it otherwise.
        """
        for given in (defaults or {}, kwargs):
            _check_names(given)
        values: dict[str, Any] = dict(defaults or {})
        values.update(_database(prefix))
        if argv is not None:
            values.update(command_line_options(argv, f"-{prefix}"))
        values.update({k: v for k, v in kwargs.items() if v is not None})
        out = cls(**values)
        out.validate()
        return out

    def replace(self, **kwargs) -> SolverOptions:
        """A validated copy with some fields changed (unknown names are an InputError)."""
        _check_names(kwargs)
        out = dataclasses.replace(self, **{k: v for k, v in kwargs.items() if v is not None})
        out.validate()
        return out

    def validate(self) -> None:
        """Raise InputError for impossible values (each field is checked when it is set)."""
        dataclasses.replace(self)  # the field checks
        if self.mprgp_alpha == "bb" and self.mprgp_expansion != "fixed":
            raise InputError("mprgp_alpha 'bb' needs mprgp_expansion 'fixed'")

    def of(self, solver: OptionSet) -> dict[str, Any]:
        """The options of one solver by their own names, e.g. ``{'rho': 1.1, 'M': 1.0, ...}``."""
        return {k: getattr(self, solver.key(k)) for k in solver.options}

    def to_dict(self) -> dict:
        """Plain dict (for the JSON report)."""
        return asdict(self)


def check_same_on_ranks(opts: SolverOptions, comm) -> None:
    """Raise on every rank unless the options are equal on every rank of ``comm`` (collective).

    The options steer collective work: a ``rtol`` or ``max_it`` that differs per rank makes
    the ranks stop at different iterations and wait for each other forever, and a ``method``
    or ``factor`` that differs is taken from some rank and ignored on the others. So they are
    compared before any work (one allgather of a few hundred bytes), and the error names each
    option that differs with its value per rank. Floats are compared bit for bit: a ``rtol``
    computed per rank that differs in the last digit is still a different stopping test.

    Args:
        opts: This rank's options.
        comm: The ranks that solve together.

    Raises:
        InputError: On every rank, when some option differs between ranks.
    """
    if comm.size == 1:
        return
    mine = {k: repr(v) for k, v in opts.to_dict().items()}  # repr: NaN-safe, exact for floats
    every = comm.allgather(mine)
    differ = sorted(k for k in mine if any(e.get(k) != mine[k] for e in every))
    differ += sorted({k for e in every for k in e} - set(mine))  # cannot happen in one build
    if differ:
        shown = "; ".join(f"{k}: " + ", ".join(f"rank {r} {e.get(k, '<missing>')}"
                                                 for r, e in enumerate(every))
                          for k in differ[:8])
        raise InputError(f"solver options differ between the ranks: {', '.join(differ)} "
                         f"({shown}); every rank must pass the same options (compute a "
                         "per-rank value once on rank 0 and broadcast it)")


def _check_names(given: Mapping[str, Any]) -> None:
    unknown = set(given) - set(DECLARED)
    if unknown:
        raise InputError(f"unknown solver options {sorted(unknown)}; known: {sorted(DECLARED)}")


def _doc() -> str:
    lines = ["Parameters of the FETI solve, made from the options each solver declares.", "",
             "Every field is checked when set (type, finiteness, range: tolerances in (0, 1), "
             "iteration", "limits integers in [1, 1e9], penalties > 0), with an InputError "
             "naming the option.", "", "Attributes:"]
    for s in OPTION_SETS:
        for k, o in s.options.items():
            where = f"{s.doc}: " if s.name else ""
            lines.append(f"    {s.key(k)}: {where}{o.doc} (default {o.default!r}).")
    return "\n".join(lines)


def _make_class() -> type:
    annotations = {name: {"int": "int", "float": "float", "bool": "bool"}.get(kind(name), "str")
                   for name in DECLARED}
    annotations = {n: (t if DECLARED[n][2].default is not None else f"{t} | None")
                   for n, t in annotations.items()}
    namespace = {"__annotations__": annotations, "__doc__": _doc(), "__module__": __name__,
                 **{n: d[2].default for n, d in DECLARED.items()}}
    cls = type("SolverOptions", (_Methods,), namespace)
    specs: dict[str, Check] = {n: d[2].check for n, d in DECLARED.items()}
    return dataclass(checked("solver option", **specs)(cls))


SolverOptions = _make_class()

__all__ = ["DECLARED", "FETI", "OPTION_SETS", "PENALTY", "SolverOptions",
           "check_same_on_ranks", "command_line_options", "kind", "option_value", "parse_text"]
