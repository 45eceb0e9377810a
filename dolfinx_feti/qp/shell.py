"""PETSc python-shell Mats that are safe to keep alive until the interpreter exits.

With petsc4py 3.18 a python Mat whose context class lives in an imported module and that is
still alive at exit is destroyed by ``PetscFinalize`` after the interpreter has shut down,
which crashes (SEGV in ``MatDestroy``). Destroying the live shells from a Python ``atexit``
hook, which runs before that, avoids it; shells collected earlier are unaffected.
"""

from __future__ import annotations

import atexit
import weakref

from petsc4py import PETSc

_live: list[weakref.ref] = []


def _destroy_live() -> None:
    # Same creation order on every rank, so the collective destroys match up.
    for ref in _live:
        mat = ref()
        if mat is not None:
            mat.destroy()
    _live.clear()


atexit.register(_destroy_live)


def python_shell(ctx, template: PETSc.Vec) -> PETSc.Mat:
    """Return a square python-type Mat with context ``ctx`` and the layout of ``template``.

    ``ctx`` needs ``mult(mat, x, y)`` (and ``multTranspose`` if transposes are used). The Mat
    is destroyed automatically at interpreter exit if it is still alive then.
    """
    sizes = template.getSizes()
    mat = PETSc.Mat().createPython((sizes, sizes), context=ctx, comm=template.getComm())
    mat.setUp()
    _live[:] = [r for r in _live if r() is not None]
    _live.append(weakref.ref(mat))
    return mat
