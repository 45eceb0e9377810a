"""Property-based tests (Hypothesis): generated valid problems keep their invariants, generated
invalid input gets a named InputError (issue 26).

Valid problems: two blocks of non-matching Kuhn-triangle grids
(``tests/support/hand_meshes.py``: any sizes, heights, offsets), one on the other, in mortar
contact or tied, with a random traction, decomposition and FETI method. Invariants: the KKT
residuals at the tolerance; the same answer for every method; the same answer translated (up
to 1e3 away) and in other units (u scales with the lengths when E and the traction scale
together); zero load gives exactly zero at once; the mirror image of a problem has the mirror
image of its answer; and under mpirun the same answer on one rank and on all.

Invalid input: wrong types, NaN/inf, out-of-range values of every public constructor's
arguments and of the solver options, and meshes with non-finite coordinates or unknown group
names: an InputError that names the argument.

Seeds: the "ci" profile (the default, in the normal suite: a few examples, < 60 s in all) is
derandomized (the same examples every run, on every rank); the "bench" profile
(``FETI_PROPERTIES=bench``, many more examples, run by ``python bench/property_suite.py``)
draws from ``--hypothesis-seed`` (the script prints it), so any failure replays with the same
seed; a failing example is also printed as a ``@reproduce_failure`` blob.
"""

from __future__ import annotations

import dataclasses
import math
import os

import numpy as np
import pytest
from hand_meshes import blocks, stacked, transformed
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st
from mpi4py import MPI
from stress_cases import ConstElasticity

import dolfinx_feti as df

COMM = MPI.COMM_WORLD
PROFILE = os.environ.get("FETI_PROPERTIES", "ci")
_COMMON = {"deadline": None, "database": None, "print_blob": True,
           "suppress_health_check": [HealthCheck.too_slow, HealthCheck.data_too_large]}
settings.register_profile("ci", max_examples=4, derandomize=True, **_COMMON)
settings.register_profile("bench", derandomize=False, **_COMMON,
                          max_examples=int(os.environ.get("FETI_PROPERTIES_EXAMPLES", 40)))
SOLVES = settings.get_profile(PROFILE)
#: Input checks cost no solve: more examples in the same time.
CHECKS = settings(SOLVES, max_examples=SOLVES.max_examples * 10)

RTOL = 1e-10
#: The answers of two solves at RTOL agree to this, relative to max |u|.
AGREE = 1e-6


# ------------------------------------------------------------------------------------------
# Valid problems
# ------------------------------------------------------------------------------------------


@dataclasses.dataclass
class Case:
    """A generated problem: the mesh's shape and everything put on it."""

    n_lower: int
    n_upper: int
    height: float
    shift: float
    kind: str  # "mortar" or "tie"
    traction: tuple[float, float]
    decomposition: object
    method: str

    def mesh(self) -> df.MeshData:
        return stacked(self.n_lower, self.n_upper, shift=self.shift, height=self.height)

    def problem(self, mesh=None, *, stress: float = 1.0, traction=None, mirror: bool = False
                ) -> df.ContactProblem:
        mesh = self.mesh() if mesh is None else mesh
        t = self.traction if traction is None else traction
        side = "upper_right" if mirror else "upper_left"  # the side held in x
        pair = ("upper_bottom", "lower_top")
        cond = {"contact": [df.Mortar(*pair)]} if self.kind == "mortar" else \
            {"ties": [df.Tie(*pair)]}
        return df.ContactProblem(
            mesh, ConstElasticity(1.0 * stress, 0.3, {"upper_top": tuple(stress * v for v in t)}),
            dirichlet=[df.Dirichlet("lower_bottom"), df.Dirichlet(side, components=(0,))],
            decomposition=self.decomposition, **cond)


def _grid(nx: int):
    def labels(mid):
        return np.floor(mid[:, 0] * nx).astype(np.int64)
    return df.ByFunction(labels)


@st.composite
def cases(draw) -> Case:
    n_lower, n_upper = draw(st.integers(2, 6)), draw(st.integers(2, 6))
    decomposition = draw(st.sampled_from(["tags", "parts", "grid"]))
    dec = {"tags": df.ByTags(), "parts": df.Parts(draw(st.integers(2, 3))),
           "grid": _grid(draw(st.integers(2, 3)))}[decomposition]
    return Case(n_lower=n_lower, n_upper=n_upper,
                height=draw(st.sampled_from([0.25, 0.5, 1.0])),
                shift=draw(st.sampled_from([0.0, 0.125, -0.25])),
                kind=draw(st.sampled_from(["mortar", "tie"])),
                traction=(draw(st.floats(-0.01, 0.01)), draw(st.floats(-0.05, -0.001))),
                decomposition=dec, method=draw(st.sampled_from(["tfeti", "feti1", "fetidp"])))


