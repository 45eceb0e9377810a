"""The condition classes, one module each, and what the problem asks of them.

Each class is where ``dolfinx_feti.problem`` and ``dolfinx_feti`` say it is; a condition's
place in the problem is its ``role`` (no type test); a pair of surfaces shares ``group``,
``groups`` and ``structure_key`` (``SurfacePair``); a friction law is checked by the friction
field's own check.
"""

from __future__ import annotations

from pathlib import Path

import pytest

import dolfinx_feti as df
from dolfinx_feti import problem
from dolfinx_feti.problem.conditions.base import SurfacePair

MESHES = Path(__file__).resolve().parents[2] / "meshes"
MODULES = {"Dirichlet": "dirichlet", "Tresca": "friction", "Coulomb": "friction",
           "NodeToNode": "node_to_node", "Mortar": "mortar", "Tie": "tie",
           "RigidObstacle": "rigid_obstacle", "Plane": "obstacles", "Sphere": "obstacles",
           "Cylinder": "obstacles", "SignedDistance": "obstacles"}


@pytest.fixture(scope="module")
def membranes() -> df.MeshData:
    return df.read_gmsh(MESHES / "membranes_8.msh")


def b1(mesh, **kwargs) -> df.ContactProblem:
    return df.ContactProblem(mesh, df.Poisson(source=-1.0), dirichlet=[df.Dirichlet("dirichlet")],
                             **kwargs)


def test_one_module_per_condition_and_the_same_public_names():
    for name, module in MODULES.items():
        cls = getattr(problem, name)
        assert cls.__module__ == f"dolfinx_feti.problem.conditions.{module}", name
        assert getattr(df, name) is cls, name
    assert set(problem.__all__) <= set(df.__all__)


def test_a_condition_takes_its_place_by_its_role(membranes):
    assert b1(membranes, contact=[df.NodeToNode("contact_left", "contact_right")]).contact
    with pytest.raises(df.InputError, match="unknown contact condition.*Tie"):
        b1(membranes, contact=[df.Tie("contact_left", "contact_right")])
    with pytest.raises(df.InputError, match="unknown contact condition.*Dirichlet"):
        b1(membranes, contact=[df.Dirichlet("contact_left")])
    ok = b1(membranes, ties=[df.Tie("contact_left", "contact_right")])
    ok.ties.append(df.NodeToNode("contact_left", "contact_right"))  # past the field's check
    with pytest.raises(df.InputError, match="ties must be"):
        ok.__post_init__()


def test_a_friction_law_is_checked_by_the_friction_field(membranes):
    pair = df.NodeToNode("contact_left", "contact_right")
    object.__setattr__(pair, "friction", "coulomb")  # a frozen dataclass altered after its checks
    with pytest.raises(df.InputError, match="friction must be None, df.Tresca or df.Coulomb"):
        b1(membranes, contact=[pair])
    with pytest.raises(df.InputError, match="friction needs a vector"):
        b1(membranes, contact=[df.NodeToNode("contact_left", "contact_right",
                                             friction=df.Coulomb(0.3))])


@pytest.mark.parametrize("cls", [df.NodeToNode, df.Mortar, df.Tie])
def test_surface_pairs_share_their_behaviour(cls):
    c = cls("s", "m")
    assert isinstance(c, SurfacePair)
    assert (c.group, c.groups) == ("s", ("s", "m"))
    assert c.structure_key() == (cls.__name__, c, False)
    assert c.role == ("tie" if cls is df.Tie else "contact")
    if cls is not df.Tie:  # the friction values do not change the structure, friction does
        a, b = cls("s", "m", friction=df.Coulomb(0.3)), cls("s", "m", friction=df.Coulomb(0.5))
        assert a.structure_key() == b.structure_key() != c.structure_key()
