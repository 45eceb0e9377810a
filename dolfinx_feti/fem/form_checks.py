"""What the forms callback returns, checked before and after assembly, with the real cause.

DOLFINx's own errors for these are about its internals ("Cannot create sparsity pattern",
an index out of range, "too many values to unpack"), and a non-symmetric stiffness matrix
passes assembly and factorization and fails much later, in the K K⁺ K = K check, as "a larger
null space than the rigid-body modes". So: the arguments of each form (a: test and trial,
L: test only), their arity (linear in each argument: ufl's own check), and K = Kᵀ.
"""

from __future__ import annotations

import functools
import weakref

import numpy as np
import scipy.sparse as sp
import ufl
from ufl.algorithms.apply_algebra_lowering import apply_algebra_lowering
from ufl.algorithms.apply_derivatives import apply_derivatives
from ufl.algorithms.check_arities import ArityMismatch, check_form_arity
from ufl.algorithms.remove_complex_nodes import remove_complex_nodes
from ufl.classes import CompoundDerivative, Derivative
from ufl.corealg.traversal import unique_pre_traversal

from ..errors import InputError

#: The largest entry of K or f the solver computes with: norms and dot products square them,
#: and a square above ~1e308 overflows to inf (the QP solver would stop on a bare NaN).
LARGEST = 1e150

#: K is symmetric when max |K − Kᵀ| <= SYMMETRY_RTOL · max |K| (assembly rounds the two
#: triangles independently; a non-symmetric term is of the size of the entries it adds to).
SYMMETRY_RTOL = 1e-10

_HINT = ("forms(V, sub) must return (a, L): a bilinear in (u, v) = (TrialFunction(V), "
         "TestFunction(V)) and L linear in v, or None (a residual F(w; v) of a Function w, or "
         "a form nonlinear in u, is not accepted: differentiate it, a = ufl.derivative(F, w, "
         "u), and solve for the increment)")


def check_form_kinds(a, L, where: str) -> None:
    """Refuse forms that are not bilinear (a) and linear (L), before DOLFINx sees them.

    Args:
        a: The bilinear form returned by the callback.
        L: The linear form (None for no load).
        where: Which subdomains, for messages.

    Raises:
        InputError: Naming the form and what it is instead.
    """
    for form, what, want in ((a, "bilinear", (0, 1)), (L, "linear", (0,))):
        if form is None and what == "linear":
            continue
        if not isinstance(form, ufl.Form):
            raise InputError(f"{where}: the {what} form is a {type(form).__name__}, not a UFL "
                             f"form; {_HINT}")
        numbers = tuple(sorted(arg.number() for arg in form.arguments()))
        if numbers != want:
            names = {0: "test", 1: "trial"}
            has = ", ".join(names.get(n, str(n)) for n in numbers) or "none"
            raise InputError(f"{where}: the {what} form has the arguments ({has}) instead of "
                             f"({', '.join(names[n] for n in want)}); {_HINT}")
        try:
            check_form_arity(_expanded(form), form.arguments())
        # ufl 2022 raises ArityMismatch with a message it fails to format: the formatting's
        # NotImplementedError or TypeError comes out instead
        except (ArityMismatch, NotImplementedError, TypeError) as e:
            detail = str(e) if isinstance(e, ArityMismatch) else "an argument enters nonlinearly"
            raise InputError(f"{where}: the {what} form is not {what} in its arguments "
                             f"({detail}); {_HINT}") from None


def check_magnitudes(K: sp.csr_matrix, f: np.ndarray, where: str) -> None:
    """Refuse a stiffness or load too large to square in double precision.

    Raises:
        InputError: Naming which one and its largest entry.
    """
    for what, values in (("load vector", f), ("stiffness matrix", K.data)):
        big = float(np.abs(values).max(initial=0.0))
        if big > LARGEST:
            raise InputError(f"{where}: the assembled {what} has entries up to {big:.3g}, beyond "
                             f"{LARGEST:.0e}: the solver's norms square them and would overflow "
                             "double precision; express the problem in other units (e.g. MPa "
                             "and mm instead of Pa and m) or check the data (a traction or "
                             "material constant off by many orders)")