def solve(problem, **options) -> tuple[np.ndarray, df.Solution]:
    sol = df.solve(problem, rtol=RTOL, **options)
    assert sol.report.converged, sol.report.reason
    return sol.nodal_values(), sol


def close(a: np.ndarray, b: np.ndarray, what: str) -> None:
    scale = max(float(np.abs(a).max()), 1e-300)
    err = float(np.abs(a - b).max()) / scale
    note(f"{what}: relative difference {err:.2e}")
    assert err <= AGREE, f"{what}: relative difference {err:.2e}"


@SOLVES
@given(case=cases())
def test_kkt_and_every_method_agree(case):
    note(repr(case))
    u, sol = solve(case.problem(), method="tfeti")
    worst = max(sol.report.kkt.values())
    assert worst <= 1e3 * RTOL, sol.report.kkt  # the report's own warning threshold
    other = case.method if case.method != "tfeti" else "feti1"
    v, _ = solve(case.problem(), method=other)
    close(u, v, f"tfeti against {other}")


@SOLVES
@given(case=cases(), shift=st.tuples(st.sampled_from([0.0, 1.0, -7.5, 1e3]),
                                     st.sampled_from([0.0, 3.25, -1e3])),
       length=st.sampled_from([1e-3, 1.0, 1e3]), stress=st.sampled_from([1e-6, 1.0, 1e6]))
def test_translation_and_units_change_nothing(case, shift, length, stress):
    note(repr(case))
    u, _ = solve(case.problem(), method=case.method)
    mesh = transformed(case.mesh(), scale=length, shift=(shift[0] * length, shift[1] * length))
    v, _ = solve(case.problem(mesh, stress=stress), method=case.method)
    close(u, v / length, f"shifted by {shift}, lengths x{length}, stresses x{stress}")


@SOLVES
@given(case=cases())
def test_zero_load_gives_exactly_zero_at_once(case):
    note(repr(case))
    sol = df.solve(case.problem(traction=(0.0, 0.0)), rtol=RTOL, method=case.method)
    assert sol.report.converged
    assert sol.report.iterations == 0, sol.report.iterations
    assert np.all(sol.nodal_values() == 0.0)


def mirrored(mesh: df.MeshData) -> df.MeshData:
    """The mirror image in x = 0: the same nodes and cells, left and right swapped."""
    x = mesh.x.copy()
    x[:, 0] = -x[:, 0]
    swap = {"left": "right", "right": "left"}
    groups = {}
    for name, f in mesh.facet_groups.items():
        body, side = name.split("_")
        groups[f"{body}_{swap.get(side, side)}"] = f
    return dataclasses.replace(mesh, x=x, facet_groups=groups)


@SOLVES
@given(case=cases())
def test_the_mirror_image_has_the_mirrored_answer(case):
    note(repr(case))
    if isinstance(case.decomposition, df.ByFunction):  # labels by x: the same cells mirrored
        case = dataclasses.replace(case, decomposition=df.ByTags())
    u, _ = solve(case.problem(), method=case.method)
    tx, ty = case.traction
    v, _ = solve(case.problem(mirrored(case.mesh()), traction=(-tx, ty), mirror=True),
                 method=case.method)
    close(u, v * np.array([-1.0, 1.0]), "mirror image")


@pytest.mark.skipif(COMM.size == 1, reason="compares one rank with all: mpirun -n 2")
@SOLVES
@given(case=cases())
def test_one_rank_and_all_ranks_agree(case):
    note(repr(case))
    u, _ = solve(case.problem(), method=case.method)
    v = df.solve(case.problem(), comm=MPI.COMM_SELF, rtol=RTOL, method=case.method)
    close(u, v.nodal_values(), f"{COMM.size} ranks against 1")


# ------------------------------------------------------------------------------------------
# Invalid input
# ------------------------------------------------------------------------------------------

