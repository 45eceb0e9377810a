"""Hyperelastic materials from a stored energy density: residual and tangent by UFL.

Total Lagrangian: the unknown is the displacement u from the reference configuration,
F = I + ∇u, and the potential is

    Π(u) = ∫ ψ(F) dX − load · (∫ b·u dX + Σ_groups ∫ t·u dS)

with dead loads b, t per reference volume and area. The residual R = ∂Π/∂u (in the direction
of the test function) and the tangent K_t = ∂R/∂u are ``ufl.derivative`` of it, evaluated at
the current iterate: a material handed to :class:`~dolfinx_feti.ContactProblem` gives at the
unloaded state (u = 0) the forms ``(K_t(0), −R(0))`` — the linearization — and
:mod:`dolfinx_feti.drivers.newton` attaches a :class:`NewtonState` (``with_state``) so the same
callback gives ``(K_t(u_k), −R(u_k))`` at each iterate. The material says how it is solved by
its attribute ``solve_by = "newton"`` (the registry of :func:`dolfinx_feti.solve`).
"""

from __future__ import annotations

import copy
import inspect
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import ufl

from .. import compat
from ..errors import InputError
from ..validation import check_arguments
from .forms import ELASTICITY, check_groups, check_magnitude, per_body_values, scaled_form

Scalar = float | Mapping[str, float]


class NewtonState:
    """The current iterate of a Newton solve, per run of subdomains (canonical dof order).

    Attributes:
        values: ``sub.indices`` → the displacement of those subdomains' canonical dofs.
    """

    def __init__(self) -> None:
        self.values: dict[tuple[int, ...], np.ndarray] = {}

    def set(self, data, u: np.ndarray) -> None:
        """Take the local primal vector ``u`` of the subdomains of ``data`` (SubdomainData)."""
        start = 0
        for sub in data.assemblers:
            n = sub.nodes.size * data.bs
            self.values[sub.indices] = u[start:start + n]
            start += n
        if start != u.size:
            raise AssertionError("the Newton state does not cover the rank's primal vector")


