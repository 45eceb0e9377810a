"""The checks of the forms callback's (a, L): a Jacobian made by ``ufl.derivative`` passes and
gives the same solution as the bilinear form written out; the checks keep no mesh alive.

(The refusals by name are in tests/robustness/test_input_causes.py.) Serial and under
``mpirun -n 2``.
"""

from __future__ import annotations

import gc

import dolfinx
import numpy as np
import ufl
from hand_meshes import stacked
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti import compat
from dolfinx_feti.fem.form_checks import check_form_kinds

MU, LMBDA = 3.0, 5.0
LOAD = (0.1, -0.4)


def _strain_energy(w):
    eps = ufl.sym(ufl.grad(w))
    return MU * ufl.inner(eps, eps) + 0.5 * LMBDA * ufl.tr(eps) ** 2


def written_out(V, sub):
    """Linear elasticity as a bilinear form of (u, v) and a body force."""
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    eps = ufl.sym(ufl.grad(u))
    sigma = 2 * MU * eps + LMBDA * ufl.tr(eps) * ufl.Identity(2)
    return (ufl.inner(sigma, ufl.sym(ufl.grad(v))) * ufl.dx,
            ufl.inner(ufl.as_vector(LOAD), v) * ufl.dx)


def by_derivative(V, sub):
    """The same: the second derivative of the strain energy at w = 0 (as a hyperelastic
    model's Jacobian is made), the load the derivative of the load's potential."""
    w, u, v = compat.function(V, "w"), ufl.TrialFunction(V), ufl.TestFunction(V)
    energy = (_strain_energy(w) - ufl.inner(ufl.as_vector(LOAD), w)) * ufl.dx
    residual = ufl.derivative(energy, w, v)
    return ufl.derivative(residual, w, u), -ufl.replace(residual, {w: ufl.zero((2,))})


def _problem(forms) -> df.ContactProblem:
    return df.ContactProblem(stacked(), forms, value_size=2,
                             dirichlet=[df.Dirichlet("lower_bottom"), df.Dirichlet("upper_top",
                                                                                   (0.0, -0.05))],
                             contact=[df.Mortar("upper_bottom", "lower_top")])


def test_a_jacobian_by_derivative_is_accepted_and_equals_the_written_form():
    """Real forms: ``inner`` conjugates the test function, which ufl's arity check would take
    for a second argument in a derivative of a residual unless the conjugates are removed."""
    a = df.solve(_problem(written_out), rtol=1e-10)
    b = df.solve(_problem(by_derivative), rtol=1e-10)
    assert a.report.converged and b.report.converged
    ua, ub = a.nodal_values(), b.nodal_values()
    assert np.abs(ua).max() > 1e-3  # the load and the push move something
    assert np.abs(ua - ub).max() <= 1e-9 * np.abs(ua).max()


def _meshes_alive() -> int:
    gc.collect()
    return sum(isinstance(o, dolfinx.mesh.Mesh) for o in gc.get_objects())


def test_the_checks_keep_no_mesh_alive():
    """ufl's derivative rules on Python 3.13.0 outlive their call (a per-object method cache
    of ``singledispatchmethod``) and kept each checked form's mesh, and so its MPI
    communicators: after some hundred assemblies MPICH had none left (PETSc error 98)."""
    def check_once():
        msh = dolfinx.mesh.create_unit_square(MPI.COMM_SELF, 2, 2)
        V = compat.function_space(msh, 2)
        a, L = by_derivative(V, None)
        check_form_kinds(a, L, "test")

    check_once()
    before = _meshes_alive()
    for _ in range(3):
        check_once()
    assert _meshes_alive() == before
