"""The rule of ``method="auto"``, the default method, by measured time (docs/benchmarks.md § 23).

CPU time of ``df.solve`` at rtol 1e-6 on the graded 2D Hertz H2, the rigid sphere S2 and a
user's graded DOLFINx box (30 k–130 k dofs, 1–77 subdomains; ``bench/auto_decomposition.py``):

- no gluing rows (every subdomain a whole body): FETI-1 (FETI-DP finds no corners there);
- up to :data:`MANY_PER_BODY` subdomains per body (16 in 2D, 4 in 3D): FETI-1, the fastest
  on most cases measured there (1.45–2.3× less time than TFETI; in 2D up to 1.15× less than
  FETI-DP, in 3D up to 1.16× less: the box in 3);
- more: FETI-DP, held bodies or floating (2D Hertz cut in 38 of equal volume: 0.75× FETI-1's
  time, 0.8× TFETI's, where FETI-1 took 1.07× TFETI's; in 3D, since FETI-DP's K_rr is
  factored per subdomain and Ψ solved per subdomain with its own corner columns, 0.58–0.93×
  FETI-1's time from 5 subdomains per body on: docs/benchmarks.md § 23). The crossover is
  lower in 3D, where FETI-DP's whole corner edges cut the F-multiplications 4–10×, than in
  2D, where its corners are vertices only. TFETI was the slowest on most cases and is not
  chosen.

Reads counts only, the same on every rank.
"""

from __future__ import annotations

#: More subdomains per body than this (on average) make FETI-DP the choice, by the mesh's
#: dimension. 2D: between B1's 16 (FETI-1 1.3× faster than FETI-DP) and 2D Hertz's 19 of equal
#: volume (FETI-DP 1.34× faster than FETI-1). 3D (one body, equal volumes): between 3 (the box:
#: FETI-1 1.16× faster; the sphere S2: FETI-DP 1.14× faster) and 5 (FETI-DP 1.07× faster on
#: the box, 1.3× on S2; 1.4–1.7× from 7 to 24).
MANY_PER_BODY = {2: 16, 3: 4}


def method_by_time(glued: bool, num_subdomains: int, num_bodies: int, gdim: int) -> str:
    """``"feti1"`` or ``"fetidp"``: the method of least measured time (module docstring).

    Args:
        glued: Whether there are gluing rows (a body in several subdomains).
        num_subdomains: The subdomains of the whole problem.
        num_bodies: The bodies of the mesh.
        gdim: The mesh's geometric dimension (2 or 3).
    """
    many = MANY_PER_BODY[2 if gdim <= 2 else 3]
    if not glued or num_subdomains <= many * max(num_bodies, 1):
        return "feti1"
    return "fetidp"


__all__ = ["MANY_PER_BODY", "method_by_time"]
