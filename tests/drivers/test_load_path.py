"""Load paths and load cases on one set-up (``df.solve_path``, ``df.solve_cases``).

Without friction the path does not matter: every step equals a single solve at its load. With
friction (2D boxes, 3D discs) the tangential rows act on the slip increment of the step: each
step equals an independent monolithic solve (``friction_reference``, semismooth Newton on the
dense dual) whose tangential rows' right-hand sides are its own previous step's B_t u; on the Hertz
disk-on-block (Cattaneo–Mindlin) a tangential load taken back to zero leaves tangential
tractions locked in, which a single solve at the final load does not have.
"""

from __future__ import annotations

import json
from contextlib import contextmanager

import numpy as np
import pytest
import reference as ref
import ufl
from friction_reference import FrictionReference
from mpi4py import MPI
from path_files import check_xdmf_series
from test_feti_solver import assert_no_setup, assert_same, hertz

import dolfinx_feti as df
from dolfinx_feti.drivers.friction import ETA_MAX, ETA_MAX_DISCS
from dolfinx_feti.io import meshes

RTOL = 1e-10


@pytest.fixture(scope="module")
def hertz_mesh(root):
    return df.read_gmsh(root / "meshes/hertz2d.msh")


# --- without friction: the path does not matter ---------------------------------------------
LOADS = (5.0, 10.0, 15.0, 10.0, 5.0, 0.5)  # load and unload


@pytest.mark.parametrize("method", ("tfeti", "fetidp"))
def test_frictionless_path_equals_single_solves(hertz_mesh, method):
    sols = df.solve_path(lambda t: hertz(hertz_mesh, load=LOADS[int(t)]), range(len(LOADS)),
                         rtol=RTOL, method=method)
    assert len(sols) == len(LOADS)
    for k, (sol, load) in enumerate(zip(sols, LOADS, strict=True)):
        assert sol.report.converged
        assert sol.report.extra["step"] == k and sol.report.extra["time"] == float(k)
        assert_same(sol, df.solve(hertz(hertz_mesh, load=load), rtol=RTOL, method=method))
        if k:
            assert_no_setup(sol)


def test_times_and_problems_checked(hertz_mesh):
    def at(t):
        return hertz(hertz_mesh)

    with pytest.raises(df.InputError, match="increase strictly"):
        df.solve_path(at, [0.0, 1.0, 1.0])
    with pytest.raises(df.InputError, match="non-empty"):
        df.solve_path(at, [])
    with pytest.raises(df.InputError, match="not a ContactProblem"):
        df.solve_path(lambda t: None, [0.0])
    with pytest.raises(df.InputError, match="differs in forms"):
        df.solve_path(lambda t: hertz(hertz_mesh, E=200.0 + t), [0.0, 1.0])

    def fails_on_the_last_rank(t):  # user code failing on one rank stops every rank
        if MPI.COMM_WORLD.rank == MPI.COMM_WORLD.size - 1:
            raise RuntimeError("no problem here")
        return hertz(hertz_mesh)

    with pytest.raises(df.SolveError, match="no problem here"):
        df.solve_path(fails_on_the_last_rank, [0.0])


def test_cases_amortized(hertz_mesh):
    loads = (5.0, 15.0, 10.0)
    sols = df.solve_cases([hertz(hertz_mesh, load=p) for p in loads], rtol=RTOL)
    for k, (sol, load) in enumerate(zip(sols, loads, strict=True)):
        assert_same(sol, df.solve(hertz(hertz_mesh, load=load), rtol=RTOL))
        case = sol.report.extra["case"]
        assert case["index"] == k and case["cases"] == 3
        assert 0 < case["amortized_seconds"] and case["setup_seconds"] <= sol.report.timings[
            "total"]
    # the later cases repeat no phase of the set-up (a structural check: times are for bench/)
    for sol in sols[1:]:
        assert not {"decomposition", "factorization", "coarse problem"} & set(
            sol.report.timings), sol.report.timings
    cold = df.solve_cases([hertz(hertz_mesh, load=p) for p in loads], rtol=RTOL, warm=False)
    for a, b in zip(sols, cold, strict=True):
        assert_same(a, b)


# --- friction with history against a monolithic reference ----------------------------------
E, NU = 21.19, 0.277
#: The block's top: pressed, sheared there and back (a load path of prescribed displacements).
SHIFTS = ((0.0, -0.02), (0.01, -0.02), (0.02, -0.02), (0.01, -0.02), (0.0, -0.02))


