"""PETSc's options database in tests: values set for a block and removed after it."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from petsc4py import PETSc


@contextmanager
def petsc_options(**values) -> Iterator[None]:
    """Set ``-<name> value`` in the PETSc options database for the block, then remove them."""
    db = PETSc.Options()
    try:
        for k, v in values.items():
            db.setValue(k, v)
        yield
    finally:
        for k in values:
            db.delValue(k)
