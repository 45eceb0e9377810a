"""A mesh held whole goes through the one set-up pipeline: the shares are the replicated ones.

Before issue 21 a mesh every rank holds (or rank 0 alone holds) was decomposed, given its rows
and split into shares on rank 0; now it is cut into blocks (``setup/whole_mesh.py``) and set
up as a distributed mesh is. The replicated set-up lives on as the oracle
(``tests/support/serial_setup.py``): every case here must give each rank the same share, bit
for bit, as the oracle, for the cases the distributed input could not take before (a curved
mesh, PT-Scotch, a labeller of all midpoints at once), and for contact, friction, ties and
FETI-DP.
"""

from __future__ import annotations

import importlib

import element_models as em
import numpy as np
import pytest
import reference as ref
from mpi4py import MPI
from serial_setup import assert_same_shares, serial_dual_qp
from test_distributed_input import CASES as INPUT_CASES
from test_mortar_p2 import curved_disk_on_block

import dolfinx_feti as df

COMM = MPI.COMM_WORLD


def membranes(root, replicate=True, **parts):
    mesh = df.read_gmsh(root / "meshes/membranes_8.msh", replicate=replicate)
    return df.ContactProblem(
        mesh, df.Poisson(source=ref.membrane_source, degree=2),
        dirichlet=[df.Dirichlet("dirichlet")],
        contact=[df.NodeToNode("contact_left", "contact_right")],
        decomposition=df.Parts(8, **parts))


def curved_plate(root):
    """A plate with a hole meshed by curved triangles: its edge points on the circle."""
    mesh = df.build_mesh(em.plate_with_hole, False, 0.3)
    return df.ContactProblem(mesh, df.Elasticity(1.0, 0.3, tractions={"hole": (0.0, 0.1)}),
                             dirichlet=[df.Dirichlet("outer")], decomposition=df.Parts(3))


def curved_mortar(root, replicate=True):
    """2D Hertz on curved (second-order) cells, mortar contact on the curved arc."""
    mesh = df.build_mesh(curved_disk_on_block, 0.5, 0.85, h_far=2.0, refine=2.0,
                         replicate=replicate)
    return df.ContactProblem(
        mesh, df.Elasticity(1.0, 0.3, tractions={"load": (0.0, -0.01)}),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("symmetry", components=[0])],
        contact=[df.Mortar("disk_contact", "block_contact")], decomposition=df.Parts(3))


def all_midpoints(root):
    """A labeller that needs all midpoints at once (the median of x): rank 0 runs it."""
    mesh = df.build_mesh(em.rectangle, True, 0.2)
    return df.ContactProblem(
        mesh, df.Poisson(source=1.0), dirichlet=[df.Dirichlet("left")],
        decomposition=df.ByFunction(lambda m: (m[:, 0] > np.median(m[:, 0])).astype(int)))


CASES = {"membranes_P2": lambda root: membranes(root),
         "membranes_root_only": lambda root: membranes(root, replicate=False),
         "ptscotch": lambda root: membranes(root, method="ptscotch"),
         "curved_plate": curved_plate, "curved_mortar": curved_mortar,
         "curved_mortar_root_only": lambda root: curved_mortar(root, replicate=False),
         "all_midpoints": all_midpoints,
         **{name: (lambda make: lambda root: make(root, False))(INPUT_CASES[name])
            for name in ("hertz_mortar", "tied_blocks_3d", "hertz_tresca",
                         "quads_by_function")}}


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_shares_are_the_replicated_ones(root, name, monkeypatch):
    if name == "ptscotch":  # PT-Scotch's parts differ from call to call: one call for both
        decompose = importlib.import_module("dolfinx_feti.mesh.decompose")
        made, partition = {}, decompose.graph_partition

        def once(cells, n, cell_type=None):
            key = (cells.tobytes(), n)
            if key not in made:
                made[key] = partition(cells, n, cell_type)
            return made[key]

        monkeypatch.setattr(decompose, "graph_partition", once)
    problem = CASES[name](root)
    assert_same_shares(serial_dual_qp(problem), df.dual_qp(problem))


@pytest.mark.parametrize("name, method", [("membranes_P2", "fetidp"),
                                          ("hertz_mortar", "auto"),
                                          ("tied_blocks_3d", "fetidp")])
def test_fetidp_and_auto_as_replicated(root, name, method):
    problem = CASES[name](root)
    assert_same_shares(serial_dual_qp(problem, method=method),
                       df.dual_qp(problem, method=method))


def test_a_curved_mesh_keeps_its_geometry_nodes(root):
    """The points of the hole's edges lie on its circle in every rank's share."""
    share = df.dual_qp(curved_plate(root)).share
    assert share.mesh.geometry_degree == 2
    facets = [f["hole"] for f in share.facets.values() if "hole" in f]
    on = np.unique(share.points.facet_points(share.mesh, np.concatenate(facets))) if facets \
        else np.zeros(0, dtype=np.int64)
    x = share.points.x[on]
    r = np.hypot(x[:, 0] - 1.0, x[:, 1] - 0.5)
    assert np.abs(r - 0.25).max(initial=0.0) < 1e-12
    assert COMM.allreduce(on.size) > 0
