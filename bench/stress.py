"""The stress suite of issue 7 at full size: every case, what happens, and how to reproduce it.

Runs the cases of ``tests/support/stress_cases.py`` (which the tests run at reduced sizes) and
writes
the table to ``output/bench/stress.md``; with ``--docs`` also into ``docs/robustness.md``
(between the markers ``<!-- stress-table -->`` and ``<!-- /stress-table -->``, one section
per group: a run with ``-k`` replaces only its groups' sections).

    python bench/stress.py                 # everything (a few minutes on one core)
    python bench/stress.py -k jumps        # the groups or cases whose key contains "jumps"
    python bench/stress.py --docs          # also update docs/robustness.md
    mpirun -n 2 python bench/stress.py -k faults --docs   # the faults with 2 ranks

Every row says what happened: converged (outer / inner iterations, F-multiplications, the
largest KKT residual and the measured difference to the reference), not converged (with the
reason), or the error raised (its type and message).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np
import ufl
from mpi4py import MPI

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "support"))
import stress_cases as sc  # noqa: E402

import dolfinx_feti as df  # noqa: E402
from dolfinx_feti.io import meshes  # noqa: E402

COMM = MPI.COMM_WORLD
ROWS: list[tuple[str, str, str, str]] = []  # (group, case, outcome, key)
CYLINDER = df.Sphere((0.5, -10.0), 10.0)


def row(group: str, key: str, label: str, outcome: str) -> None:
    ROWS.append((group, label, outcome, key))
    if COMM.rank == 0:
        print(f"[{key}] {label}: {outcome}", flush=True)


def solved(group, key, case: sc.Case, extra: str = "") -> sc.Case:
    row(group, key, case.name, case.outcome() + extra + f" ({case.seconds:.1f} s)")
    return case


def error_of(fn) -> str:
    try:
        fn()
    except Exception as e:  # noqa: BLE001 - the message is the result
        msg = str(e)
        return f"{type(e).__name__}: {msg[:200]}{'…' if len(msg) > 200 else ''}"
    return "**accepted** (no error)"


# ------------------------------------------------------------------------------------------
# Groups of cases
# ------------------------------------------------------------------------------------------


def jumps() -> None:
    """Composite with stiff inclusions, E ratio 1 … 1e6, decompositions × preconditioners."""
    g = "Coefficient jumps (composite, h = 0.02, 2×2 inclusions; obstacle: rigid cylinder)"
    mesh = df.build_mesh(sc.composite, 0.02, 2)
    for ratio in (1.0, 1e2, 1e4, 1e6):
        ref = sc.composite_reference(mesh, ratio)
        for dec in ("tags", "grid"):
            for pc, scaling in (("none", "multiplicity"), ("lumped", "multiplicity"),
                                ("dirichlet", "multiplicity"), ("lumped", "stiffness"),
                                ("dirichlet", "stiffness")):
                case = sc.coefficient_jump(mesh, ratio, dec, pc, reference=ref,
                                           preconditioner_scaling=scaling)
                if scaling == "stiffness":
                    case.name += " (stiffness scaling)"
                solved(g, "jumps", case)
    for rtol in (1e-12, 1e-14):
        solved(g, "jumps", sc.coefficient_jump(mesh, 1e6, "tags", rtol=rtol),
               f", rtol {rtol:.0e}")


def incompressible() -> None:
    """ν → 0.5: the solver on the discrete problem, and P1 locking against Hertz."""
    g = "Near-incompressibility"
    mesh = df.build_mesh(sc.composite, 0.02, 2)
    for nu in (0.3, 0.45, 0.49, 0.499):
        ref = sc.composite_reference(mesh, 1.0, nu)
        case = sc.run(f"homogeneous block on a cylinder, ν = {nu}, 3×3 grid",
                      lambda nu=nu: sc.composite_problem(mesh, 1.0, sc.DECOMPOSITIONS["grid"],
                                                         nu=nu), rtol=1e-8)
        if case.solution is not None:
            case.numbers[sc.VS_MONO] = sc.rel_diff(case.solution.nodal_values(), ref)
        solved(g, "incompressible", case)
    for h in (0.1, 0.05, 0.025):
        hm = df.build_mesh(meshes.hertz2d, h_contact=h)
        for nu in (0.3, 0.45, 0.49, 0.499):
            case = sc.run(f"Hertz h = {h}, ν = {nu}", lambda hm=hm, nu=nu: sc.hertz_problem(
                hm, nu=nu), rtol=1e-8)
            if case.solution is not None:
                case.numbers["p_max/p0 − 1 (locking)"] = \
                    sc.hertz_peak(case.solution) / sc.hertz_p0(nu) - 1.0
            solved(g, "incompressible", case)


def scaling() -> None:
    """Large H/h and many floating subdomains (B1 and elasticity)."""
    g = "Large H/h, many floating subdomains"
    for n, H in ((32, 0.5), (64, 0.5), (128, 0.5), (256, 0.5), (128, None), (64, 0.25),
                 (64, 0.125), (64, 1 / 16), (128, 1 / 16)):
        mesh = df.build_mesh(meshes.membranes, n)
        solved(g, "scaling", sc.b1_case(mesh, n, H, rtol=1e-6))
    for n in (32, 64, 128, 256):  # 2×1 block on a cylinder, H = 1/2: H/h = n/2
        mesh = df.build_mesh(sc.rectangle, 2.0, 1.0, n)
        sphere = df.Sphere((1.0, -10.0), 10.0)
        case = sc.run(f"elastic block n={n}, H/h={n // 2}, 8 subdomains",
                      lambda mesh=mesh, sphere=sphere: sc.block_on_plane(
                          mesh, obstacles=[df.RigidObstacle("block_bottom", sphere)],
                          decomposition=df.ByFunction(sc.grid_labels(0.5))),
                      rtol=1e-6)
        solved(g, "scaling", case)
    mesh = df.build_mesh(sc.rectangle, 1.0, 1.0, 64)
    solved(g, "scaling", sc.run("elastic square n=64, H/h=4, 256 subdomains", lambda: \
        sc.block_on_plane(mesh, obstacles=[df.RigidObstacle("block_bottom", CYLINDER)],
                          decomposition=df.ByFunction(sc.grid_labels(1 / 16))), rtol=1e-8))
    # SMALBE's outer iterations against the number of subdomains (finding 9)
    mesh = df.build_mesh(sc.rectangle, 2.0, 1.0, 16)
    for H in (0.5, 0.25, 0.125, 1 / 16):
        for opts in ({"max_outer": 100}, {}, {"smalbe_rho": 10.0}):
            name = (f"2×1 block n=16 on an off-centre cylinder, {round(2 / H / H)} subdomains, "
                    + (", ".join(f"{k} {v:g}" for k, v in opts.items()) or "defaults"))
            solved(g, "scaling", sc.run(name, lambda H=H: sc.block_on_plane(
                mesh, obstacles=[df.RigidObstacle("block_bottom", CYLINDER)],
                decomposition=df.ByFunction(sc.grid_labels(H))), rtol=1e-8, **opts))


def shapes() -> None:
    """Thin and badly shaped subdomains, pieces touching at a vertex."""
    g = "Thin, badly shaped, vertex-connected subdomains (unit square, n = 50, on a cylinder)"
    mesh = df.build_mesh(sc.rectangle, 1.0, 1.0, 50)
    ref = sc.block_reference(mesh, obstacles=[("block_bottom", CYLINDER)])

    def checker(x):
        return ((np.floor(5 * x[:, 0]) + np.floor(5 * x[:, 1])) % 2).astype(np.int64)

    decs = {"one subdomain": df.ByTags(), "5×5 squares": df.ByFunction(sc.grid_labels(0.2)),
            "50 vertical strips 1:50": df.ByFunction(sc.grid_labels((0.02, 10.0))),
            "25 horizontal strips 1:25": df.ByFunction(sc.grid_labels((10.0, 0.04))),
            "checkerboard labels (split at vertices)": df.ByFunction(checker),
            "PT-Scotch, 25 parts": df.Parts(25, "ptscotch")}
    for name, dec in decs.items():
        for pc in ("none", "dirichlet"):
            case = sc.run(f"{name}, {pc}", lambda dec=dec: sc.block_on_plane(
                mesh, obstacles=[df.RigidObstacle("block_bottom", CYLINDER)], decomposition=dec),
                rtol=1e-8, preconditioner=pc)
            if case.solution is not None:
                case.numbers["subdomains"] = case.report.sizes["subdomains"]
                case.numbers[sc.VS_MONO] = sc.rel_diff(case.solution.nodal_values(), ref)
            solved(g, "shapes", case)
    corner = df.build_mesh(sc.corner_squares, 16, True)
    plane = df.Plane((0.0, 1.0), (0.0, 1.0))
    t = (0.0, -0.01)
    ref = sc.monolithic(corner, 1.0, 0.3, dirichlet=[("bottom_a", None, [0.0, 0.0])],
                        obstacles=[("bottom_b", plane)], tractions={"top_b": t})
    for name, dec in (("ByTags", df.ByTags()), ("Parts(4)", df.Parts(4))):
        case = sc.run(f"one body of two squares sharing one corner node, {name}",
                      lambda dec=dec: df.ContactProblem(
                          corner, sc.ConstElasticity(1.0, 0.3, tractions={"top_b": t}),
                          dirichlet=[df.Dirichlet("bottom_a")],
                          contact=[df.RigidObstacle("bottom_b", plane)], decomposition=dec),
                      rtol=1e-10)
        if case.solution is not None:
            case.numbers["subdomains"] = case.report.sizes["subdomains"]
            case.numbers[sc.VS_MONO] = sc.rel_diff(case.solution.nodal_values(), ref)
        solved(g, "shapes", case)


def gluing() -> None:
    """Gluing schemes at cross points; redundant contact rows."""
    g = "Gluing at cross points, redundant contact rows (2×1 block, n = 32)"
    mesh = df.build_mesh(sc.rectangle, 2.0, 1.0, 32)
    sphere = df.Sphere((1.0, -10.0), 10.0)
    ref = sc.block_reference(mesh, obstacles=[("block_bottom", sphere)])
    for gl in ("orthonormal", "redundant", "nonredundant"):
        for pc in ("none", "dirichlet"):
            case = sc.run(f"8×4 grid, gluing {gl}, {pc}", lambda gl=gl, pc=pc: sc.block_on_plane(
                mesh, obstacles=[df.RigidObstacle("block_bottom", sphere)],
                decomposition=df.ByFunction(sc.grid_labels(0.25)), gluing=gl),
                rtol=1e-10, preconditioner=pc)
            if case.solution is not None:
                case.numbers["dual"] = case.report.sizes["dual"]
                case.numbers[sc.VS_MONO] = sc.rel_diff(case.solution.nodal_values(), ref)
            solved(g, "gluing", case)
    plane = df.Plane((0.0, 0.0), (0.0, 1.0))
    wall = df.Plane((0.0, 0.0), (1.0, 0.0))
    grid = df.ByFunction(sc.grid_labels(0.5))
    base = sc.run("one plane", lambda: sc.block_on_plane(mesh, load=(0.0, -0.1),
                                                         decomposition=grid), rtol=1e-10)
    for name, obstacles in (
            ("the same plane twice (duplicate rows)", [plane, plane]),
            ("a plane and a tangent cylinder R = 1e3", [plane, df.Sphere((1.0, -1e3), 1e3)])):
        case = sc.run(name, lambda obstacles=obstacles: sc.block_on_plane(
            mesh, load=(0.0, -0.1), decomposition=grid,
            obstacles=[df.RigidObstacle("block_bottom", o) for o in obstacles]), rtol=1e-10)
        if case.solution is not None:
            case.numbers["‖u − u_one plane‖/‖u‖"] = sc.rel_diff(case.solution.nodal_values(),
                                                               base.solution.nodal_values())
        solved(g, "gluing", case)
    ref = sc.monolithic(mesh, 1.0, 0.3, obstacles=[("block_bottom", plane), ("left", wall)],
                        tractions={"top": (-0.05, -0.1)})
    case = sc.run("pushed into a rigid corner: node (0,0) on floor and wall",
                  lambda: sc.block_on_plane(mesh, load=(-0.05, -0.1), sides=False,
                                            decomposition=grid,
                                            obstacles=[df.RigidObstacle("block_bottom", plane),
                                                       df.RigidObstacle("left", wall)]),
                  rtol=1e-10)
    if case.solution is not None:
        case.numbers[sc.VS_MONO] = sc.rel_diff(case.solution.nodal_values(), ref)
    solved(g, "gluing", case)


def gaps() -> None:
    """Gaps, penetration, no load, loads without a solution."""
    g = "Gaps and loads (2×1 block, n = 32, 4×2 grid, on the plane y = −gap)"
    mesh = df.build_mesh(sc.rectangle, 2.0, 1.0, 32)
    grid = df.ByFunction(sc.grid_labels(0.5))
    for gap in (0.0, 1e-12, 1e-6, 10.0, -1e-3):
        ref = sc.block_reference(mesh, gap=gap, load=(0.0, -0.1))
        case = sc.run(f"gap {gap:g}" + (" (initial penetration)" if gap < 0 else ""),
                      lambda gap=gap: sc.block_on_plane(mesh, gap=gap, load=(0.0, -0.1),
                                                        decomposition=grid), rtol=1e-10)
        if case.solution is not None:
            case.numbers[sc.VS_MONO] = sc.rel_diff(case.solution.nodal_values(), ref)
        solved(g, "gaps", case)
    for far in (1e3, 1e6):
        ref = sc.monolithic(mesh, 1.0, 0.3, dirichlet=[("block_sides", None, [0.0, 0.0])],
                            obstacles=[("block_bottom", df.Plane((0.0, -far), (0.0, 1.0)))],
                            tractions={"top": (0.0, -0.01)})
        case = sc.run(f"clamped block, obstacle {far:g} away (‖u‖∞ = 0.021), rtol 1e-10",
                      lambda far=far: df.ContactProblem(
                          mesh, sc.ConstElasticity(1.0, 0.3, tractions={"top": (0.0, -0.01)}),
                          dirichlet=[df.Dirichlet("block_sides")],
                          contact=[df.RigidObstacle("block_bottom",
                                                    df.Plane((0.0, -far), (0.0, 1.0)))],
                          decomposition=grid), rtol=1e-10)
        if case.solution is not None:
            case.numbers[sc.VS_MONO] = sc.rel_diff(case.solution.nodal_values(), ref)
            case.numbers["warning"] = "yes" if case.report.warnings else "no"
        solved(g, "gaps", case)
    for sides in (True, False):
        how = "fixed in x" if sides else "free"
        solved(g, "gaps", sc.run(f"resting on the plane, no load, sides {how}",
                                 lambda sides=sides: sc.block_on_plane(
                                     mesh, load=(0.0, 0.0), sides=sides, decomposition=grid)))
    solved(g, "gaps", sc.run("tangential + normal load, frictionless, no side support",
                             lambda: sc.block_on_plane(mesh, load=(0.01, -0.1), sides=False,
                                                       decomposition=grid)))
    solved(g, "gaps", sc.run("pulled up off its only support", lambda: sc.block_on_plane(
        mesh, load=(0.0, 0.1), decomposition=grid), rtol=1e-8))


def units() -> None:
    """The Hertz problem in other units; tolerances."""
    g = "Units and tolerances (2D Hertz, h = 0.05, Parts(2))"
    mesh = df.build_mesh(meshes.hertz2d, h_contact=0.05)
    base = sc.run("base units", lambda: sc.hertz_problem(mesh), rtol=1e-10)
    solved(g, "units", base)
    for length, stress in ((1e-3, 1e6), (1e3, 1e-6), (1e-3, 1.0), (1.0, 1e9), (1e-6, 1e9),
                           (1e6, 1e-9)):
        solved(g, "units", sc.unit_change(mesh, length, stress, base.solution))
    for rtol in (1e-6, 1e-8, 1e-10, 1e-12, 1e-14, 1e-16):
        case = sc.run(f"rtol {rtol:.0e}", lambda: sc.hertz_problem(mesh), rtol=rtol)
        case.numbers["‖gᴾ‖/‖b‖"] = case.report.gP_rel
        case.numbers["‖Gλ−e‖/‖e‖"] = case.report.G_lambda
        solved(g, "units", case)


def precond() -> None:
    """The Dirichlet preconditioner with a singular interior block."""
    g = "Dirichlet preconditioner, a subdomain that no row touches (B1 n = 8 without contact)"
    membranes = df.read_gmsh(ROOT / "meshes/membranes_8.msh")

    def left_only(x):
        return ufl.conditional(ufl.lt(x[0], 1.0), -1.0, 0.0)

    for factor in ("cholmod", "mumps", "petsc"):
        case = sc.run(f"floating unloaded right membrane, factor {factor}",
                      lambda: df.ContactProblem(membranes, df.Poisson(source=left_only),
                                                dirichlet=[df.Dirichlet("dirichlet")]),
                      rtol=1e-10, preconditioner="dirichlet", factor=factor)
        solved(g, "precond", case)


def hostile() -> None:
    """Hostile input: the error each raises (before any solve)."""
    g = "Hostile input (each refused before any solve; nothing written)"
    x, cells = sc.grid_arrays(3, 3)

    def read(x, cells, bodies=None, facets=None):
        return df.build_mesh(sc.from_arrays, x, cells,
                             bodies or {"plate": np.arange(len(cells))}, facets or {})

    inverted = x.copy()
    inverted[5] = (2.3, 1.6)
    row(g, "hostile", "inverted cell (a node moved across an opposite edge)",
        error_of(lambda: read(inverted, cells)))
    xs = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.0, 1.0]])
    row(g, "hostile", "degenerate cell (three collinear nodes)",
        error_of(lambda: read(xs, np.array([[0, 1, 2], [0, 1, 3]]))))
    xo = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1.0], [0.5, -1.0], [0.3, 2.0]])
    row(g, "hostile", "three cells on one facet (overlapping cells)",
        error_of(lambda: read(xo, np.array([[0, 1, 2], [0, 1, 3], [0, 1, 4]]))))
    xn = x.copy()
    xn[9] = (np.nan, 2.0)
    row(g, "hostile", "NaN node coordinate", error_of(lambda: read(xn, cells)))
    row(g, "hostile", "empty body group", error_of(lambda: read(
        x, cells, {"plate": np.arange(len(cells)), "ghost": []})))
    forms = sc.ConstElasticity(1.0, 0.3, tractions={"right": (0.1, 0.0)})
    for label, args in (("duplicate nodes: two squares in one body, not fragmented", (4, False)),
                        ("hanging nodes: the same, meshed 4 and 6 per unit", (4, False, 6))):
        m = df.build_mesh(sc.two_squares_one_body, *args)
        row(g, "hostile", label, error_of(lambda m=m: df.ContactProblem(
            m, forms, dirichlet=[df.Dirichlet("left")])))
    m = df.build_mesh(sc.two_squares_one_body, 4, False)
    bypass = dataclasses.replace(m)  # the same mesh: without the check it would solve …
    from dolfinx_feti.mesh import checks

    saved = checks.check_conforming
    checks.check_conforming = lambda *a, **k: None
    import dolfinx_feti.problem.contact_problem as problem_module

    problem_module.check_conforming = checks.check_conforming
    try:
        both = df.ContactProblem(bypass, sc.ConstElasticity(1.0, 0.3), dirichlet=[
            df.Dirichlet("left"), df.Dirichlet("right", (0.1, 0.0))])
        sol = df.solve(both, rtol=1e-10)
        x1 = np.isclose(bypass.x[:, 0], 1.0)
        jump = float(np.ptp(sol.nodal_values()[x1, 0]))
        row(g, "hostile", "… the same without the check, both ends clamped (the old behaviour)",
            f"solved, {sol.report.sizes['subdomains']} subdomains: a crack at x = 1 (u_x jumps by "
            f"{jump:.3f} there, 0 for the glued plate) — a silently wrong answer")
    finally:
        checks.check_conforming = saved
        problem_module.check_conforming = saved
    comp = df.build_mesh(sc.composite, 0.2, 1)
    row(g, "hostile", "contact surface on the glued matrix/inclusion interface",
        error_of(lambda: df.ContactProblem(comp, sc.ConstElasticity(1.0, 0.3),
                                           dirichlet=[df.Dirichlet("top")], contact=[
                                               df.RigidObstacle("interface",
                                                                df.Plane((0, 0), (0, 1)))])))
    block = df.build_mesh(sc.rectangle, 1.0, 1.0, 4)
    row(g, "hostile", "body inside a solid Sphere obstacle (normals the wrong way)",
        error_of(lambda: df.solve(sc.block_on_plane(block, obstacles=[
            df.RigidObstacle("block_bottom", df.Sphere((0.5, 0.5), 1.0))]))))
    membranes = df.read_gmsh(ROOT / "meshes/membranes_8.msh")
    row(g, "hostile", "node-to-node surfaces facing the same way (tests/robustness/test_errors.py)",
        error_of(lambda: df.solve(df.ContactProblem(
            membranes, sc.ConstElasticity(1.0, 0.3), dirichlet=[df.Dirichlet("contact_left")],
            contact=[df.NodeToNode("contact_right", "dirichlet")]))))
    for label, obstacle in (("Sphere radius NaN", df.Sphere((0.5, -1.0), np.nan)),
                            ("Plane point Inf", df.Plane((0.0, np.inf), (0.0, 1.0)))):
        row(g, "hostile", label, error_of(lambda obstacle=obstacle: df.solve(
            sc.block_on_plane(block, obstacles=[df.RigidObstacle("block_bottom", obstacle)]))))
    row(g, "hostile", "Dirichlet value Inf", error_of(lambda: df.solve(df.ContactProblem(
        block, sc.ConstElasticity(1.0, 0.3),
        dirichlet=[df.Dirichlet("block_sides", (np.inf, 0.0))]))))


def faults() -> None:
    """A fault on one rank's subdomains (run under mpirun -n 2: each body on its own rank)."""
    g = f"Faults on one rank ({COMM.size} rank(s))"
    membranes = df.read_gmsh(ROOT / "meshes/membranes_8.msh")

    def pushed(forms):
        return df.ContactProblem(membranes, forms, dirichlet=[df.Dirichlet("dirichlet")],
                                 contact=[df.NodeToNode("contact_right", "contact_left")])

    for factor in ("cholmod", "mumps"):
        row(g, "faults", f"E = 0 in body 'right' (forms callback), factor {factor}",
            error_of(lambda factor=factor: df.solve(pushed(sc.ConstElasticity(
                1.0, 0.3, zero_E=("right",))), factor=factor)) + " (rank 0's message)")

    class Boom(sc.ConstElasticity):
        def __call__(self, V, sub):
            if sub.body == "right":
                raise RuntimeError("boom: no forms for the right body")
            return super().__call__(V, sub)

    row(g, "faults", "forms callback raising for body 'right'",
        error_of(lambda: df.solve(pushed(Boom(1.0, 0.3)))) + " (rank 0's message)")
    block = df.build_mesh(sc.rectangle, 1.0, 1.0, 8)
    case = sc.run("one subdomain on all ranks (ranks without subdomains)",
                  lambda: sc.block_on_plane(block), rtol=1e-8)
    solved(g, "faults", case)