@pytest.fixture(scope="module")
def blocks(root):
    return df.build_mesh(meshes.tresca2d, n=6)


def sheared(mesh, shift, friction):
    return df.ContactProblem(
        mesh, df.Elasticity(E, NU),
        dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=shift)],
        contact=[df.NodeToNode("block_bottom", "foundation_top", friction=friction)],
        decomposition=df.Parts(3))


def reference_path(mesh, friction):
    """The monolithic path: each step's tangential rows start from the last step's B_t u."""
    out, slip0 = [], None
    for shift in SHIFTS:
        r = FrictionReference(mesh, ref.elasticity_forms(E, NU),
                              dirichlet=[("bottom", (0.0, 0.0)), ("top", shift)],
                              slave="block_bottom", master="foundation_top", normal=(0.0, 1.0))
        sol = r.solve_coulomb(friction.coefficient, slip0=slip0) \
            if isinstance(friction, df.Coulomb) else r.solve_tresca(friction.bound) \
            if slip0 is None else r.solve_bound(friction.bound * r.area, slip0=slip0)
        out.append(sol)
        slip0 = r.tangential_displacement(sol.u)
    return out


@pytest.mark.parametrize("method", ["tfeti", "fetidp"])
@pytest.mark.parametrize("friction", [df.Tresca(0.1), df.Coulomb(0.3, rtol=1e-10)],
                         ids=["tresca", "coulomb"])
def test_friction_path_against_monolithic_reference(blocks, friction, method):
    sols = df.solve_path(lambda t: sheared(blocks, SHIFTS[int(t)], friction),
                         range(len(SHIFTS)), rtol=RTOL, method=method, progress=False)
    refs = reference_path(blocks, friction)
    tol = 1e-6
    for sol, r in zip(sols, refs, strict=True):
        assert sol.report.converged
        c = sol.contact
        assert ref.rel_max_diff(sol.nodal_values(), r.u) <= tol
        scale = r.normal_force.max()
        assert np.abs(r.by_node(c.node, c.force) - r.normal_force).max() <= tol * scale
        ft = r.by_node(c.node, c.tangential_force)
        assert np.abs(ft - r.tangential_force).max() <= tol * scale
    # the path matters: back at the first shift, the state is not the first step's
    first, last = sols[0], sols[-1]
    assert ref.rel_max_diff(last.nodal_values(), first.nodal_values()) > 1e-3
    single = df.solve(sheared(blocks, SHIFTS[-1], friction), rtol=RTOL)
    assert_same(single, first, tol=1e-6)


def test_friction_values_change_between_steps(blocks):
    """A Tresca bound that changes along the path, and Tresca → Coulomb (the same rows)."""
    frictions = (df.Tresca(0.1), df.Tresca(0.05), df.Coulomb(0.3, rtol=1e-10))
    sols = df.solve_path(lambda t: sheared(blocks, SHIFTS[int(t)], frictions[int(t)]),
                         range(3), rtol=RTOL)
    slip0 = None
    for k, (sol, fr) in enumerate(zip(sols, frictions, strict=True)):
        r = FrictionReference(blocks, ref.elasticity_forms(E, NU),
                              dirichlet=[("bottom", (0.0, 0.0)), ("top", SHIFTS[k])],
                              slave="block_bottom", master="foundation_top", normal=(0.0, 1.0))
        rs = r.solve_coulomb(fr.coefficient, slip0=slip0) if isinstance(fr, df.Coulomb) \
            else r.solve_bound(fr.bound * r.area, slip0=slip0)
        assert ref.rel_max_diff(sol.nodal_values(), rs.u) <= 1e-6
        slip0 = r.tangential_displacement(rs.u)
    assert sols[2].report.extra["friction"]["model"] == "coulomb"
    problem = sheared(blocks, SHIFTS[0], None)
    with pytest.raises(df.InputError, match="differs in contact"):
        df.solve_path(lambda t: sheared(blocks, SHIFTS[0], frictions[0]) if t == 0 else problem,
                      [0.0, 1.0])


# --- 3D: discs (MPGP), a block pressed, sheared along x, then along y, then released ---------
SHIFTS3 = ((0.0, 0.0, -0.02), (0.02, 0.0, -0.02), (0.02, 0.02, -0.02), (0.0, 0.0, -0.02))


@pytest.mark.parametrize("friction", [df.Tresca(0.0075), df.Coulomb(0.3, rtol=1e-10)],
                         ids=["tresca", "coulomb"])
