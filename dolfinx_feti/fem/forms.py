"""Ready-made forms: linear elasticity (plane strain or 3D) and the scalar Poisson problem.

Each helper is a callable ``forms(V, sub) -> (a, L)`` as :class:`~dolfinx_feti.ContactProblem`
expects, with ``value_size`` and a ``check(mesh)`` that validates its data against the mesh.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import ufl

from .. import compat
from ..errors import InputError
from ..validation import (
    SAFE_MAGNITUDE,
    Either,
    Function,
    Integer,
    MappingOf,
    Maybe,
    Real,
    Text,
    Vector,
    check_arguments,
    per_body,
)
from . import load_literals

#: What the helpers accept, checked when they are made (ranges per body in ``check(mesh)``).
_NUMBER = per_body(Real(finite=False))
_VECTOR = Either(Vector(), Function(), what="a sequence of numbers (one per coordinate) or a "
                 "function of the UFL spatial coordinate x")
_SCALAR = Either(Real(finite=False), Function(), what="a number or a function of the UFL "
                 "spatial coordinate x")
_DEGREE = Maybe(Integer(ge=1, le=2))
_FACTOR = Real()
ELASTICITY = {"E": _NUMBER, "nu": _NUMBER, "tractions": MappingOf(Text(), _VECTOR),
              "body_force": Maybe(_VECTOR), "degree": _DEGREE, "load_factor": _FACTOR}
POISSON = {"source": _SCALAR, "flux": MappingOf(Text(), _SCALAR), "k": _NUMBER,
           "degree": _DEGREE, "load_factor": _FACTOR}

Scalar = float | Mapping[str, float]


def per_body_values(value, mesh, what: str) -> dict[str, float]:
    """One number per body of ``mesh`` from a number or a body name → number mapping."""
    if isinstance(value, Mapping):
        unknown = set(value) - set(mesh.body_names)
        if unknown:
            raise InputError(f"{what}: unknown bodies {sorted(unknown)}; the bodies are "
                             f"{list(mesh.body_names)}")
        missing = set(mesh.body_names) - set(value)
        if missing:
            raise InputError(f"{what}: no value for bodies {sorted(missing)}")
        return {k: float(v) for k, v in value.items()}
    return dict.fromkeys(mesh.body_names, float(value))


def scaled_value(v, s: float):
    """A traction, body force or Dirichlet value times ``s`` (None stays None).

    A value that knows how to scale itself (``v.scaled(s)``, e.g. a problem file's affine
    traction) does; a function of x is wrapped; numbers are multiplied.
    """
    if v is None:
        return None
    scale = getattr(v, "scaled", None)
    if callable(scale):
        return scale(s)
    if callable(v):
        def times(x, _v=v):
            return s * _v(x)
        return times
    a = np.asarray(v, dtype=float) * s
    return float(a) if a.ndim == 0 else tuple(float(c) for c in a)


def scaled_form(L, factor: float, V):
    """``factor · L`` with the factor a runtime constant (None for no linear form)."""
    if not isinstance(L, ufl.Form):
        return None if L is None or L == 0 else L
    return L if L.empty() else compat.constant(compat.space_mesh(V), factor) * L


def _load_key(kind: str, terms: list, sub) -> tuple:
    """The shape of a subdomain's loads: where each acts; a function of x by its structure.

    A function of x is called on the subdomain's coordinate: its float literals become runtime
    constants (:mod:`~dolfinx_feti.fem.load_literals`), so a new case whose function differs
    in numbers only compiles nothing; one that reads other objects (a new Function) is
    another structure and is compiled again.
    """
    return kind, tuple((where, load_literals.load_key(v, sub.mesh) if callable(v) else None)
                       for where, v in terms)


def _load_values(terms: list, load_factor: float, sub) -> list:
    """The runtime constants' values in the order the forms make them, the load factor last."""
    values: list = []
    for _, v in terms:
        if callable(v):
            values.extend(load_literals.load_values(v, sub.mesh))
        else:
            values.append(np.asarray(v, dtype=float))
    return values + [load_factor]


def _of_x(load: Callable, x, mesh):
    """``load(x)`` with its float literals as runtime constants (:func:`_load_key`)."""
    expr = load(x)
    expr = ufl.as_vector(expr) if isinstance(expr, list | tuple) else ufl.as_ufl(expr)
    return load_literals.with_constants(expr, load_literals.literals(expr), mesh)


