"""What may change between two load cases of one set-up, and a refusal naming what may not.

:meth:`~dolfinx_feti.FetiSolver.update` reuses the decomposition, the rows' structure and the
factorizations, so the new problem must have the same mesh, groups, decomposition, conditions
and stiffness; its loads (tractions, body forces), Dirichlet values, rigid obstacles'
positions and friction values (coefficients, Tresca bounds; Tresca for Coulomb and back) may
differ — not whether a condition has friction (that makes the tangential rows).
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from ..errors import InputError, collective
from ..mesh.decompose import ByFunction
from .conditions import Dirichlet
from .contact_problem import ContactProblem


def _dirichlet_key(bc: Dirichlet) -> tuple:
    return bc.group, None if bc.components is None else tuple(int(c) for c in bc.components)


def stiffness_key(forms):
    """What determines the stiffness matrix of ``forms``, when the forms object says so.

    :class:`~dolfinx_feti.Elasticity` and :class:`~dolfinx_feti.Poisson` give theirs
    (``stiffness_key``); for a plain callable the object itself stands for its bilinear form.
    """
    key = getattr(forms, "stiffness_key", None)
    return key() if callable(key) else forms


def _same_decomposition(old, new) -> bool:
    """Equal, or two ByFunction (whose labels :func:`check_same_labels` compares)."""
    return new == old or (isinstance(old, ByFunction) and isinstance(new, ByFunction))


def check_same_labels(how, share, comm: MPI.Comm) -> None:
    """Refuse a ByFunction whose labels cut a subdomain of the set-up (collective).

    The function of a new load case is another object (a new closure per step is usual), so
    its labels are checked on each rank's cells: every subdomain of the set-up must get one
    label. (Labels that join two subdomains are not detected: they would have given the same
    subdomains, split into connected pieces, only if the pieces were separate.)
    """
    if not isinstance(how, ByFunction):
        return
    mesh, cell_sub = share.mesh, share.dec.cell_sub
    with collective(comm, "decomposition"):
        try:
            labels = np.asarray(how.fn(mesh.x[mesh.cells].mean(axis=1)))
        except Exception as e:  # a user's function: say which one failed
            raise InputError(f"ByFunction.fn(midpoints) raised {type(e).__name__}: {e}") from e
        if labels.shape != cell_sub.shape:
            raise InputError("ByFunction: the function must return one label per cell")
        order = np.lexsort((labels, cell_sub))
        sub, lab = cell_sub[order], labels[order]
        cut = np.any((sub[1:] == sub[:-1]) & (lab[1:] != lab[:-1]))
    if comm.allreduce(bool(cut), op=MPI.LOR):
        raise InputError("FetiSolver.update: the new problem's ByFunction decomposition cuts a "
                         "subdomain of the set-up; the decomposition cannot change on one set-up")


def check_same_structure(old: ContactProblem, new: ContactProblem, *,
                         stiffness: bool = True) -> None:
    """Refuse, by name, a new problem whose differences a set-up of ``old`` cannot reuse.

    Args:
        old: The problem of the set-up.
        new: The new load case.
        stiffness: Whether the bilinear form must be the same too (not for a new stiffness).

    Raises:
        InputError: Naming the first difference found.
    """
    if not isinstance(new, ContactProblem):
        raise InputError(f"update takes a ContactProblem, got {type(new).__name__}")
    same = [
        ("mesh", new.mesh is old.mesh, "another mesh object (the decomposition and the "
         "shares belong to the set-up's mesh)"),
        ("value_size", new.value_size == old.value_size, f"{new.value_size} components, not "
         f"{old.value_size}"),
        ("degree", new.degree == old.degree, f"degree {new.degree}, not {old.degree}"),
        ("decomposition", _same_decomposition(old.decomposition, new.decomposition),
         f"{new.decomposition!r}, not {old.decomposition!r}"),
        ("gluing", new.gluing == old.gluing, f"{new.gluing!r}, not {old.gluing!r}"),
        ("ties", list(new.ties) == list(old.ties), "other ties"),
        ("dirichlet", [_dirichlet_key(b) for b in new.dirichlet]
         == [_dirichlet_key(b) for b in old.dirichlet],
         "other Dirichlet groups or components (their values may change)"),
        ("contact", [c.structure_key() for c in new.contact]
         == [c.structure_key() for c in old.contact],
         "other contact conditions, groups, or friction where there was none or none where "
         "there was (a rigid obstacle's position and the friction values may change)"),
    ]
    if stiffness:
        differs = stiffness_key(new.forms) != stiffness_key(old.forms)
        same.append(("forms", not differs, "another material or bilinear form; use "
                     "FetiSolver.update_stiffness(problem) (or update(problem, "
                     "check_stiffness=True) for forms whose stiffness is unchanged)"))
    for name, ok, why in same:
        if not ok:
            raise InputError(f"FetiSolver.update: the new problem differs in {name}: {why}. "
                             "Only loads, Dirichlet values, obstacle positions and friction "
                             "values may change on one set-up; create a new FetiSolver for the "
                             "rest")


__all__ = ["check_same_labels", "check_same_structure", "stiffness_key"]