class Hyperelastic:
    """A hyperelastic material given by its stored energy density ψ(F) (UFL).

    Args:
        energy: ``energy(F)`` → ψ, or ``energy(F, sub)`` (``sub`` the
            :class:`~dolfinx_feti.fem.Subdomain`: per-body constants by ``sub.cellwise``), a
            UFL expression of the deformation gradient F = I + ∇u (gdim × gdim; plane strain in
            2D).
        tractions: Boundary group → dead traction (force per reference area).
        body_force: A constant vector, or ``body_force(x)`` of the reference coordinate.
        degree: Degree of the Lagrange space (1 or 2).
        load_factor: Multiplies every load (a runtime constant of the forms).
    """

    value_size = "vector"
    #: How :func:`dolfinx_feti.solve` and :func:`dolfinx_feti.solve_path` solve problems of
    #: this material (the key of :data:`dolfinx_feti.solver.SOLVE_BY`).
    solve_by = "newton"

    def __init__(self, energy: Callable, tractions: Mapping[str, Sequence[float]] | None = None,
                 body_force: Sequence[float] | Callable | None = None, degree: int | None = 1,
                 load_factor: float = 1.0) -> None:
        if not callable(energy):
            raise InputError(f"Hyperelastic: energy must be a function energy(F) or "
                             f"energy(F, sub) returning a UFL expression, got {energy!r}")
        spec = {k: ELASTICITY[k] for k in ("tractions", "body_force", "degree", "load_factor")}
        args = check_arguments("Hyperelastic", spec, {
            "tractions": tractions or {}, "body_force": body_force, "degree": degree,
            "load_factor": load_factor})
        self.energy = energy
        self.tractions, self.body_force = args["tractions"], args["body_force"]
        self.degree, self.load_factor = args["degree"], args["load_factor"]
        try:
            params = inspect.signature(energy).parameters
            self._with_sub = len(params) >= 2
        except (TypeError, ValueError):
            self._with_sub = False
        self._state: NewtonState | None = None
        self._cache: dict = {}

    def stiffness_key(self) -> tuple:
        """What the forms depend on besides the loads (a load step keeps it)."""
        return type(self).__name__, id(self.energy), self.degree, self._material_key()

    def _material_key(self) -> tuple:
        return ()

    def with_state(self, state: NewtonState) -> Hyperelastic:
        """A copy whose forms are evaluated at the iterate held by ``state``."""
        new = copy.copy(self)
        new._state, new._cache = state, {}
        return new

    def loads_scaled(self, s: float) -> Hyperelastic:
        """A copy whose dead loads are ``s`` times these (a step of a ``[loading]`` path).

        The factor multiplies the load factor, a runtime constant of the forms: the material
        and the compiled forms' shape stay.
        """
        new = copy.copy(self)
        new.load_factor, new._cache = self.load_factor * float(s), {}
        return new

    def check(self, mesh) -> None:
        """Validate the loads against ``mesh`` (a vector problem: 2D or 3D)."""
        if mesh.gdim not in (2, 3):
            raise InputError(f"Hyperelastic needs a 2D or 3D mesh, got gdim = {mesh.gdim}")
        check_groups(self.tractions, mesh, "traction")
        for name, t in self.tractions.items():
            if not callable(t) and np.asarray(t, dtype=float).size != mesh.gdim:
                raise InputError(f"traction on {name!r} has {np.asarray(t).size} components; "
                                 f"the mesh is {mesh.gdim}D")
        if self.body_force is not None and not callable(self.body_force) and \
                np.asarray(self.body_force, dtype=float).size != mesh.gdim:
            raise InputError(f"body force has {np.asarray(self.body_force).size} components; "
                             f"the mesh is {mesh.gdim}D")

    def _psi(self, F, sub):
        return self.energy(F, sub) if self._with_sub else self.energy(F)

    def _external(self, V, sub, u):
        """The work of the dead loads (None without loads)."""
        msh = compat.space_mesh(V)
        x = ufl.SpatialCoordinate(V.mesh)
        W = 0
        if self.body_force is not None:
            b = self.body_force(x) if callable(self.body_force) else compat.constant(
                msh, [float(c) for c in self.body_force])
            W += ufl.inner(b, u) * sub.dx()
        for name, t in self.tractions.items():
            if sub.has_facets(name):
                tv = t(x) if callable(t) else compat.constant(msh, [float(c) for c in t])
                W += ufl.inner(tv, u) * sub.ds(name)
        return scaled_form(W, self.load_factor, V) if isinstance(W, ufl.Form) else None

    def _forms_of(self, V, sub):
        """(u, K_t form, −R form, Π form) on this run of subdomains, made once."""
        key = sub.indices
        made = self._cache.get(key)
        if made is not None and compat.same_space(made[0].ufl_function_space(), V):
            return made
        u = compat.function(V, "u")
        v, du = ufl.TestFunction(V), ufl.TrialFunction(V)
        F = ufl.variable(ufl.Identity(len(u)) + ufl.grad(u))
        psi = self._psi(F, sub)
        if not isinstance(psi, ufl.core.expr.Expr) or psi.ufl_shape != ():
            shape = getattr(psi, "ufl_shape", None)
            raise InputError(f"Hyperelastic: energy(F) must return a scalar UFL expression of "
                             f"F, got {type(psi).__name__}"
                             f"{'' if shape is None else f' of shape {shape}'}")
        Pi = psi * sub.dx()
        W = self._external(V, sub, u)
        if W is not None:
            Pi = Pi - W
        R = ufl.derivative(Pi, u, v)
        J = ufl.derivative(R, u, du)
        made = (u, J, -R, Pi)
        self._cache[key] = made
        return made

    def __call__(self, V, sub):
        """The forms (K_t(u), −R(u)) on one run of subdomains at the current iterate."""
        u, J, mR, _ = self._forms_of(V, sub)
        values = None if self._state is None else self._state.values.get(sub.indices)
        if values is None:
            u.x.array[:] = 0.0
        else:
            u.x.array[sub.dof_permutation] = values
        return J, mR