def _frozen(value):
    """A per-body mapping as a sorted tuple (comparable), a number as itself."""
    return tuple(sorted(value.items())) if isinstance(value, Mapping) else value


def check_groups(groups: Mapping, mesh, what: str) -> None:
    """Refuse unknown boundary groups and non-finite constant values on them."""
    for name, v in groups.items():
        mesh.facets(name)
        if not callable(v) and not np.all(np.isfinite(np.asarray(v, dtype=float))):
            raise InputError(f"{what} on {name!r} is not finite: {v}")


def check_magnitude(what: str, values, given: str) -> None:
    """Refuse material constants whose products in the solver overflow or underflow."""
    if any(not 1.0 / SAFE_MAGNITUDE <= abs(v) <= SAFE_MAGNITUDE for v in values):
        raise InputError(f"{what} lie outside [{1 / SAFE_MAGNITUDE:.0e}, {SAFE_MAGNITUDE:.0e}] "
                         f"({given}): the solver's products (K K⁺ K, norms) would overflow or "
                         "underflow in double precision; choose other units")


@dataclass(frozen=True)
class BoundaryModel:
    """What boundary elements (Total BETI) need of a PDE: its fundamental solution and loads.

    Boundary elements replace a subdomain's stiffness by its Steklov–Poincaré operator, which
    needs the PDE's fundamental solution and has no volume terms; a forms class that can be
    solved so says how (see :meth:`Elasticity.boundary_model`).

    Attributes:
        kernel: The fundamental solution: ``"laplace"``, or ``"lame"`` (plane strain).
        constants: Constant name → body name → value (``"k"``; or ``"mu"`` and ``"nu"``).
        loads: Boundary group → load (a number, a vector or a function of x).
        load_name: What the loads are called ("tractions", "fluxes"), for messages.
        volume_load: The volume load the forms carry (which boundary elements cannot take),
            or None.
    """

    kernel: str
    constants: Mapping[str, Mapping[str, float]]
    loads: Mapping
    load_name: str
    volume_load: str | None