def test_friction_path_3d_against_monolithic_reference(friction):
    mesh = df.build_mesh(meshes.blocks3d, n=3)

    def at(t):
        return df.ContactProblem(
            mesh, df.Elasticity(1.0, 0.3),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=SHIFTS3[int(t)])],
            contact=[df.NodeToNode("contact_upper", "contact_lower", friction=friction)],
            decomposition=df.Parts(2))

    sols = df.solve_path(at, range(len(SHIFTS3)), rtol=RTOL, progress=False)
    slip0 = None
    for sol, shift in zip(sols, SHIFTS3, strict=True):
        r = FrictionReference(mesh, ref.elasticity_forms(1.0, 0.3),
                              dirichlet=[("bottom", (0, 0, 0)), ("top", shift)],
                              slave="contact_upper", master="contact_lower",
                              normal=(0.0, 0.0, 1.0), match_axes=(0, 1))
        rs = r.solve_coulomb(friction.coefficient, slip0=slip0) \
            if isinstance(friction, df.Coulomb) \
            else r.solve_bound(friction.bound * r.area, slip0=slip0)
        slip0 = r.tangential_displacement(rs.u)
        assert sol.report.converged and sol.report.extra["friction"]["disc"]
        c = sol.contact
        assert ref.rel_max_diff(sol.nodal_values(), rs.u) <= 1e-6
        scale = rs.normal_force.max()
        assert np.abs(rs.by_node(c.node, c.tangential_force) - rs.tangential_force).max() \
            <= 1e-6 * scale
    released = sols[-1].contact
    assert np.linalg.norm(released.tangential_force, axis=1).max() > 1e-2 * released.force.max()
    if isinstance(friction, df.Coulomb):
        # the first solve is cold (its first steps loose on discs: ETA_MAX_DISCS); the later
        # ones start warm, where a loose Tresca step gains nothing (drivers/friction.py)
        first = [s.report.extra["friction"]["steps"][0]["inner_rtol"] for s in sols]
        assert first[0] == ETA_MAX_DISCS and max(first[1:]) <= ETA_MAX, first


# --- Cattaneo–Mindlin–Deresiewicz on the Hertz disk-on-block -------------------------------
R, P, EH, NUH, F = 8.0, 10.0, 200.0, 0.3, 0.4
H = 0.1
A_HERTZ = 2.0 * np.sqrt(R * P / (np.pi * EH / (2.0 * (1.0 - NUH**2))))


@pytest.fixture(scope="module")
def disk():
    return df.build_mesh(meshes.hertz2d_full, h_contact=H)


def disk_problem(mesh, p, q):
    """Normal load p and tangential load q on the disk's top, without a moment about the
    contact point (a linear normal part cancels q's), so the pressure stays Hertzian."""
    m = 3.0 * q / (2.0 * R**2)

    def traction(x):
        return ufl.as_vector((q / (2 * R), -p / (2 * R) + m * x[0]))

    return df.ContactProblem(
        mesh, df.Elasticity(EH, NUH, tractions={"load": traction}),
        dirichlet=[df.Dirichlet("bottom")],
        contact=[df.NodeToNode("disk_contact", "block_contact", friction=df.Coulomb(F))],
        decomposition=df.Parts(2))


def half_width(x, inside):
    xi = x[inside]
    return 0.5 * (xi.max() - xi.min()) + 0.5 * H


#: Q/(𝓕P) along the path: P first, then Q up to Q*, back through 0 to −Q*, and up to Q*.
RATIOS = (0.0, 0.3, 0.6, 0.3, 0.0, -0.6, 0.0, 0.6)
P0 = 2.0 * P / (np.pi * A_HERTZ)  # the Hertz peak pressure


def cattaneo(x, r):
    """The tangential traction of Cattaneo–Mindlin at Q = r𝓕P (signed along Q)."""
    c = A_HERTZ * np.sqrt(1.0 - abs(r))
    return np.sign(r) * F * P0 * (np.sqrt(np.maximum(1.0 - x**2 / A_HERTZ**2, 0.0))
                                  - c / A_HERTZ * np.sqrt(np.maximum(1.0 - x**2 / c**2, 0.0)))


def theory(x):
    """The traction at every step of RATIOS: Cattaneo while Q rises from 0, then
    Mindlin–Deresiewicz after each reversal at (Q_r, q_r): q = q_r + 2 q_Cattaneo((Q − Q_r)/2)."""
    up = cattaneo(x, 0.6)
    down = -up
    return [cattaneo(x, r) for r in RATIOS[:3]] + \
        [up + 2 * cattaneo(x, (r - 0.6) / 2) for r in RATIOS[3:6]] + \
        [down + 2 * cattaneo(x, (r + 0.6) / 2) for r in RATIOS[6:]]


