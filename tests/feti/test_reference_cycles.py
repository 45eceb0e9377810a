"""No PETSc object of a solve sits in a Python reference cycle.

petsc4py (3.18 on) destroys a parallel object whose wrapper was collected only at a collective
clean-up, and only when every rank has queued it. An object inside a reference cycle is freed
by each rank's cyclic garbage collector at its own moment, so it lingers; one reached by
reference counting alone goes on every rank as soon as its last owner is dropped. Checked with
the collector off during the solves and every unreachable object kept (``gc.DEBUG_SAVEALL``):
the solves' unreachable PETSc objects are those of cycles. Each rank checks its own (run
serially and under mpirun).
"""

from __future__ import annotations

import gc

import pytest
from petsc4py import PETSc
from test_obstacle_motion import spun

import dolfinx_feti as df
from dolfinx_feti.io.meshes_rubber import ironing_block


@pytest.fixture(scope="module")
def block():
    return df.build_mesh(ironing_block, lx=6.0, ly=2.0, h_top=0.25, h_far=0.5)


def petsc_objects_in_cycles(run) -> list[str]:
    """The types of the PETSc objects that ``run()`` left unreachable but not freed."""
    gc.collect()  # the garbage of earlier tests, not ours
    enabled = gc.isenabled()
    gc.disable()
    gc.set_debug(gc.DEBUG_SAVEALL)
    try:
        run()
        gc.collect()
        return sorted(type(o).__name__ for o in gc.garbage if isinstance(o, PETSc.Object))
    finally:
        gc.set_debug(0)
        gc.garbage.clear()
        if enabled:
            gc.enable()


@pytest.mark.parametrize("material", [df.Elasticity(1.0, 0.3), df.NeoHookean(1.0, 0.3)],
                         ids=["small-deformation", "newton"])
def test_a_finished_load_path_frees_its_petsc_objects(block, material):
    """A FETI-DP load path with friction (the QP of each step made by ``for_load`` from the
    first one's, the corner factors shared) and the same path under Newton."""
    def run():
        sols = df.solve_path(lambda s: spun(block, s, material), [0.5, 1.0, 1.2], rtol=1e-11,
                             method="fetidp", progress=False)
        assert all(s.report.converged for s in sols)

    assert petsc_objects_in_cycles(run) == []


def test_a_dropped_solver_frees_its_petsc_objects(block):
    """A FetiSolver (FETI-DP) that solved two load cases, then dropped."""
    material = df.Elasticity(1.0, 0.3)

    def run():
        solver = df.FetiSolver(spun(block, 0.5, material), rtol=1e-11, method="fetidp")
        assert solver.solve().report.converged
        solver.update(spun(block, 1.0, material))
        assert solver.solve().report.converged

    assert petsc_objects_in_cycles(run) == []
