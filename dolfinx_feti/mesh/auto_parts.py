"""``Auto()``: the decomposition chosen from the mesh and the ranks (the default).

A user who gives no decomposition gets :class:`~.decompose.Parts` of equal volume with a
number of parts per body from the body's size and the number of ranks:

- every body in parts of about ``cells`` cells (:data:`TARGET_CELLS` by cell type), cut to
  equal volumes (:data:`BALANCE`) and merged into connected subdomains
  (:mod:`.connected_parts`). The targets are where the CPU time of a solve was least on one
  rank (``bench/auto_decomposition.py``, docs/benchmarks.md § 23): on the graded 2D Hertz
  mesh H2, the graded 3D rigid sphere S2 and a user's graded DOLFINx box of 30 k and 110 k
  dofs, fewer subdomains took less time down to one per body (box, 197 k tetrahedra: 11.0 s
  whole, 15.4 s in 5 parts, 15.5 s in 13, FETI-1): a factorization of up to 110 k dofs
  costs less than the iterations more subdomains add. The targets are the largest parts
  measured (triangles 40 k, tetrahedra 200 k cells); quadrilaterals and hexahedra take about
  the same dofs per subdomain (half and a fifth of the cells), not measured;
- on several ranks, at least one subdomain per rank when the mesh has at least
  :data:`MIN_CELLS` cells per rank (a rank without a subdomain would idle), the extra parts
  given to the bodies by their size; a smaller mesh keeps the parts of one rank (measured
  on 2 ranks at two sizes only);
- a body smaller than half a part stays whole (on a small mesh ``Auto()`` is ``ByTags()``).

The counts depend on the mesh's cells, not on its numbering: the same on every rank, and for
a distributed mesh (the cell counts summed over the ranks) the serial result.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..validation import Integer, Maybe, checked

#: Cells per subdomain with the least time, by cell type (bench/auto_decomposition.py).
TARGET_CELLS = {"triangle": 40000, "quadrilateral": 20000, "tetrahedron": 200000,
                "hexahedron": 40000}
#: The fewest cells per rank for which every rank gets a subdomain (2 ranks: the sphere S2,
#: 32 801 cells, took 1.2–1.4× longer in 2 subdomains than whole; the box of 48 000 cells 0.88×
#: in 3; bench/auto_decomposition.py under mpirun).
MIN_CELLS = 20000
#: What the parts make equal: their volumes (on meshes graded toward a contact 1.3–5× less
#: time than equal cell counts, bench/auto_decomposition.py --balance cells).
BALANCE = "volume"


@dataclass(frozen=True)
@checked(cells=Maybe(Integer(ge=1)))
class Auto:
    """The decomposition chosen from the mesh and the ranks (the default of a problem).

    ``Parts(n, balance="volume")`` with n per body the body's cells over ``cells`` (at least
    1), raised on several ranks to one subdomain per rank or more (module
    :mod:`.auto_parts`).

    Args:
        cells: The cells per subdomain to aim at; None: the measured default of the cell
            type (:data:`TARGET_CELLS`).
    """

    cells: int | None = None


def auto_parts(how: Auto, body_cells: Sequence[int], body_names: Sequence[str],
               cell_type: str | None, comm_size: int) -> dict[str, int]:
    """The parts per body that ``how`` stands for: ``Parts(auto_parts(...), balance=BALANCE)``.

    Args:
        how: The Auto decomposition.
        body_cells: The cells of each body (whole mesh).
        body_names: The bodies' names.
        cell_type: The cells' type (None: simplices of the mesh's dimension, as triangles).
        comm_size: The number of ranks that will solve.
    """
    count = np.asarray(body_cells, dtype=np.int64)
    target = how.cells or TARGET_CELLS.get(cell_type or "triangle", TARGET_CELLS["triangle"])
    n = np.maximum(1, np.rint(count / target)).astype(np.int64)
    total = int(count.sum())
    if comm_size > 1 and n.sum() < comm_size and total >= comm_size * MIN_CELLS:
        # the missing parts to the bodies by their size (largest remainder, first body first)
        want = count * comm_size / max(total, 1)
        n = np.maximum(n, np.floor(want).astype(np.int64))
        rest = comm_size - int(n.sum())
        if rest > 0:
            order = np.lexsort((np.arange(n.size), -(want - np.floor(want))))
            n[order[:rest]] += 1
        n = np.minimum(n, np.maximum(count, 1))
    return {name: int(k) for name, k in zip(body_names, n, strict=True)}


__all__ = ["BALANCE", "MIN_CELLS", "TARGET_CELLS", "Auto", "auto_parts"]