@pytest.fixture(scope="module")
def mindlin(disk, tmp_path_factory):
    folder = tmp_path_factory.mktemp("path") if MPI.COMM_WORLD.rank == 0 else None
    folder = MPI.COMM_WORLD.bcast(folder, root=0)
    sols = df.solve_path(lambda t: disk_problem(disk, P, RATIOS[int(t)] * F * P),
                         range(len(RATIOS)), rtol=1e-8, xdmf=folder / "path.xdmf",
                         history=folder / "history.json")
    return sols, folder


def test_locked_in_traction_after_unloading(disk, mindlin):
    sols, _ = mindlin
    for sol, r in zip(sols, RATIOS, strict=True):
        assert sol.report.converged, sol.report.summary()
        assert np.allclose(sol.total_contact_force, [-r * F * P, P], rtol=0, atol=1e-6 * P)
    last = sols[4].contact  # Q* and back to 0
    single = df.solve(disk_problem(disk, P, 0.0), rtol=1e-8).contact
    locked = np.abs(last.tangential_force[:, 0])
    fresh = np.abs(single.tangential_force[:, 0])
    # zero net tangential force both, but the path's tractions are an order larger
    assert abs(last.tangential_force[:, 0].sum()) <= 1e-6 * P
    assert locked.sum() > 10 * fresh.sum()
    assert locked.max() > 0.1 * F * last.force.max()
    # the same contact pressure: the tangential history does not change the normal problem
    assert np.abs(last.force - single.force).max() <= 2e-2 * single.force.max()


def test_stick_zone_while_loading(mindlin):
    """Q rising at constant P: the stick zone c = a sqrt(1 − Q/(𝓕P)) (Cattaneo–Mindlin)."""
    sols, _ = mindlin
    for sol, r in zip(sols[1:3], RATIOS[1:3], strict=True):
        c = sol.contact
        x = c.x[:, 0]
        stick = c.state == df.ContactData.STICK
        c_theory = A_HERTZ * np.sqrt(1.0 - r)
        assert abs(half_width(x, stick) - c_theory) <= 2 * H


def test_unloading_reverses_slip_at_the_edges(mindlin):
    """Mindlin–Deresiewicz: unloading from Q* to Q* − ΔQ, the edges c′ < |x| < a slip back
    (the friction force reverses there) while the centre sticks, c′/a = sqrt(1 − ΔQ/(2𝓕P)).
    """
    sols, _ = mindlin
    loaded, unloaded = sols[2].contact, sols[3].contact
    x = unloaded.x[:, 0]
    stick = unloaded.state == df.ContactData.STICK
    c_prime = A_HERTZ * np.sqrt(1.0 - (RATIOS[2] - RATIOS[3]) / 2.0)
    assert abs(half_width(x, stick) - c_prime) <= 2 * H
    slip = (unloaded.state == df.ContactData.SLIP) & (unloaded.force > 0)
    # at the slipping edges the friction force flips sign from the loaded step
    assert np.all(np.sign(unloaded.tangential_force[slip, 0])
                  == -np.sign(loaded.tangential_force[slip, 0]))


def test_tractions_follow_mindlin_deresiewicz(disk, mindlin):
    """Every step's tangential traction against the theory (RMS over the pressed nodes, in
    units of 𝓕p₀; measured 0.01–0.06 on this mesh of a/h ≈ 10); the cycle Q* → −Q* → Q*
    closes and dissipates energy."""
    sols, _ = mindlin
    x = sols[0].contact.x[:, 0]
    for k, (sol, q) in enumerate(zip(sols, theory(x), strict=True)):
        c = sol.contact
        err = -c.tangential_traction[:, 0] - q  # the traction on the disk opposes Q
        assert np.sqrt(np.mean(err[c.force > 0] ** 2)) <= 0.08 * F * P0, k
    q2, q7 = (sols[k].contact.tangential_traction[:, 0] for k in (2, 7))
    assert np.abs(q7 - q2).max() <= 1e-4 * F * P0
    top = np.unique(disk.facet_groups["load"])
    shift = [sol.nodal_values()[top, 0].mean() for sol in sols]  # the disk's tangential motion
    Q = np.asarray(RATIOS) * F * P
    work = sum(0.5 * (Q[k] + Q[k + 1]) * (shift[k + 1] - shift[k]) for k in range(2, 7))
    assert work > 1e-2 * F * P * abs(shift[2] - shift[0])
    assert abs(shift[7] - shift[2]) <= 1e-4 * abs(shift[2])


