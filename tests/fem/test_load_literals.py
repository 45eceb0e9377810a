"""A load's float literals as runtime constants: the structure is the key, the numbers values."""

from __future__ import annotations

import dolfinx.mesh
import numpy as np
import pytest
import ufl
from mpi4py import MPI
from ufl.algorithms.analysis import extract_constants

from dolfinx_feti import compat
from dolfinx_feti.fem import load_literals as ll


@pytest.fixture(scope="module")
def mesh():
    return dolfinx.mesh.create_unit_square(MPI.COMM_SELF, 2, 2)


def traction(q, p, m):
    return lambda x: ufl.as_vector((q, -p + m * x[0] ** 2))


def test_same_structure_other_numbers(mesh):
    key = ll.load_key(traction(1.0, 2.0, 3.0), mesh)
    assert ll.load_key(traction(1.5, -2.0, 0.25), mesh) == key
    assert sorted(ll.load_values(traction(1.5, -2.0, 0.25), mesh)) == [0.25, 1.5, 2.0]


def test_other_structure_other_key(mesh):
    key = ll.load_key(traction(1.0, 2.0, 3.0), mesh)
    assert ll.load_key(lambda x: ufl.as_vector((1.0, -2.0 + 3.0 * x[1] ** 2)), mesh) != key
    assert ll.load_key(lambda x: ufl.as_vector((1.0, -2.0 + 3.0 * x[0] ** 3)), mesh) != key
    # equal numbers are one literal: another structure than three distinct ones
    assert ll.load_key(traction(-2.0, 2.0, 3.0), mesh) != key


def test_constants_take_the_literals_places(mesh):
    x = ufl.SpatialCoordinate(mesh)
    expr = traction(1.5, 2.0, 0.25)(x)
    lits = ll.literals(expr)
    replaced = ll.with_constants(expr, lits, mesh)
    assert not ll.literals(replaced)  # every float literal became a constant
    consts = sorted(extract_constants(replaced), key=lambda c: c.count())
    assert [float(np.asarray(c.value)) for c in consts] == [float(v) for v in lits]
    # the same values as the literal expression at a point: both integrated over the mesh
    one = compat.assemble_scalar(expr[1] * ufl.dx(domain=mesh), MPI.COMM_SELF)
    two = compat.assemble_scalar(replaced[1] * ufl.dx(domain=mesh), MPI.COMM_SELF)
    assert two == pytest.approx(one, rel=1e-14)
