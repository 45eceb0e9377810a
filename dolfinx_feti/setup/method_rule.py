"""The rule of ``method="auto"``, by measured time (docs/solvers.md, docs/benchmarks.md § 23).

CPU time of ``df.solve`` at rtol 1e-6 on the graded 2D Hertz H2, the rigid sphere S2 and a
user's graded DOLFINx box (30 k–130 k dofs, 1–51 subdomains; ``bench/auto_decomposition.py``):

- no gluing rows (every subdomain a whole body): FETI-1 (FETI-DP finds no corners there);
- up to :data:`MANY_PER_BODY` subdomains per body: FETI-1, the fastest on every case measured
  there (1.45–2.3× less time than TFETI; up to 1.9× less than FETI-DP, whose corner set-up
  outweighs its fewer F-multiplications: box, 13 subdomains, 15.5 s against 28.9 s);
- more: FETI-DP, held bodies or floating (2D Hertz cut in 51: 0.3× FETI-1's time, 0.7×
  TFETI's). TFETI was the slowest on every case and is not chosen.

Reads counts only, the same on every rank.
"""

from __future__ import annotations

#: More subdomains per body than this (on average) make FETI-DP the choice: between the 13 of
#: the box where FETI-1 was 1.9× faster and the 25.5 of 2D Hertz where FETI-DP was 3.3× faster
#: (the sphere S2 in 22: FETI-1 1.13× faster).
MANY_PER_BODY = 24


def method_by_time(glued: bool, num_subdomains: int, num_bodies: int) -> str:
    """``"feti1"`` or ``"fetidp"``: the method of least measured time (module docstring).

    Args:
        glued: Whether there are gluing rows (a body in several subdomains).
        num_subdomains: The subdomains of the whole problem.
        num_bodies: The bodies of the mesh.
    """
    if not glued or num_subdomains <= MANY_PER_BODY * max(num_bodies, 1):
        return "feti1"
    return "fetidp"


__all__ = ["MANY_PER_BODY", "method_by_time"]
