"""A block of constraint rows B u (=|<=) c; entries addressed by (subdomain, node, component)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from enum import IntEnum

import numpy as np


class Kind(IntEnum):
    """What a row expresses."""

    GLUE = 0
    DIRICHLET = 1
    CONTACT = 2  # node-to-node, between two bodies
    OBSTACLE = 3  # a body against a rigid obstacle
    TANGENT = 4  # friction: relative tangential displacement of a contact node (box/disc bound)


@dataclass
class Rows:
    """Constraint rows in coordinate form.

    Entries: ``coef`` at row ``e_row`` and primal dof (``e_sub``, ``e_node``, ``e_comp``).
    Per row: right-hand side ``rhs`` (of the scaled row), ``kind``, ``scale`` (the row is the
    physical constraint multiplied by ``scale``, so the physical multiplier — a nodal force —
    is ``scale * λ``), ``node`` (the slave/constrained node), ``partner`` (the master node of a
    node-to-node pair, else -1), ``normal`` (contact normal, zeros otherwise; for a TANGENT
    row its unit tangent t, the row being scale·(u_slave − u_master)·t) and ``spec`` (index of
    the condition in the problem's list that made the row).
    """

    e_row: np.ndarray
    e_sub: np.ndarray
    e_node: np.ndarray
    e_comp: np.ndarray
    e_coef: np.ndarray
    rhs: np.ndarray
    kind: np.ndarray
    scale: np.ndarray
    node: np.ndarray
    partner: np.ndarray
    normal: np.ndarray
    spec: np.ndarray

    @property
    def size(self) -> int:
        """Number of rows."""
        return self.rhs.size

    @property
    def inequality(self) -> np.ndarray:
        """Mask of the rows that are inequalities (B u <= c)."""
        return (self.kind == Kind.CONTACT) | (self.kind == Kind.OBSTACLE)

    @property
    def tangential(self) -> np.ndarray:
        """Mask of the friction rows (multipliers in a box or a disc, see constraints.friction)."""
        return self.kind == Kind.TANGENT

    @staticmethod
    def empty(gdim: int) -> Rows:
        """No rows."""
        z = np.zeros(0)
        zi = np.zeros(0, dtype=np.int64)
        return Rows(zi, zi.astype(np.int32), zi, zi.astype(np.int8), z, z, zi.astype(np.int8), z,
                    zi, zi, np.zeros((0, gdim)), zi.astype(np.int32))

    @staticmethod
    def concatenate(blocks: list[Rows]) -> Rows:
        """Stack row blocks (row numbers are shifted)."""
        shift = np.cumsum([0] + [b.size for b in blocks[:-1]])
        out = {}
        for f in fields(Rows):
            parts = [getattr(b, f.name) for b in blocks]
            if f.name == "e_row":
                parts = [p + s for p, s in zip(parts, shift, strict=True)]
            out[f.name] = np.concatenate(parts)
        return Rows(**out)

    def permuted(self, order: np.ndarray) -> Rows:
        """The rows ``order`` in that order (new row i is old row order[i]).

        Rows not in ``order`` are left out. The entries of a row keep their order.
        """
        order = np.asarray(order, dtype=np.int64)
        new_of_old = np.full(self.size, -1, dtype=np.int64)
        new_of_old[order] = np.arange(order.size)
        e_new = new_of_old[self.e_row]
        kept = np.flatnonzero(e_new >= 0)
        e_order = kept[np.argsort(e_new[kept], kind="stable")]
        out = {}
        for f in fields(Rows):
            v = getattr(self, f.name)
            out[f.name] = v[e_order] if f.name.startswith("e_") else v[order]
        out["e_row"] = e_new[e_order]
        return Rows(**out)

    def min_subdomain(self) -> np.ndarray:
        """The smallest subdomain each row touches (its owner is that subdomain's rank)."""
        m = np.full(self.size, np.iinfo(np.int32).max, dtype=np.int64)
        np.minimum.at(m, self.e_row, self.e_sub)
        return m