GROUPS = {"jumps": jumps, "incompressible": incompressible, "scaling": scaling,
          "shapes": shapes, "gluing": gluing, "gaps": gaps, "units": units,
          "precond": precond, "hostile": hostile, "faults": faults}


def sections() -> dict[str, str]:
    """The table of each group that ran, as markdown between markers."""
    out: dict[str, list[str]] = {}
    for g, label, outcome, key in ROWS:
        if key not in out:
            cmd = f"`python bench/stress.py -k {key}`"
            if key == "faults":
                cmd = f"`mpirun -n {COMM.size} python bench/stress.py -k {key}`"
            out[key] = [f"<!-- group:{key} -->", f"**{g}** — {cmd}", "",
                        "| case | what happens |", "|---|---|"]
        out[key].append(f"| {label.replace('|', chr(92) + '|')} | "
                        f"{outcome.replace('|', chr(92) + '|')} |")
    return {k: "\n".join(v + [f"<!-- /group:{k} -->", ""]) for k, v in out.items()}


def merge(body: str, new: dict[str, str]) -> str:
    """Replace the groups' sections in the doc's table region (append the missing ones)."""
    start, end = "<!-- stress-table -->\n", "<!-- /stress-table -->"
    i, j = body.index(start) + len(start), body.index(end)
    region = body[i:j]
    for key, text in new.items():
        a, b = f"<!-- group:{key} -->", f"<!-- /group:{key} -->\n"
        if a in region:
            p, q = region.index(a), region.index(b) + len(b)
            region = region[:p] + text + region[q:]
        else:
            region = region + text
    return body[:i] + region + body[j:]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-k", default="", help="run the groups whose name contains this")
    parser.add_argument("--docs", action="store_true",
                        help="update the groups' tables in docs/robustness.md")
    args, _ = parser.parse_known_args()
    t0 = time.perf_counter()
    for name, fn in GROUPS.items():
        if args.k in name:
            fn()
    new = sections()
    if COMM.rank == 0:
        out = ROOT / "output/bench/stress.md"
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text("\n".join(new.values()))
        print(f"wrote {out} ({time.perf_counter() - t0:.0f} s)")
        if args.docs:
            doc = ROOT / "docs/robustness.md"
            doc.write_text(merge(doc.read_text(), new))
            print(f"updated {doc}")


if __name__ == "__main__":
    main()
