"""Problem files: the malformed-file table (each fault named with the file, the key and what
was expected; non-zero exit; nothing written), all faults at once, the schema pieces (grid,
per-body source, affine traction, mesh generators), von Mises, the arc length, the docs."""

from __future__ import annotations

import re

import numpy as np
import pytest
import ufl
from cli_helpers import (
    COMM,
    HAS_FRICTION,
    MESHES,
    PROBLEMS,
    ROOT,
    files_in,
    remove_shared,
    shared_dir,
    write_text,
)

import dolfinx_feti as df
from dolfinx_feti import compat
from dolfinx_feti.cli import main
from dolfinx_feti.io import problemfile as pfile
from dolfinx_feti.io import schema
from dolfinx_feti.results.postprocess import surface_arclength, von_mises


@pytest.fixture(scope="module")
def folder():
    d = shared_dir("feti-problemfile-")
    yield d
    remove_shared(d)


HERTZ = (MESHES / "hertz2d.msh").as_posix()

#: A valid problem (2D Hertz, coarse tolerance); each malformed case edits it.
BASE = f'''
mesh = "{HERTZ}"

[model]
type = "elasticity"
E = 200.0
nu = 0.3
tractions = {{ load = [0.0, -0.625] }}

[[dirichlet]]
group = "bottom"

[[dirichlet]]
group = "symmetry"
components = [0]

[[contact]]
type = "node_to_node"
slave = "disk_contact"
master = "block_contact"

[decomposition]
type = "parts"
n = 2

[solver]
rtol = 1e-6

[output]
xdmf = "out.xdmf"
'''


def edit(*pairs: tuple[str, str]) -> str:
    text = BASE
    for old, new in pairs:
        assert old in text, old
        text = text.replace(old, new, 1)
    return text