def test_path_output(mindlin):
    sols, folder = mindlin
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        steps = json.loads((folder / "history.json").read_text())["steps"]
        assert [s["step"] for s in steps] == list(range(len(RATIOS)))
        for s, sol in zip(steps, sols, strict=True):
            assert s["hessian_mults"] == sol.report.hessian_mults
            assert np.allclose(s["contact_force"], sol.total_contact_force)
            assert s["stick_nodes"] + s["slip_nodes"] == sol.contact.force.size
            pressed = sol.contact.force > 0
            assert s["contact_nodes"] == pressed.sum()
            # the pressed nodes' lumped lengths: about the Hertz width 2a
            assert abs(s["contact_area"] - 2 * A_HERTZ) <= 2 * H
        check_xdmf_series(folder, len(RATIOS))
    comm.barrier()


def test_proportional_loading_does_not_slip(disk):
    """(P, Q) rising together with Q/P < 𝓕 from zero: every pressed node sticks, but for
    the node that enters contact in the step (the discrete contact zone grows by jumps)."""
    ratio = 0.5  # Q = 0.5 𝓕 P
    loads = np.linspace(0.25, 1.0, 4) * P
    sols = df.solve_path(lambda t: disk_problem(disk, loads[int(t)],
                                                ratio * F * loads[int(t)]),
                         range(loads.size), rtol=1e-8, progress=False)
    for prev, sol in zip(sols[:-1], sols[1:], strict=True):
        c, before = sol.contact, prev.contact.force > 0
        slip = (c.state == df.ContactData.SLIP) & (c.force > 0)
        assert not np.any(slip & before), c.x[slip & before]
    single = df.solve(disk_problem(disk, loads[-1], ratio * F * loads[-1]),
                      rtol=1e-8).contact
    assert np.any((single.state == df.ContactData.SLIP) & (single.force > 0))  # Cattaneo



def test_coulomb_start_predicted_along_the_path(disk):
    """Where λ's start is the secant predictor, Coulomb's slip bounds start from the normal
    forces extrapolated alike: the fixed point's first residual is smaller than a scaled
    start's, its Tresca solves are solved to the final accuracy from the first, and each step
    equals the cold solve of the same step (same slip history). The secant first serves the
    fourth case: the tangential rows' right-hand sides (the slip history) enter d from the
    second case on, so the first step of d is off the line of the later ones."""
    qs = (0.3, 0.33, 0.363, 0.3993)  # Q / (𝓕P), 10 % steps
    opts = {"rtol": 1e-8, "method": "tfeti"}
    solver = df.FetiSolver(disk_problem(disk, P, qs[0] * F * P), **opts)
    cold = df.FetiSolver(disk_problem(disk, P, qs[0] * F * P), **opts)
    prev, sols = solver.solve(), []
    for q in qs[1:]:
        solver.update(disk_problem(disk, P, q * F * P), slip_from=prev)
        cold.update(disk_problem(disk, P, q * F * P), slip_from=prev)
        prev = solver.solve()
        assert_same(prev, cold.solve(x0="cold"))
        sols.append(prev.report.extra)
    assert [e["warm_start_secant"] is not None for e in sols] == [False, False, True]
    steps = [e["friction"]["steps"] for e in sols]
    eta_min = min(opts["rtol"], 0.5 * df.Coulomb(F).rtol)
    assert steps[0][0]["inner_rtol"] > eta_min  # the scaled start: solved loosely first
    assert all(s["inner_rtol"] == pytest.approx(eta_min) for s in steps[2])
    assert steps[2][0]["change"] < steps[0][0]["change"]
    solver.destroy()
    cold.destroy()


def smalbe_history(sol) -> list[tuple[int, float]]:
    """(k, M) of each SMALBE outer iteration in the solve's history (kept on rank 0)."""
    comm = MPI.COMM_WORLD
    h = sol.report.extra["history"] if comm.rank == 0 else []
    return comm.bcast([(e["k"], e["M"]) for e in h], root=0)