MESH = stacked()
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf])
NOT_A_NUMBER = st.sampled_from(["1", b"1", None, [1.0, math.nan], {"a": 1}, object()])
NOT_TEXT = st.sampled_from([1, 2.5, None, b"top", ["top"], object()])


def _bad(draw, good_kind: str):
    """A value that is not a finite number (``"number"``) or not a name (``"text"``)."""
    if good_kind == "text":
        return draw(NOT_TEXT)
    return draw(st.one_of(NON_FINITE, NOT_A_NUMBER))


@st.composite
def bad_arguments(draw):
    """(what to call, the argument's name) for a call that must be refused."""
    which = draw(st.sampled_from([
        "dirichlet.group", "dirichlet.value", "mortar.slave", "mortar.search_distance",
        "tie.search_distance", "plane.point", "plane.normal", "sphere.radius", "coulomb",
        "tresca", "elasticity.E", "elasticity.nu", "parts.n", "rtol", "max_it",
        "node_to_node.match_tol", "node_to_node.gap"]))
    number = _bad(draw, "number")
    text = _bad(draw, "text")
    negative = draw(st.sampled_from([0.0, -1.0, -1e-300]))
    calls = {
        "dirichlet.group": (lambda: df.Dirichlet(text), "group"),
        "dirichlet.value": (lambda: df.Dirichlet("top", value=number), "value"),
        "mortar.slave": (lambda: df.Mortar(text, "b"), "slave"),
        "mortar.search_distance": (lambda: df.Mortar("a", "b", search_distance=draw(
            st.one_of(NON_FINITE, NOT_A_NUMBER.filter(lambda v: v is not None),
                      st.just(negative)))), "search_distance"),
        "tie.search_distance": (lambda: df.Tie("a", "b", search_distance=draw(
            st.one_of(NON_FINITE, st.just(negative)))), "search_distance"),
        "plane.point": (lambda: df.Plane(point=(0.0, number), normal=(0.0, 1.0)), "point"),
        "plane.normal": (lambda: df.Plane(point=(0.0, 0.0), normal=draw(st.sampled_from(
            [(0.0, 0.0), (math.nan, 1.0), (math.inf, 0.0)]))), "normal"),
        "sphere.radius": (lambda: df.Sphere(center=(0.0, 0.0), radius=draw(
            st.one_of(NON_FINITE, st.just(negative)))), "radius"),
        "coulomb": (lambda: df.Coulomb(draw(st.sampled_from([-0.1, math.nan, math.inf]))),
                    "coefficient"),
        "tresca": (lambda: df.Tresca(draw(st.sampled_from([-1.0, math.nan, -math.inf]))),
                   "bound"),
        # the material constants: by type when made, by range when the problem is made
        "elasticity.E": (lambda: df.ContactProblem(MESH, df.Elasticity(E=draw(st.one_of(
            NON_FINITE, st.just(negative), st.just("200"))), nu=0.3)), "E"),
        "elasticity.nu": (lambda: df.ContactProblem(MESH, df.Elasticity(E=1.0, nu=draw(
            st.sampled_from([0.5, 0.7, -1.0, -2.0, math.nan])))), "nu"),
        "parts.n": (lambda: df.Parts(draw(st.sampled_from([0, -2, 2.5, 10**12, math.nan]))),
                    "n"),
        "rtol": (lambda: df.SolverOptions.create(rtol=draw(st.one_of(
            NON_FINITE, st.sampled_from([0.0, 1.0, 2.0, -1e-8, "1e-8x"])))), "rtol"),
        "max_it": (lambda: df.SolverOptions.create(max_it=draw(st.sampled_from(
            [0, -1, 1.5, math.nan, 10**12, "many"]))), "max_it"),
        "node_to_node.match_tol": (lambda: df.NodeToNode("a", "b", match_tol=draw(
            st.sampled_from([0.0, 1.0, math.nan, math.inf, -1e-3]))), "match_tol"),
        "node_to_node.gap": (lambda: df.NodeToNode("a", "b", gap=draw(NON_FINITE)), "gap"),
    }
    return (which, *calls[which])


@CHECKS
@given(bad=bad_arguments())
def test_bad_arguments_are_refused_by_name(bad):
    which, call, name = bad
    note(which)
    with pytest.raises(df.InputError) as info:
        call()
    assert name in str(info.value), str(info.value)


