"""The patch tests of tests/fem/test_elements.py as a table: errors per element type and degree.

A uniaxial stress state (pressure p on the top, rollers or contact with a rigid plane at the
bottom, symmetry planes) has an exact linear displacement. For each cell type and degree this
prints the relative max-norm error of the nodal solution, the contact pressure error (rigid
plane), the number of dofs and of subdomains.

Run from the repository root (the meshes and cases come from ``tests/``):
``python bench/element_patch.py``, or under ``mpirun -n 2``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from mpi4py import MPI

_TESTS = Path(__file__).resolve().parents[1] / "tests"
sys.path[:0] = [str(_TESTS / "support"), str(_TESTS / "fem")]
import test_elements as te  # noqa: E402

import dolfinx_feti as df  # noqa: E402


def main() -> None:
    comm = MPI.COMM_WORLD
    built = {}
    meshes = {"triangle": lambda: df.build_mesh(te.em.rectangle, quads=False),
              "quadrilateral": lambda: df.build_mesh(te.em.rectangle, quads=True),
              "tetrahedron": lambda: df.build_mesh(te.em.box, hexes=False),
              "hexahedron": lambda: df.build_mesh(te.em.box, hexes=True),
              "distorted-hexahedron": te.em.distorted_hexahedra}
    if comm.rank == 0:
        print(f"{'cell':22} deg  dofs   error (rollers)  error (rigid plane)  pressure error")
    for cell, make in meshes.items():
        built[cell] = make()
        for degree in (1, 2):
            p = te.uniaxial(built[cell], degree)
            s = df.solve(p, rtol=te.RTOL)
            family = "P" if cell in ("triangle", "tetrahedron") else "Q"
            dofs = s.report.sizes["primal"]
            row = f"{cell:22} {family}{degree}  {dofs:>5}  {te.rel_error(p, s):14.1e}"
            pc = te.uniaxial(built[cell], degree, contact=True)
            sc = df.solve(pc, rtol=te.RTOL)
            perr = np.abs(sc.contact.pressure - te.PRESSURE).max() / te.PRESSURE
            row += f"  {te.rel_error(pc, sc):19.1e}  {perr:14.1e}"
            if comm.rank == 0:
                print(row, flush=True)


if __name__ == "__main__":
    main()