def test_coulomb_warm_solve_restarts_smalbe_and_keeps_the_scales(disk):
    """A warm Coulomb solve with the Krylov recycling starts SMALBE's M from the options, as a
    cold one does (not from the last Tresca solve's lowered M, which ratcheted down along a
    path; without the recycling it is carried), and takes the last solve's KKT scales before
    its first Tresca step (no recovery for a rescale after it); the result is the cold
    solve's. Under Newton (``u_floor`` > 0) the scales are not carried."""
    qs = (0.3, 0.33, 0.363)
    opts = {"rtol": 1e-8, "method": "tfeti"}
    solver = df.FetiSolver(disk_problem(disk, P, qs[0] * F * P), **opts)
    cold = df.FetiSolver(disk_problem(disk, P, qs[0] * F * P), **opts)
    prev = solver.solve()
    M0 = solver.qp.norm_A  # the options' M, 1.0 ‖A‖
    hist = smalbe_history(prev)
    first = [m for k, m in hist if k == 0]
    assert first and all(m == pytest.approx(M0) for m in first)
    assert hist[-1][1] < M0  # SMALBE-M lowered it
    for q in qs[1:]:
        solver.update(disk_problem(disk, P, q * F * P), slip_from=prev)
        cold.update(disk_problem(disk, P, q * F * P), slip_from=prev)
        prev, ref = solver.solve(), cold.solve(x0="cold")
        assert_same(prev, ref)
        starts = [m for k, m in smalbe_history(prev) if k == 0]
        assert starts and all(m == pytest.approx(M0) for m in starts)
        warm_stop, cold_stop = prev.report.stopping, ref.report.stopping
        assert warm_stop["met"] and cold_stop["met"]
        assert warm_stop["check_kplus_solves"] == warm_stop["checks"] - 1  # no rescale
        assert cold_stop["check_kplus_solves"] == cold_stop["checks"]  # the rescale's
        assert prev.report.kkt["coulomb_bound"] <= df.Coulomb(F).rtol
    solver.u_floor = 1e-12  # as Newton sets it: the rescale is back
    solver.update(disk_problem(disk, P, 0.4 * F * P), slip_from=prev)
    stop = solver.solve().report.stopping
    assert stop["check_kplus_solves"] == stop["checks"]
    solver.destroy()
    cold.destroy()
    # without the recycling M is carried (each restart of the inner solves starts CG afresh)
    plain = df.FetiSolver(disk_problem(disk, P, qs[0] * F * P), mprgp_reuse=0, **opts)
    last = smalbe_history(plain.solve())[-1][1]
    plain.update(disk_problem(disk, P, qs[1] * F * P))
    starts = [m for k, m in smalbe_history(plain.solve()) if k == 0]
    assert last < M0 and starts and all(m == pytest.approx(last) for m in starts)
    plain.destroy()


# --- the [loading] table of a problem file ---------------------------------------------------
@contextmanager
def command_path(root, name: str, capsys, problem_at_of):
    """Run ``problems/<name>.toml`` through the command and the same path through the API
    (``problem_at_of(pf) -> (problem_at, steps)``); the last steps' u agree. Yields the output
    folder, the problem file and the API's Solutions."""
    from cli_helpers import remove_shared, shared_dir

    from dolfinx_feti.cli import main
    from dolfinx_feti.io import problemfile

    out = shared_dir("feti-path-")
    try:
        assert main([str(root / f"problems/{name}.toml"), "-o", str(out), "-q"]) == 0, \
            capsys.readouterr().err
        pf = problemfile.load(root / f"problems/{name}.toml")
        at, steps = problem_at_of(pf)
        sols = df.solve_path(at, range(steps), rtol=1e-8, progress=False)
        u = np.load(out / f"{name}_nodal.npz")["u"]
        assert ref.rel_max_diff(u, sols[-1].nodal_values()) <= 1e-6
        yield out, pf, sols
    finally:
        remove_shared(out)


def load_path_api(pf):
    """``problems/load_path.toml``'s path written with the Python API (the affine traction
    times each factor, by hand)."""
    def at(t):
        f = pf.loading[int(t)]
        return df.ContactProblem(
            pf.mesh, df.Elasticity(200.0, 0.3, tractions={"load": lambda x: ufl.as_vector(
                (f * 0.125, f * (-0.625 + 0.046875 * x[0])))}),
            dirichlet=[df.Dirichlet("bottom")],
            contact=[df.NodeToNode("disk_contact", "block_contact",
                                   friction=df.Coulomb(0.4))],
            decomposition=df.Parts(2))

    return at, len(pf.loading)