class Elasticity:
    """Small-strain isotropic linear elasticity, plane strain in 2D.

    Args:
        E: Young's modulus: one number or body name → number.
        nu: Poisson's ratio, in (−1, 0.5): one number or body name → number.
        tractions: Boundary group → traction vector (force per area) applied there.
        body_force: A constant vector, or ``body_force(x)`` of the UFL spatial coordinate.
        degree: Degree of the Lagrange space of the displacement (1 or 2); by default the
            degree of the mesh's geometry (2 on a curved second-order mesh, else 1).
        load_factor: Multiplies every load (tractions and body force). A runtime constant of
            the compiled form, as the numbers given for the loads are: load steps and load
            cases of one shape (``FetiSolver.update``) compile nothing, also when the loads
            are functions of x.
    """

    value_size = "vector"

    def __init__(self, E: Scalar, nu: Scalar, *,
                 tractions: Mapping[str, Sequence[float]] | None = None,
                 body_force: Sequence[float] | Callable | None = None,
                 degree: int | None = None, load_factor: float = 1.0) -> None:
        args = check_arguments("Elasticity", ELASTICITY, {
            "E": E, "nu": nu, "tractions": tractions or {}, "body_force": body_force,
            "degree": degree, "load_factor": load_factor})
        self.load_factor = args["load_factor"]
        self.E, self.nu = args["E"], args["nu"]
        self.tractions = args["tractions"]
        self.body_force = args["body_force"]
        self.degree = args["degree"]
        self._E = self._nu = None

    def stiffness_key(self) -> tuple:
        """What the bilinear form depends on (a new load case keeps it; see FetiSolver)."""
        return "Elasticity", _frozen(self.E), _frozen(self.nu), self.degree

    def loads_scaled(self, s: float) -> Elasticity:
        """The same material with its tractions and body force times ``s`` (a load step).

        Constant loads stay runtime constants (no compilation per factor); an affine traction
        of a problem file is scaled in its coefficients.
        """
        return Elasticity(self.E, self.nu,
                          tractions={g: scaled_value(t, s) for g, t in self.tractions.items()},
                          body_force=scaled_value(self.body_force, s), degree=self.degree,
                          load_factor=self.load_factor)

    def _loads(self, sub) -> list:
        """The loads on ``sub`` in the order :meth:`__call__` makes them: (where, value)."""
        terms = [] if self.body_force is None else [("dx", self.body_force)]
        return terms + [(name, t) for name, t in self.tractions.items() if sub.has_facets(name)]

    def load_key(self, sub) -> tuple | None:
        """The shape of the loads on ``sub`` (see :mod:`~dolfinx_feti.fem.load_form`)."""
        return _load_key("Elasticity", self._loads(sub), sub)

    def load_values(self, sub) -> list:
        """The values of the loads' runtime constants on ``sub``, in the order they are made."""
        return _load_values(self._loads(sub), self.load_factor, sub)

    def check(self, mesh) -> None:
        """Validate the material data and the named groups against ``mesh``."""
        self._E = per_body_values(self.E, mesh, "Young's modulus E")
        self._nu = per_body_values(self.nu, mesh, "Poisson's ratio nu")
        for body, E in self._E.items():
            if not np.isfinite(E) or E <= 0:
                raise InputError(f"Young's modulus of body {body!r} must be positive and "
                                 f"finite, got E = {E}")
        for body, nu in self._nu.items():
            if not np.isfinite(nu) or not -1.0 < nu < 0.5:
                raise InputError(f"Poisson's ratio of body {body!r} must lie in (-1, 0.5), got "
                                 f"nu = {nu}" + (" (incompressible)" if nu == 0.5 else ""))
            E = self._E[body]
            lame = (E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu)))
            check_magnitude(f"the Lamé constants (mu, lambda) of body {body!r}",
                             [v for v in (*lame, E) if v != 0], f"E = {E}, nu = {nu}")
        check_groups(self.tractions, mesh, "traction")
        for name, t in self.tractions.items():
            if not callable(t) and np.asarray(t, dtype=float).size != mesh.gdim:
                raise InputError(f"traction on {name!r} has {np.asarray(t).size} components; "
                                 f"the mesh is {mesh.gdim}D")
        if self.body_force is not None and not callable(self.body_force):
            b = np.asarray(self.body_force, dtype=float)
            if not np.all(np.isfinite(b)):
                raise InputError(f"body force is not finite: {self.body_force}")
            if b.size != mesh.gdim:
                raise InputError(f"body force has {b.size} components; the mesh is "
                                 f"{mesh.gdim}D")

    def boundary_model(self) -> BoundaryModel:
        """Lamé's fundamental solution, μ and ν per body, the tractions (after :meth:`check`)."""
        mu = {b: E / (2 * (1 + self._nu[b])) for b, E in self._E.items()}
        return BoundaryModel("lame", {"mu": mu, "nu": dict(self._nu)}, self.tractions,
                             "tractions", None if self.body_force is None else "body force")

    def output_fields(self, u, cellwise: Callable) -> dict:
        """Cell fields for the output: the von Mises stress of ``u`` as a UFL expression.

        Args:
            u: The displacement Function.
            cellwise: Body name → value mapping (or one number) → a DG0 Function on ``u``'s
                mesh.
        """
        return {"von_mises": _von_mises(u, cellwise(self.E), cellwise(self.nu))}

    def __call__(self, V, sub):
        """The forms on one subdomain."""
        u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
        E = sub.cellwise(self._E)
        nu = sub.cellwise(self._nu)
        mu = E / (2 * (1 + nu))
        lmbda = E * nu / ((1 + nu) * (1 - 2 * nu))  # plane strain in 2D

        def eps(w):
            return ufl.sym(ufl.grad(w))

        def sigma(w):
            return 2 * mu * eps(w) + lmbda * ufl.tr(eps(w)) * ufl.Identity(len(w))

        a = ufl.inner(sigma(u), eps(v)) * sub.dx()
        L = 0
        x = ufl.SpatialCoordinate(V.mesh)
        for where, t in self._loads(sub):
            msh = compat.space_mesh(V)
            tv = _of_x(t, x, msh) if callable(t) else compat.constant(msh, [float(c) for c in t])
            L += ufl.inner(tv, v) * (sub.dx() if where == "dx" else sub.ds(where))
        return a, scaled_form(L, self.load_factor, V)