def _lame(E: float, nu: float) -> tuple[float, float]:
    return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))


class _Isotropic(Hyperelastic):
    """An isotropic material of Young's modulus and Poisson's ratio (per body)."""

    _NAME = ""

    def __init__(self, E: Scalar, nu: Scalar, *, tractions=None, body_force=None,
                 degree: int | None = 1, load_factor: float = 1.0) -> None:
        args = check_arguments(self._NAME, {"E": ELASTICITY["E"], "nu": ELASTICITY["nu"]},
                               {"E": E, "nu": nu})
        self.E, self.nu = args["E"], args["nu"]
        self._mu = self._lmbda = None
        super().__init__(self._density, tractions=tractions, body_force=body_force,
                         degree=degree, load_factor=load_factor)

    def _material_key(self) -> tuple:
        frozen = [tuple(sorted(v.items())) if isinstance(v, Mapping) else v
                  for v in (self.E, self.nu)]
        return tuple(frozen)

    def stiffness_key(self) -> tuple:  # noqa: D102 — the energy is the class's own
        return type(self).__name__, self.degree, self._material_key()

    def check(self, mesh) -> None:
        """Validate E, ν (per body) and the loads against ``mesh``."""
        Es = per_body_values(self.E, mesh, "Young's modulus E")
        nus = per_body_values(self.nu, mesh, "Poisson's ratio nu")
        mu, lm = {}, {}
        for body in Es:
            E, nu = Es[body], nus[body]
            if not np.isfinite(E) or E <= 0:
                raise InputError(f"Young's modulus of body {body!r} must be positive and "
                                 f"finite, got E = {E}")
            if not np.isfinite(nu) or not -1.0 < nu < 0.5:
                raise InputError(f"Poisson's ratio of body {body!r} must lie in (-1, 0.5) "
                                 f"(compressible), got nu = {nu}")
            mu[body], lm[body] = _lame(E, nu)
            check_magnitude(f"the Lamé constants (mu, lambda) of body {body!r}",
                             [v for v in (mu[body], lm[body], E) if v != 0],
                             f"E = {E}, nu = {nu}")
        self._mu, self._lmbda = mu, lm
        super().check(mesh)

    def _density(self, F, sub):
        raise NotImplementedError


class NeoHookean(_Isotropic):
    """Compressible neo-Hookean: ψ = μ/2 (tr C − d) − μ ln J + λ/2 (ln J)².

    C = FᵀF, J = det F, d the dimension (plane strain in 2D), μ and λ the Lamé constants of
    ``E`` and ``nu`` (its linearization at F = I is :class:`~dolfinx_feti.Elasticity`).
    """

    _NAME = "NeoHookean"

    def _density(self, F, sub):
        mu, lmbda = sub.cellwise(self._mu), sub.cellwise(self._lmbda)
        d = F.ufl_shape[0]
        J = ufl.det(F)
        return mu / 2 * (ufl.tr(F.T * F) - d) - mu * ufl.ln(J) + lmbda / 2 * ufl.ln(J) ** 2


class SaintVenantKirchhoff(_Isotropic):
    """Saint Venant–Kirchhoff: ψ = λ/2 (tr E)² + μ tr(E²), E = (C − I)/2 (plane strain in 2D)."""

    _NAME = "SaintVenantKirchhoff"

    def _density(self, F, sub):
        mu, lmbda = sub.cellwise(self._mu), sub.cellwise(self._lmbda)
        Eg = (F.T * F - ufl.Identity(F.ufl_shape[0])) / 2
        return lmbda / 2 * ufl.tr(Eg) ** 2 + mu * ufl.tr(Eg * Eg)


__all__ = ["Hyperelastic", "NeoHookean", "NewtonState", "SaintVenantKirchhoff"]
