"""The record every QP solver of this package returns."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np
from petsc4py import PETSc


class ConvergedReason(IntEnum):
    """Why a solver stopped, shared by all solvers: positive converged, negative diverged.

    PETSc's convention (``KSPConvergedReason``). Each solver reports the reason as its label
    (``QPResult.reason``, e.g. ``'max_it'``); :meth:`of` gives the signed code.
    """

    CONVERGED_RTOL = 2  #: ``'rtol'``: ||g^P|| <= rtol ||b||
    CONVERGED_ATOL = 3  #: ``'atol'``: ||g^P|| <= atol
    CONVERGED_USER = 4  #: ``'stop'``: the caller's test (SMALBE's inner solves)
    CONVERGED_KKT = 5  #: ``'converged'``: SMALBE, the gradient and the equality both small
    DIVERGED_MAX_IT = -3  #: ``'max_it'``: the budget of (inner) iterations is spent
    DIVERGED_MAX_OUTER = -4  #: ``'max_outer'``: the budget of outer iterations is spent
    DIVERGED_UNBOUNDED = -5  #: ``'unbounded'``: a descent direction of no curvature, no bound
    DIVERGED_BREAKDOWN = -6  #: ``'breakdown'``: non-finite values in the iteration
    DIVERGED_NAN = -9  #: ``'non-finite iterate'``: the final iterate is not finite
    DIVERGED_FIXED_POINT = -10  #: ``'coulomb_max_steps'``: the Coulomb fixed point did not settle

    @property
    def label(self) -> str:
        """The solvers' name of the reason (``QPResult.reason``)."""
        return _LABELS[self]

    @classmethod
    def of(cls, label: str) -> ConvergedReason:
        """The reason of a label (``'rtol'`` → ``CONVERGED_RTOL``)."""
        try:
            return _CODES[label]
        except KeyError:
            raise ValueError(f"unknown stopping reason {label!r}; known: {sorted(_CODES)}"
                             ) from None


_LABELS = {
    ConvergedReason.CONVERGED_RTOL: "rtol", ConvergedReason.CONVERGED_ATOL: "atol",
    ConvergedReason.CONVERGED_USER: "stop", ConvergedReason.CONVERGED_KKT: "converged",
    ConvergedReason.DIVERGED_MAX_IT: "max_it", ConvergedReason.DIVERGED_MAX_OUTER: "max_outer",
    ConvergedReason.DIVERGED_UNBOUNDED: "unbounded",
    ConvergedReason.DIVERGED_BREAKDOWN: "breakdown",
    ConvergedReason.DIVERGED_NAN: "non-finite iterate",
    ConvergedReason.DIVERGED_FIXED_POINT: "coulomb_max_steps"}
_CODES = {label: code for code, label in _LABELS.items()}


@dataclass
class QPResult:
    """Outcome of a QP solve.

    Attributes:
        x: The final iterate (the Vec the caller passed in, modified in place).
        converged: Whether the stopping test was met.
        reason: Why the solver stopped (:class:`ConvergedReason` by its label; the signed
            code is ``converged_reason``): ``'rtol'``, ``'atol'``, ``'stop'`` (the user test),
            ``'converged'`` (SMALBE), ``'max_it'``, ``'max_outer'``, ``'unbounded'``,
            ``'breakdown'``.
        iterations: Inner iterations in total (CG steps, expansions and proportionings).
        outer_iterations: Outer iterations (SMALBE); 0 for single-level solvers.
        hessian_mults: Multiplications by the Hessian ``A`` performed inside the call, including
            the norm estimate when the solver had to make one (see ``counts['norm']``).
        counts: Step counts: ``'cg'``, ``'expansion'``, ``'proportioning'``, ``'norm'`` (the
            multiplications of the norm estimate) and, for MPRGP's ``'projcg'`` expansion
            and its projected Galerkin steps, ``'rejected'``; with Krylov recycling
            ``'recycle'`` (Galerkin steps) and ``'galerkin'`` (expansions by the projected
            Galerkin step).
        gP_norm: Final projected gradient norm (for SMALBE the projected gradient of the
            Lagrangian with the returned multiplier).
        Dx_norm: ``||D x||`` at the end, or None without equality constraints.
        b_norm: The norm the relative tolerances were measured against.
        active: Local mask of the entries of ``x`` that sit on a bound, or None.
        active_count: Global number of entries on a bound (the sum of ``active`` over ranks).
        history: One small dict per iteration (MPRGP, CG) or per outer iteration (SMALBE).
        multiplier: Equality multiplier ``mu`` (replicated), SMALBE only.
        objective: Final value of the minimized quadratic (for SMALBE's inner solves: the
            augmented Lagrangian), when the solver has it for free.
    """

    x: PETSc.Vec
    converged: bool
    reason: str
    iterations: int
    outer_iterations: int = 0
    hessian_mults: int = 0
    counts: dict[str, int] = field(default_factory=dict)
    gP_norm: float = math.nan
    Dx_norm: float | None = None
    b_norm: float = math.nan
    active: np.ndarray | None = None
    active_count: int | None = None
    history: list[dict[str, Any]] = field(default_factory=list)
    multiplier: np.ndarray | None = None
    objective: float | None = None

    @property
    def converged_reason(self) -> ConvergedReason:
        """The signed reason (positive: converged, negative: diverged) of ``reason``."""
        return ConvergedReason.of(self.reason)

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable summary without ``x`` and the local ``active`` mask.

        Not collective: the mask differs between ranks, so only its global count is reported.
        """
        return {
            "converged": bool(self.converged),
            "reason": str(self.reason),
            "converged_reason": int(self.converged_reason),
            "iterations": int(self.iterations),
            "outer_iterations": int(self.outer_iterations),
            "hessian_mults": int(self.hessian_mults),
            "counts": {str(k): int(v) for k, v in self.counts.items()},
            "gP_norm": float(self.gP_norm),
            "Dx_norm": None if self.Dx_norm is None else float(self.Dx_norm),
            "b_norm": float(self.b_norm),
            "active_count": None if self.active_count is None else int(self.active_count),
            "history": [_plain(h) for h in self.history],
            "multiplier": None if self.multiplier is None else _plain(self.multiplier),
            "objective": None if self.objective is None else float(self.objective),
        }


def _plain(obj: Any) -> Any:
    """Convert NumPy scalars/arrays (recursively) into JSON-friendly Python objects."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return obj