def check_symmetric(K: sp.csr_matrix, where: str) -> None:
    """Refuse a non-symmetric stiffness matrix (FETI and the Cholesky factors need K = Kᵀ).

    Raises:
        InputError: With the largest asymmetry relative to the largest entry.
    """
    if K.nnz == 0:
        return
    scale = float(np.abs(K.data).max())
    D = (K - K.T).tocsr()
    asym = float(np.abs(D.data).max(initial=0.0))
    if asym > SYMMETRY_RTOL * scale:
        i = int(np.argmax(np.abs(D.data)))
        row = int(np.searchsorted(D.indptr, i, side="right") - 1)
        raise InputError(f"{where}: the bilinear form is not symmetric: the assembled matrix has "
                         f"|K - K^T| up to {asym:.3g} (relative {asym / scale:.1e}, e.g. at row "
                         f"{row}, column {int(D.indices[i])}); FETI with Cholesky factors needs "
                         "a symmetric a(u, v) = a(v, u) (an advection or other first-order term, "
                         "or a swapped test and trial function in one term, breaks it)")


def _expanded(form: ufl.Form) -> ufl.Form:
    """The form with its algebra lowered and, only if it has any, its derivatives applied.

    Grad, div and the like are left as they are (the arity check reads them); only a
    ``derivative``/``diff`` needs ufl's derivative algorithm, which on Python 3.13.0 keeps
    every rule object it makes alive (see :func:`_release_traversers`). The solver is real:
    the conjugates that ``inner`` puts on the test function are removed, as DOLFINx does
    before its own check (else ``derivative`` of a residual mixes v and conj(v)).
    """
    form = remove_complex_nodes(apply_algebra_lowering(form))
    if any(isinstance(o, Derivative) and not isinstance(o, CompoundDerivative)
           for itg in form.integrals() for o in unique_pre_traversal(itg.integrand())):
        form = apply_derivatives(form)
        _release_traversers()
    return form


def _release_traversers() -> None:
    """Forget the bound methods Python 3.13.0's ``singledispatchmethod`` caches per object.

    That cache (a weak-key dictionary whose values are closures over their keys, removed again
    in later Pythons) keeps each of ufl's rule objects alive, and with it the expressions it
    cached, their function spaces and meshes, and the MPI communicators the meshes hold: a few
    hundred assemblies later MPICH has no communicator left ("Too many communicators", PETSc
    error 98 at the next MatCreate).
    """
    try:
        from ufl.corealg.dag_traverser import DAGTraverser
    except ImportError:  # ufl < 2025 has no such rule objects
        return
    todo = [DAGTraverser]
    while todo:
        cls = todo.pop()
        todo.extend(cls.__subclasses__())
        for attr in vars(cls).values():
            cache = getattr(attr, "_method_cache", None)
            if isinstance(attr, functools.singledispatchmethod) and \
                    isinstance(cache, weakref.WeakKeyDictionary):
                cache.clear()


def check_finite_literals(expr, what: str) -> None:
    """Refuse a NaN or infinite number in a form or expression, naming ``what``.

    FFCx would write it into C code that fails to build (a bare compiler error); a load whose
    literals become runtime constants would assemble NaN instead.

    Raises:
        InputError: A literal is NaN or infinite.
    """
    if isinstance(expr, ufl.Form):
        integrands = [i.integrand() for i in expr.integrals()]
    else:  # an expression, or no form at all (None, 0)
        integrands = [expr] if isinstance(expr, ufl.core.expr.Expr) else []
    for integrand in integrands:
        for node in unique_pre_traversal(integrand):
            if isinstance(node, ufl.constantvalue.ScalarValue) and not np.isfinite(node.value()):
                raise InputError(f"{what} is not finite: it contains the number {node.value()}")