class Poisson:
    """The scalar problem −div(k ∇u) = f with fluxes k ∂u/∂n = g on boundary groups.

    Args:
        source: f: a number, or ``source(x)`` of the UFL spatial coordinate.
        flux: Boundary group → g (a number or a function of x).
        k: Conductivity: a number or body name → number (positive).
        degree: Degree of the Lagrange space (1 or 2); by default that of the mesh's geometry.
        load_factor: Multiplies the source and the fluxes, as a runtime constant (see
            :class:`Elasticity`).
    """

    value_size = 1

    def __init__(self, source: float | Callable = 0.0, *, flux: Mapping | None = None,
                 k: Scalar = 1.0, degree: int | None = None, load_factor: float = 1.0) -> None:
        args = check_arguments("Poisson", POISSON, {"source": source, "flux": flux or {}, "k": k,
                                                  "degree": degree,
                                                  "load_factor": load_factor})
        self.load_factor = args["load_factor"]
        self.source, self.flux, self.k = args["source"], args["flux"], args["k"]
        self.degree = args["degree"]
        self._k = None

    def stiffness_key(self) -> tuple:
        """What the bilinear form depends on (a new load case keeps it; see FetiSolver)."""
        return "Poisson", _frozen(self.k), self.degree

    def _loads(self, sub) -> list:
        """The loads on ``sub`` in the order :meth:`__call__` makes them: (where, value)."""
        terms = [] if self.source == 0 and not callable(self.source) else [("dx", self.source)]
        return terms + [(name, g) for name, g in self.flux.items() if sub.has_facets(name)]

    def load_key(self, sub) -> tuple | None:
        """The shape of the loads on ``sub`` (see :mod:`~dolfinx_feti.fem.load_form`)."""
        return _load_key("Poisson", self._loads(sub), sub)

    def load_values(self, sub) -> list:
        """The values of the loads' runtime constants on ``sub``, in the order they are made."""
        return _load_values(self._loads(sub), self.load_factor, sub)

    def check(self, mesh) -> None:
        """Validate the data and the named groups against ``mesh``."""
        self._k = per_body_values(self.k, mesh, "conductivity k")
        for body, k in self._k.items():
            if not np.isfinite(k) or k <= 0:
                raise InputError(f"conductivity of body {body!r} must be positive, got {k}")
            check_magnitude(f"the conductivity of body {body!r}", [k], f"k = {k}")
        check_groups(self.flux, mesh, "flux")
        if not callable(self.source) and not np.isfinite(self.source):
            raise InputError(f"source is not finite: {self.source}")

    def boundary_model(self) -> BoundaryModel:
        """Laplace's fundamental solution, k per body, the fluxes (after :meth:`check`)."""
        source = "source term" if callable(self.source) or self.source != 0 else None
        return BoundaryModel("laplace", {"k": dict(self._k)}, self.flux, "fluxes", source)

    def output_fields(self, u, cellwise: Callable) -> dict:
        """No cell fields besides the solution (see :meth:`Elasticity.output_fields`)."""
        return {}

    def __call__(self, V, sub):
        """The forms on one subdomain."""
        u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
        x = ufl.SpatialCoordinate(V.mesh)
        a = sub.cellwise(self._k) * ufl.inner(ufl.grad(u), ufl.grad(v)) * sub.dx()
        msh = compat.space_mesh(V)
        f = _of_x(self.source, x, msh) if callable(self.source) else \
            compat.constant(msh, self.source) if self.source != 0 else 0.0
        L = f * v * sub.dx()
        for name, g in self.flux.items():
            if sub.has_facets(name):
                L += (_of_x(g, x, msh) if callable(g) else compat.constant(msh, g)) * v * \
                    sub.ds(name)
        return a, scaled_form(L, self.load_factor, V)


def _von_mises(u, E, nu):
    """The von Mises stress of a displacement as a UFL expression (plane strain in 2D)."""
    d = len(u)
    mu = E / (2 * (1 + nu))
    lmbda = E * nu / ((1 + nu) * (1 - 2 * nu))
    eps = ufl.sym(ufl.grad(u))
    sigma = 2 * mu * eps + lmbda * ufl.tr(eps) * ufl.Identity(d)
    if d == 3:
        s = ufl.dev(sigma)
        return ufl.sqrt(1.5 * ufl.inner(s, s))
    szz = lmbda * ufl.tr(eps)
    mean = (ufl.tr(sigma) + szz) / 3
    s = sigma - mean * ufl.Identity(d)
    return ufl.sqrt(1.5 * (ufl.inner(s, s) + (szz - mean) ** 2))