@st.composite
def bad_meshes(draw):
    """(mesh, what the problem names, words the error must hold) of a broken problem."""
    mesh = stacked(draw(st.integers(2, 4)), draw(st.integers(2, 4)))
    fault = draw(st.sampled_from(["coordinate", "group", "body", "shape"]))
    if fault == "coordinate":
        x = mesh.x.copy()
        x[draw(st.integers(0, x.shape[0] - 1)), draw(st.integers(0, 1))] = draw(NON_FINITE)
        return dataclasses.replace(mesh, x=x), {}, ("non-finite",)
    if fault == "group":
        name = draw(st.sampled_from(["lower_tip", "Upper_bottom", "", "upper bottom"]))
        role = draw(st.sampled_from(["dirichlet", "mortar", "tie", "traction"]))
        if name == "":
            return mesh, {role: name}, ("non-empty string",)
        return mesh, {role: name}, ("unknown boundary group", repr(name))
    if fault == "body":
        return blocks([{"name": "lower", "n": (2, 1)}]), {"tie": "upper_bottom"}, (
            "unknown boundary group",)
    x = np.concatenate([mesh.x, np.zeros((mesh.x.shape[0], 1))], axis=1)  # 3D points
    return dataclasses.replace(mesh, x=x), {"mortar": "upper_bottom"}, ("the mesh is 3D",)


@CHECKS
@given(bad=bad_meshes())
def test_broken_problems_are_refused_before_any_solve(bad):
    mesh, names, words = bad
    note(f"{names} {words}")
    with pytest.raises(df.InputError) as info:
        dirichlet = [df.Dirichlet(names.get("dirichlet", "lower_bottom"))]
        tractions = {names.get("traction", "upper_top"): (0.0, -0.01)}
        pair = (names.get("mortar", names.get("tie", "upper_bottom")), "lower_top")
        cond = {"ties": [df.Tie(*pair)]} if "tie" in names else {"contact": [df.Mortar(*pair)]}
        df.solve(df.ContactProblem(mesh, df.Elasticity(E=1.0, nu=0.3, tractions=tractions),
                                   dirichlet=dirichlet, **cond))
    msg = str(info.value)
    assert all(w in msg for w in words), msg


#: Valid values of some collective options: any two that differ, one per rank, are an error.
PER_RANK = {
    "rtol": st.floats(1e-12, 1e-4),
    "max_it": st.integers(10, 10_000),
    "method": st.sampled_from(["tfeti", "feti1", "fetidp"]),
    "stop_test": st.sampled_from(["kkt", "dual"]),
    "preconditioner": st.sampled_from(["none", "lumped", "dirichlet"]),
}


class _OtherRank:
    """A stand-in communicator of two ranks (serially): the other rank has ``other``."""

    size = 2

    def __init__(self, other: df.SolverOptions) -> None:
        self.other = other

    def allgather(self, mine):
        return [mine, {k: repr(v) for k, v in self.other.to_dict().items()}]


@CHECKS
@given(data=st.data())
def test_options_that_differ_per_rank_are_named_on_every_rank(data):
    """Two valid values of one option, rank 0 one and the other ranks the other: an InputError
    on every rank naming it, before any work (serially against a stand-in second rank; under
    mpirun by the solver's own check, every rank must raise: none may hang)."""
    from dolfinx_feti.options import check_same_on_ranks

    name = data.draw(st.sampled_from(sorted(PER_RANK)))
    a, b = data.draw(st.lists(PER_RANK[name], min_size=2, max_size=2, unique=True))
    note(f"{name}: {a!r} on rank 0, {b!r} on the others")
    mine = df.SolverOptions.create(**{name: a if COMM.rank == 0 else b})
    with pytest.raises(df.InputError) as info:
        if COMM.size == 1:
            check_same_on_ranks(mine, _OtherRank(df.SolverOptions.create(**{name: b})))
        else:
            df.FetiSolver(PROBLEM, options=mine)
    msg = str(info.value)
    assert "differ between the ranks" in msg and name in msg, msg
    assert len(set(COMM.allgather(msg))) == 1  # the same words on every rank


PROBLEM = df.ContactProblem(MESH, df.Elasticity(E=1.0, nu=0.3,
                                                tractions={"upper_top": (0.0, -0.01)}),
                            dirichlet=[df.Dirichlet("lower_bottom")],
                            contact=[df.Mortar("upper_bottom", "lower_top")])