def test_problem_file_loading(root, capsys):
    """``problems/load_path.toml`` through the command against the same path written with the
    Python API (the affine traction times each factor, by hand)."""
    from cli_helpers import files_in

    api = load_path_api

    with command_path(root, "load_path", capsys, api) as (out, pf, sols):
        factors = pf.loading
        assert len(factors) >= 4
        report = json.loads((out / "load_path.json").read_text())
        assert report["converged"]
        assert [s["factor"] for s in report["extra"]["loading"]] == list(factors)
        steps = json.loads((out / "load_path_history.json").read_text())["steps"]
        for s, sol in zip(steps, sols, strict=True):
            assert np.allclose(s["contact_force"], sol.total_contact_force, rtol=1e-6,
                               atol=1e-9)
        assert (out / "load_path.xdmf").read_text().count('<Time Value="') == 4 * len(factors)
        assert not any(f.startswith(".") for f in files_in(out))


def load_faults(path, text: str) -> str:
    """The faults a problem file of ``text`` written at ``path`` is refused with."""
    from cli_helpers import write_text

    from dolfinx_feti.io import problemfile

    with pytest.raises(problemfile.ProblemFileError) as e:
        problemfile.load(write_text(path, text))
    return str(e.value)


def test_problem_file_loading_checked(root, tmp_path):
    from cli_helpers import write_text

    from dolfinx_feti.io import problemfile

    text = (root / "problems/load_path.toml").read_text()
    text = text.replace("factors = [0.25, 0.5, 0.75, 1.0, 0.75, 0.5]",
                        'factors = "up"\nsteps = 3')
    folder = MPI.COMM_WORLD.bcast(tmp_path if MPI.COMM_WORLD.rank == 0 else None, root=0)
    bad = write_text(folder / "bad.toml", text)
    with pytest.raises(problemfile.ProblemFileError) as e:
        problemfile.load(bad)
    msg = str(e.value)
    assert "loading.factors: expected an array of load factors" in msg
    assert "loading.steps" in msg  # an unknown key, named
    text = (root / "problems/load_path3d.toml").read_text()
    msg = load_faults(folder / "bad3d.toml", text.replace(
        "values.top = [[0.0, 0.0, -0.02], [0.005, 0.0, -0.02],",
        "factors = [1.0, 1.0]\nvalues.lid = [[0.0]]\n"
        "values.bottom = [[0.0, 0.0], [0.005, 0.0, -0.02],"))
    assert "loading.values.lid: not the group of a [[dirichlet]] condition" in msg
    assert "loading.values.bottom[0]: expected one number or [3]" in msg


def blocks_path_api(pf, mus=None):
    """``problems/load_path3d.toml``'s path written with the Python API: the top's value per
    step, Coulomb's coefficient per step (0.3 throughout if None)."""
    tops = pf.loading_values["top"]

    def at(t):
        mu = 0.3 if mus is None else mus[int(t)]
        return df.ContactProblem(
            pf.mesh, df.Elasticity(1.0, 0.3),
            dirichlet=[df.Dirichlet("bottom"), df.Dirichlet("top", value=tops[int(t)])],
            contact=[df.NodeToNode("contact_upper", "contact_lower",
                                   friction=df.Coulomb(mu))],
            decomposition=df.Parts(4))

    return at, len(tops)


def test_problem_file_values_path(root, capsys):
    """``problems/load_path3d.toml`` ([loading] values: the top's displacement per step)
    through the command against the same path written with the Python API."""

    def api(pf):
        assert len(pf.loading) == len(pf.loading_values["top"]) and set(pf.loading) == {1.0}
        return blocks_path_api(pf)

    with command_path(root, "load_path3d", capsys, api) as (out, _, sols):
        steps = json.loads((out / "load_path3d_history.json").read_text())["steps"]
        assert [s["hessian_mults"] for s in steps] == [s.report.hessian_mults for s in sols]
        # back at the first shift, with tractions locked in: not the first state
        assert ref.rel_max_diff(sols[-1].nodal_values(), sols[0].nodal_values()) > 1e-3


