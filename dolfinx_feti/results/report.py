"""The solve report: what was solved, how the solver did, the KKT residuals, where time went."""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any


@dataclass
class Report:
    """Summary of one solve (identical on every rank).

    Attributes:
        method: Decomposition method ("TFETI", "FETI-1" or "FETI-DP").
        solver: QP solver used: "cg" (no inequality), "mprgp" (no equality), "smalbe".
        converged: Whether the solver met its stopping test.
        reason: Why it stopped (the label of ``converged_reason``).
        converged_reason: The signed reason shared by all solvers
            (:class:`~dolfinx_feti.qp.ConvergedReason`): positive converged and why (2 rtol,
            5 SMALBE's test), negative diverged and why (-3 max_it, -4 max_outer, -5 unbounded,
            -6 breakdown, -9 non-finite iterate, -10 Coulomb fixed point).
        sizes: primal, dual, equality and inequality rows, subdomains, coarse dimension, ranks.
        outer_iterations, iterations: SMALBE outer and (all) inner iterations.
        hessian_mults: F multiplications inside the QP solver (the figure of merit), and
            those of the stopping test's checks before the last one (one each).
        hessian_mults_total: All F multiplications, norm estimate and recovery included.
        counts: CG, expansion and proportioning steps.
        gP_rel: ||g^P|| / ||b|| at the end.
        G_lambda: ||Gλ − e|| / ||e|| (or the absolute value when e = 0).
        kkt: dual_feasibility, primal_feasibility, equality, complementarity, equilibrium.
        max_penetration: Largest violation of a non-penetration condition (length units).
        norm_F: The estimate of ||PFP|| used by the solver.
        timings: Seconds per phase (maximum over ranks).
        warnings: Anything the user should know (e.g. a rigid motion left undetermined).
        stopping: The stopping test: ``test`` (``'kkt'`` or ``'dual'``), ``checks`` (exact
            checks of the KKT residuals, i.e. recoveries of u), ``check_hessian_mults`` and
            ``check_kplus_solves`` (what the checks before the last cost: the last recovery
            is the solution's own), ``history`` (per check the bound and the residuals).
    """

    method: str = "TFETI"
    solver: str = ""
    converged: bool = False
    reason: str = ""
    converged_reason: int = 0
    sizes: dict[str, int] = field(default_factory=dict)
    outer_iterations: int = 0
    iterations: int = 0
    hessian_mults: int = 0
    hessian_mults_total: int = 0
    counts: dict[str, int] = field(default_factory=dict)
    gP_rel: float = float("nan")
    G_lambda: float = float("nan")
    kkt: dict[str, float] = field(default_factory=dict)
    max_penetration: float = 0.0
    norm_F: float = float("nan")
    timings: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    stopping: dict[str, Any] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Plain, JSON-serialisable data."""
        return asdict(self)

    def save_json(self, path: str | os.PathLike) -> None:
        """Write the report as JSON atomically (a temporary file renamed into place)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it 0600; a report is an ordinary file
        try:
            with os.fdopen(fd, "w") as f:
                json.dump(self.to_dict(), f, indent=2, default=float)
            os.replace(tmp, path)
        except BaseException:
            os.unlink(tmp)
            raise

    def summary(self) -> str:
        """A few human-readable lines."""
        s = self.sizes
        lines = [
            f"{self.method} + {self.solver}: {'converged' if self.converged else 'NOT CONVERGED'}"
            f" ({self.reason}, reason {self.converged_reason:+d})",
            f"  sizes: {s.get('primal', 0)} primal dofs, {s.get('dual', 0)} multipliers "
            f"({s.get('inequality', 0)} contact), {s.get('subdomains', 0)} subdomains, "
            f"{s.get('ranks', 1)} rank(s)",
            f"  iterations: {self.outer_iterations} outer, {self.iterations} inner, "
            f"{self.hessian_mults} F-multiplications ({self.hessian_mults_total} in all)",
            f"  stopping test: {self.stopping.get('test', '?')}, "
            f"{self.stopping.get('checks', 0)} exact KKT check(s)",
            f"  ||g^P||/||b|| = {self.gP_rel:.2e}, ||G lambda - e|| (rel) = {self.G_lambda:.2e}",
            "  KKT: " + ", ".join(f"{k} {v:.2e}" for k, v in self.kkt.items()),
            "  time [s]: " + ", ".join(f"{k} {v:.3f}" for k, v in self.timings.items()),
        ]
        lines += [f"  warning: {w}" for w in self.warnings]
        return "\n".join(lines)