#: id → (problem file text, extra command-line arguments, [(key, words of the message)]).
MALFORMED = {
    "syntax error": (edit(("nu = 0.3", "nu = 0.3 0.4")), [],
                     [("", "TOML syntax error")]),
    "unterminated string": (edit(('type = "parts"', 'type = "parts')), [],
                            [("", "TOML syntax error")]),
    "unknown top-level key": ("material = 1\n" + BASE, [],
                              [("material", "unknown key; expected one of: mesh")]),
    "unknown key with a hint": (edit(("nu = 0.3", "nuu = 0.3")), [],
                                [("model.nuu", "did you mean 'nu'"), ("model.nu", "required")]),
    "bad type": (edit(("E = 200.0", 'E = "steel"')), [],
                 [("model.E", "expected a number > 0, or a table of one per body, got a string")]),
    "missing mesh file": (edit((HERTZ, "no/such/mesh.msh")), [],
                          [("mesh", "mesh file not found")]),
    "mesh is not a path": (edit((f'mesh = "{HERTZ}"', "mesh = 3")), [],
                           [("mesh", "expected the path of a gmsh .msh file")]),
    "unknown tag": (edit(('group = "bottom"', 'group = "botom"')), [],
                    [("dirichlet[0].group", "unknown boundary group 'botom' (did you mean "
                                            "'bottom'?)")]),
    "a body used as a boundary group": (edit(('master = "block_contact"', 'master = "block"')),
                                        [], [("contact[0].master", "'block' is a body")]),
    "contact pair with itself": (edit(('master = "block_contact"', 'master = "disk_contact"')),
                                 [], [("contact[0]", "with itself")]),
    "negative gap": (edit(('master = "block_contact"', 'master = "block_contact"\ngap = -0.1')),
                     [], [("contact[0].gap", "expected a number >= 0")]),
    "NaN value": (edit(("E = 200.0", "E = nan")), [], [("model.E", "finite")]),
    "incompressible nu": (edit(("nu = 0.3", "nu = 0.5")), [],
                          [("model.nu", "expected a number in (-1, 0.5), or a table of one "
                                        "per body, got 0.5")]),
    "E <= 0": (edit(("E = 200.0", "E = -200.0")), [], [("model.E", "expected a number > 0")]),
    "unknown body": (edit(("E = 200.0", "E = { disk = 200.0, blok = 100.0 }")), [],
                     [("model.E.blok", "unknown body"), ("model.E", "no value for bodies "
                                                                    "['block']")]),
    "traction of the wrong dimension": (edit(("[0.0, -0.625]", "[0.0, 0.0, -0.625]")), [],
                                        [("model.tractions.load", "expected an array of 2 "
                                                                  "numbers")]),
    "component out of range": (edit(("components = [0]", "components = [2]")), [],
                               [("dirichlet[1].components", "expected indices in 0..1")]),
    "missing required key": (edit(('master = "block_contact"\n', "")), [],
                             [("contact[0].master", "missing")]),
    "dirichlet as a table": (edit(('[[dirichlet]]\ngroup = "bottom"', '[dirichlet]\ngroup = '
                                   '"bottom"'), ('[[dirichlet]]\ngroup = "symmetry"\ncomponents'
                                                 ' = [0]\n', '')), [],
                             [("dirichlet", "expected an array of tables")]),
    "unknown solver option": (edit(("rtol = 1e-6", "tol = 1e-6")), [],
                              [("solver.tol", "did you mean 'rtol'")]),
    "bad solver value": (edit(("rtol = 1e-6", 'rtol = 1e-6\nfactor = "superlu"')), [],
                         [("solver.factor", "factor must be one of 'cholmod', 'mumps', 'petsc'")]),
    "solver options that do not go together": (
        edit(("rtol = 1e-6", 'rtol = 1e-6\nmprgp_alpha = "bb"\nmprgp_expansion = "optimal"')),
        [], [("solver", "mprgp_alpha 'bb' needs mprgp_expansion 'fixed'")]),
    "zero parts": (edit(("n = 2", "n = 0")), [], [("decomposition.n", "expected an integer >= 1")]),
    "unknown decomposition": (edit(('type = "parts"', 'type = "metis"')), [],
                              [("decomposition.type", "expected one of 'tags', 'parts', 'grid'")]),
    "key of another decomposition": (edit(('type = "parts"', 'type = "grid"\nsize = 5.0')), [],
                                     [("decomposition.n", "belongs to type 'parts'")]),
    "grid finer than the mesh": (edit(('type = "parts"\nn = 2', 'type = "grid"\nsize = 1e-4')),
                                 [], [("decomposition.size", "finer than the mesh")]),
    "cylinder obstacle in 2D": (edit(('type = "node_to_node"\nslave = "disk_contact"\nmaster = '
                                      '"block_contact"', 'type = "obstacle"\ngroup = '
                                      '"disk_contact"\ncylinder = { point = [0, 0, 0], axis = '
                                      '[0, 0, 1], radius = 1.0 }')), [],
                                [("contact[0].cylinder", "a cylinder obstacle needs a 3D mesh")]),
    "zero plane normal": (edit(('type = "node_to_node"\nslave = "disk_contact"\nmaster = '
                                '"block_contact"', 'type = "obstacle"\ngroup = "disk_contact"\n'
                                'plane = { point = [0, 0], normal = [0, 0] }')), [],
                          [("contact[0].plane.normal", "non-zero")]),
    "output name without its suffix": (edit(('xdmf = "out.xdmf"', 'xdmf = "out.vtk"')), [],
                                       [("output.xdmf", "ending in .xdmf")]),
    "plot of a surface without contact": (BASE + '\n[output.pressure_plot]\nsurface = "load"\n',
                                          [], [("output.pressure_plot.surface",
                                                "expected the slave or obstacle group")]),
    "unknown -feti_ option": (BASE, ["-feti_rtoll", "1e-8"],
                              [("command line -feti_rtoll", "did you mean -feti_rtol")]),
    "bad -feti_ value": (BASE, ["-feti_max_it", "many"],
                         [("command line -feti_max_it",
                           "max_it must be an integer >= 1 and <= 1000000000, got 'many'")]),
    "poisson model with an obstacle": (
        edit(('type = "elasticity"\nE = 200.0\nnu = 0.3\ntractions = { load = [0.0, -0.625] }',
              'type = "poisson"'), ('type = "node_to_node"\nslave = "disk_contact"\nmaster = '
                                    '"block_contact"', 'type = "obstacle"\ngroup = '
                                    '"disk_contact"\nsphere = { center = [0, 9], radius = 1 }'),
             ("components = [0]", "")),
        [], [("contact[0]", "a rigid obstacle needs an elasticity model")]),
    "unknown mesh generator": (edit((f'mesh = "{HERTZ}"', 'mesh = { generator = "hertz3d" }')),
                               [], [("mesh.generator", "(did you mean 'hertz2d'?)")]),
    "unknown generator parameter": (edit((f'mesh = "{HERTZ}"',
                                          'mesh = { generator = "hertz2d", h = 0.1 }')), [],
                                    [("mesh.h", "unknown parameter of meshes.hertz2d")]),
    "generator refuses its parameters": (edit((f'mesh = "{HERTZ}"', 'mesh = { generator = '
                                               '"hertz2d", h_contact = -1.0 }')), [],
                                         [("mesh", "meshes.hertz2d(h_contact=-1.0) failed")]),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_problem_file(case, folder, capsys):
    text, extra, expected = MALFORMED[case]
    slug = re.sub(r"\W+", "_", case)
    toml = write_text(folder / slug / f"{slug}.toml", text)
    out = folder / slug / "out"
    code = main([str(toml), "-o", str(out), *extra])
    assert code == 2
    assert files_in(folder / slug) == [toml.name]  # nothing written, no folder made
    err = capsys.readouterr().err
    if COMM.rank == 0:
        for key, words in expected:
            line = f"{toml}: {key}: " if key else f"{toml}: "
            assert any(ln.startswith(line) and words in ln for ln in err.splitlines()), \
                f"expected a line '{line}...{words}...' in:\n{err}"
    else:
        assert err == ""
    with pytest.raises(pfile.ProblemFileError) as info:
        pfile.load(toml, command_line=extra, output_dir=out)
    assert info.value.path == str(toml)
    assert {f.key for f in info.value.faults} >= {k for k, _ in expected}


def test_at_least_fifteen_malformed_cases():
    assert len(MALFORMED) >= 15


def test_all_faults_at_once(folder, capsys):
    text = edit(("nu = 0.3", "nu = 0.7"), ('group = "bottom"', 'group = "floor"'),
                ("rtol = 1e-6", "rtol = -1.0\nspeed = 3"),
                ('master = "block_contact"', 'master = "block_contact"\ngap = nan'),
                ("n = 2", 'n = { disk = 2, plate = 1 }'))
    toml = write_text(folder / "many" / "many.toml", "colour = 1\n" + text)
    with pytest.raises(pfile.ProblemFileError) as info:
        pfile.load(toml)
    keys = [f.key for f in info.value.faults]
    assert set(keys) == {"model.nu", "dirichlet[0].group", "solver.rtol", "solver.speed",
                         "contact[0].gap", "decomposition.n.plate", "colour"}, keys
    message = str(info.value)
    assert message.splitlines()[0] == f"{toml}: 7 errors in the problem file"
    assert main([str(toml), "-q"]) == 2
    if COMM.rank == 0:
        assert capsys.readouterr().err.count(f"{toml}: ") == 8


def test_missing_problem_file(folder, capsys):
    assert main([str(folder / "nope.toml")]) == 2
    if COMM.rank == 0:
        assert "nope.toml: the problem file does not exist" in capsys.readouterr().err


def test_valid_base_problem_loads(folder):
    toml = write_text(folder / "base" / "base.toml", BASE)
    pf = pfile.load(toml)
    p = pf.problem
    assert pf.model == "elasticity" and p.value_size == 2
    assert [(d.group, d.components) for d in p.dirichlet] == [("bottom", None),
                                                               ("symmetry", [0])]
    assert p.contact == [df.NodeToNode("disk_contact", "block_contact")]
    assert p.decomposition == df.Parts(2, "rcb")
    assert pf.solver == {"rtol": 1e-6}
    assert pf.output.xdmf == folder / "base" / "out.xdmf"
    assert pf.output.report == folder / "base" / "base.json"
    assert pf.output.nodal_values is None and pf.output.pressure_plot is None


@pytest.mark.skipif(not HAS_FRICTION, reason="friction is not available")
def test_friction_keys(folder):
    good = edit(('master = "block_contact"', 'master = "block_contact"\nfriction = { type = '
                 '"coulomb", coefficient = 0.3, max_steps = 20 }'))
    pf = pfile.load(write_text(folder / "fr" / "good.toml", good))
    assert pf.problem.contact[0].friction == df.Coulomb(0.3, max_steps=20)
    bad = edit(('master = "block_contact"', 'master = "block_contact"\nfriction = { type = '
                '"coulomb", coefficient = -0.3, rtol = 0 }'))
    with pytest.raises(pfile.ProblemFileError) as info:
        pfile.load(write_text(folder / "fr" / "bad.toml", bad))
    assert {f.key for f in info.value.faults} == {"contact[0].friction.coefficient",
                                                  "contact[0].friction.rtol"}
    tresca = edit(('master = "block_contact"', 'master = "block_contact"\nfriction = { type = '
                   '"tresca", bound = inf }'))
    pf = pfile.load(write_text(folder / "fr" / "tresca.toml", tresca))
    assert pf.problem.contact[0].friction == df.Tresca(np.inf)


# ------------------------------------------------------------------------------------------
# Pieces of the schema
# ------------------------------------------------------------------------------------------


def test_grid_labels_match_the_demo_grid():
    mesh = df.read_gmsh(MESHES / "membranes_16.msh")
    mid = mesh.x[mesh.cells].mean(axis=1)
    labels = pfile.GridLabels((0.25, 0.25), (0.0, 0.0))(mid)
    demo = (np.floor(mid[:, 0] / 0.25) + 8 * np.floor(mid[:, 1] / 0.25)).astype(np.int64)
    assert np.array_equal(labels, demo)


def test_per_body_source_and_affine_traction(folder):
    """A per-body Poisson source and an affine traction give the Python API's solution."""
    text = f'''
mesh = "{(MESHES / "membranes_8.msh").as_posix()}"
[model]
type = "poisson"
source = {{ left = -1.0, right = -0.5 }}
[[model.source_boxes]]
min = [1.5, 0.0]
max = [2.0, 1.0]
value = -1.0
[[dirichlet]]
group = "dirichlet"
[[contact]]
slave = "contact_left"
master = "contact_right"
'''
    pf = pfile.load(write_text(folder / "src" / "src.toml", text))

    def f(x):
        right = ufl.conditional(ufl.ge(x[0], 1.5), -1.5, -0.5)
        return ufl.conditional(ufl.lt(x[0], 1.0), -1.0, right)

    api = df.ContactProblem(pf.mesh, df.Poisson(source=f), dirichlet=[df.Dirichlet("dirichlet")],
                            contact=[df.NodeToNode("contact_left", "contact_right")])
    u_file = df.solve(pf.problem, rtol=1e-10).nodal_values()
    u_api = df.solve(api, rtol=1e-10).nodal_values()
    assert np.abs(u_file - u_api).max() <= 1e-8 * np.abs(u_api).max()

    t = pfile.AffineTraction((1.0, 2.0), ((0.0, 3.0), (4.0, 0.0)))
    x = ufl.SpatialCoordinate(compat.ufl_domain("triangle", 2))
    assert str(t(x)) == str(ufl.as_vector((1.0 + 3.0 * x[1], 2.0 + 4.0 * x[0])))


def test_generators_are_the_mesh_builders():
    gens = pfile.generators()
    assert {"hertz2d", "membranes", "blocks3d"} <= set(gens)
    assert "physical_groups" not in gens


def test_command_line_pairs():
    pairs, faults = pfile.check_command_line(["-feti_rtol", "1e-9", "-feti_smalbe_M", "-2",
                                              "-feti_norm_rtol", "-1", "-feti_verbose"])
    assert pairs == [("-feti_rtol", "1e-9")]
    assert [f.key for f in faults] == ["command line -feti_smalbe_M",
                                       "command line -feti_norm_rtol",
                                       "command line -feti_verbose"]
    assert "smalbe_M must be a finite number > 0, got -2" in faults[0].message
    assert "norm_rtol must be a finite number > 0 and < 1, got -1" in faults[1].message
    assert "expected a value" in faults[2].message


# ------------------------------------------------------------------------------------------
# Post-processing
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("msh", ["membranes_8.msh", "blocks3d.msh"])
def test_von_mises_of_a_linear_field(msh):
    mesh = df.read_gmsh(MESHES / msh)
    d = mesh.gdim
    rng = np.random.default_rng(1)
    A = rng.standard_normal((d, d))
    u = mesh.x @ A.T  # grad u = A
    E, nu = 3.0, 0.25
    vm = von_mises(mesh, u, E, nu)
    eps = 0.5 * (A + A.T)
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    s = np.zeros((3, 3))
    s[:d, :d] = 2 * mu * eps + lam * np.trace(eps) * np.eye(d)
    if d == 2:
        s[2, 2] = lam * np.trace(eps)  # plane strain
    dev = s - np.trace(s) / 3 * np.eye(3)
    assert np.allclose(vm, np.sqrt(1.5 * np.sum(dev * dev)), rtol=1e-10)
    # Per-body data: body 1 twice as stiff, twice the stress.
    vm2 = von_mises(mesh, u, {mesh.body_names[0]: E, mesh.body_names[1]: 2 * E}, nu)
    assert np.allclose(vm2[mesh.cell_body == 1], 2 * vm[mesh.cell_body == 1])


def test_arclength_along_the_disk():
    mesh = df.read_gmsh(MESHES / "hertz2d.msh")
    nodes, s = surface_arclength(mesh, "disk_contact")
    x = mesh.x[nodes]
    assert np.all(np.diff(x[:, 0]) > 0)  # from x = 0 outwards
    R = 8.0
    assert s[-1] == pytest.approx(R * np.arcsin(x[-1, 0] / R), rel=1e-3)
    with pytest.raises(df.InputError, match="separate pieces|branches"):
        surface_arclength(mesh, "symmetry")  # two segments, one per body


# ------------------------------------------------------------------------------------------
# The reference in docs/index.md names every key
# ------------------------------------------------------------------------------------------


def test_docs_reference_lists_every_key():
    """The tables other than the conditions' (those: tests/io/test_problemfile_schema.py)."""
    docs = (ROOT / "docs" / "index.md").read_text()
    ref = docs[docs.index("## Problem file reference"):]
    keys = set(schema.TOP_KEYS) | set(schema.BOX_KEYS) | set(schema.OUTPUT_KEYS) | \
        set(schema.PLOT_KEYS) | set(schema.AFFINE_KEYS)
    for table in (schema.MODEL_KEYS, schema.DECOMPOSITION_KEYS):
        for ks in table.values():
            keys |= set(ks)
    missing = sorted(k for k in keys if f"`{k}`" not in ref)
    assert not missing, f"docs/index.md's problem file reference does not list {missing}"
    for f in PROBLEMS.glob("*.toml"):
        assert f"problems/{f.name}" in docs


def test_self_contact_in_a_problem_file(folder):
    """type = "mortar" with slave = master is self-contact; a tie with itself is refused."""
    text = edit(('type = "node_to_node"\nslave = "disk_contact"\nmaster = "block_contact"',
                 'type = "mortar"\nslave = "disk_contact"\nmaster = "disk_contact"'))
    pf = pfile.load(write_text(folder / "self" / "self.toml", text))
    assert pf.problem.contact == [df.Mortar("disk_contact", "disk_contact")]
    tie = text + '\n[[tie]]\nslave = "block_contact"\nmaster = "block_contact"\n'
    with pytest.raises(pfile.ProblemFileError) as info:
        pfile.load(write_text(folder / "self" / "tie.toml", tie))
    assert any("with itself" in f.message for f in info.value.faults)


def test_mortar_normals_in_a_problem_file(folder):
    """contact.normals = "flatter" reaches df.Mortar; another word is a fault naming the key."""
    base = edit(('type = "node_to_node"\nslave = "disk_contact"\nmaster = "block_contact"',
                 'type = "mortar"\nslave = "disk_contact"\nmaster = "block_contact"\n'
                 'normals = "flatter"'))
    pf = pfile.load(write_text(folder / "normals" / "ok.toml", base))
    assert pf.problem.contact == [df.Mortar("disk_contact", "block_contact", normals="flatter")]
    with pytest.raises(pfile.ProblemFileError) as info:
        pfile.load(write_text(folder / "normals" / "bad.toml",
                              base.replace('"flatter"', '"flat"')))
    assert any("normals" in f.key and "flatter" in f.message for f in info.value.faults)