def test_problem_file_translations_path(root, capsys):
    """``problems/ironing_path.toml`` ([loading] translations: a rigid die pressed into a
    neo-Hookean block and slid) through the command against the same path written with the
    Python API (the die at each position, its RigidMotion the translation); while it slides
    the die drags the block's surface: the tangential force on the block points along the
    motion and stays below 𝓕 times the normal one (every node at |λ_T| ≤ 𝓕λ_N)."""
    from ironing_path import die_at

    from dolfinx_feti.io.meshes_rubber import ironing_block

    def api(pf):
        moves = pf.loading_translations["top"]
        mesh = df.build_mesh(ironing_block, h_top=0.25, h_far=0.75)
        return (lambda t: die_at(mesh, moves[int(t)])), len(moves)

    with command_path(root, "ironing_path", capsys, api) as (out, pf, sols):
        moves = pf.loading_translations["top"]
        assert set(pf.loading) == {1.0} and len(moves) == 5
        history = json.loads((out / "ironing_path_history.json").read_text())["steps"]
        for s, sol in zip(history, sols, strict=True):
            assert np.allclose(s["contact_force"], sol.total_contact_force, rtol=1e-6,
                               atol=1e-9)
        for k in (2, 3, 4):  # sliding to +x
            fx, fy = sols[k].total_contact_force
            assert fy < 0 and 0.2 * 0.3 * -fy < fx <= 0.3 * -fy * (1 + 1e-6)


def test_problem_file_translations_checked(root, tmp_path):
    text = (root / "problems/ironing_path.toml").read_text()
    folder = MPI.COMM_WORLD.bcast(tmp_path if MPI.COMM_WORLD.rank == 0 else None, root=0)
    msg = load_faults(folder / "bad.toml", text.replace(
        "translations.top = [[0.0, -0.05],",
        "translations.bottom = [[0.0, 0.0]]\nvalues.bottom = [0.0, 0.0]\n"
        "translations.top = [[0.0, -0.05, 0.0],"))
    assert "loading.translations.bottom: not the group of a [[contact]] condition with a " \
        "rigid obstacle (those are ['top'])" in msg
    assert "loading.translations.top[0]: expected an array of 2 coordinates" in msg
    assert "loading.translations.top: a sphere with friction cannot move in small " \
        "deformation" in load_faults(folder / "small.toml", text.replace(
            'type = "neo-hookean"', 'type = "elasticity"'))


def test_problem_file_friction_per_step(root, tmp_path, capsys):
    """``[loading] friction``: Coulomb's coefficient per step from the command line (the 3D
    blocks pressed and sheared, the friction lowered as they slide) equals the same path with
    the coefficients set by hand in Python, and differs from the path at a constant 0.3; a
    group without friction and a negative value are refused by name."""
    from cli_helpers import remove_shared, shared_dir, write_text

    from dolfinx_feti.cli import main
    from dolfinx_feti.io import problemfile

    text = (root / "problems/load_path3d.toml").read_text()
    start = text.index("values.top = [")
    end = text.index("\n\n", start)
    mus = [0.3, 0.3, 0.1, 0.1]
    text = text[:start] + (
        "values.top = [[0.0, 0.0, -0.02], [0.01, 0.0, -0.02], [0.02, 0.0, -0.02], "
        f"[0.03, 0.0, -0.02]]\nfriction.contact_upper = {mus}") + text[end:]
    folder = MPI.COMM_WORLD.bcast(tmp_path if MPI.COMM_WORLD.rank == 0 else None, root=0)
    path = write_text(folder / "load_path3d.toml", text)
    pf = problemfile.load(path)
    assert pf.loading_friction == {"contact_upper": tuple(mus)}
    assert [pf.problem_at(k).contact[0].friction.coefficient for k in range(4)] == mus
    out = shared_dir("feti-friction-")
    try:
        assert main([str(path), "-o", str(out), "-q"]) == 0, capsys.readouterr().err
        u = np.load(out / "load_path3d_nodal.npz")["u"]
    finally:
        remove_shared(out)
    at, steps = blocks_path_api(pf, mus)
    sols = df.solve_path(at, range(steps), rtol=1e-8, progress=False)
    assert ref.rel_max_diff(u, sols[-1].nodal_values()) <= 1e-6
    at, steps = blocks_path_api(pf)  # 0.3 throughout: less slip, another last state
    fixed = df.solve_path(at, range(steps), rtol=1e-8, progress=False)
    assert ref.rel_max_diff(fixed[-1].nodal_values(), sols[-1].nodal_values()) > 1e-3
    msg = load_faults(folder / "bad.toml", text.replace(
        f"friction.contact_upper = {mus}",
        "friction.contact_lower = [0.1]\nfriction.contact_upper = [0.3, -0.1, 0, 0]"))
    assert "loading.friction.contact_lower: not the (first) group of a [[contact]] " \
        "condition with friction (those are ['contact_upper'])" in msg
    assert "loading.friction.contact_upper[1]: expected a friction value >= 0" in msg
