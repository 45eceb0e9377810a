"""No hang under MPI: a failure on one rank ends every collective phase on every rank, with the
failing rank's message (issue 13). Runs serially and under mpirun -n 2; a watchdog ends a
hanging test (tests/support/scratch.py).

- Every site of :data:`dolfinx_feti.errors.SITES` fails on one rank (``inject_fault``) in a
  command run that passes through all of them; the command ends on every rank with the same
  exit status, prints the site and the rank, and leaves no file.
- Each kind of user callback raises on one rank only (a ByFunction labeller, a Dirichlet value,
  a Tresca bound, a signed distance, the forms): every rank raises, with the same message.
- The reported hang: ``-o <an existing file>`` is refused before the solve.
"""

from __future__ import annotations

import numpy as np
import pytest
import stress_cases as sc
from cli_helpers import COMM, files_in, remove_shared, shared_dir, write_text
from scratch import scratch_cwd_fixture

import dolfinx_feti as df
from dolfinx_feti.cli import main
from dolfinx_feti.errors import SITES, inject_fault

scratch_cwd = scratch_cwd_fixture("feti-faults-")
LAST = COMM.size - 1  # the rank that fails: rank 1 under mpirun -n 2

#: A small problem whose command run passes through every site of SITES: a generated mesh,
#: a grid decomposition (a ByFunction labeller), Dirichlet rows, Tresca friction, every output.
PROBLEM = """
mesh = { generator = "tresca2d", n = 4 }
[model]
type = "elasticity"
E = 21.19
nu = 0.277
[[dirichlet]]
group = "bottom"
[[dirichlet]]
group = "top"
value = [0.02, -0.02]
[[contact]]
type = "node_to_node"
slave = "block_bottom"
master = "foundation_top"
friction = { type = "tresca", bound = 0.1 }
[decomposition]
type = "grid"
size = 2.0
[solver]
rtol = 1e-8
[output]
directory = "out"
nodal_values = "p_nodal.npz"
pressure_plot = { surface = "block_bottom", along = "x" }
"""

EXIT = {"problem file": 2, "options": 1, "mesh": 2, "output folder": 1, "decomposition": 1,
        "constraints": 1, "friction": 1, "assembly": 1, "factorization": 1, "outputs": 1}


@pytest.fixture
def folder():
    d = shared_dir("feti-faults-cli-")
    write_text(d / "p.toml", PROBLEM)
    yield d
    remove_shared(d)


def test_every_site_is_tested():
    assert set(EXIT) == set(SITES)


def test_the_problem_runs_through_every_site(folder):
    assert main([str(folder / "p.toml"), "-q"]) == 0
    assert set(files_in(folder / "out")) == {"p.xdmf", "p.h5", "p.json", "p_nodal.npz",
                                             "p_pressure.png"}


@pytest.mark.parametrize("rank", sorted({0, LAST}), ids=lambda r: f"rank{r}")
@pytest.mark.parametrize("site", sorted(SITES))
def test_a_fault_at_every_site_ends_every_rank(folder, site, rank, capsys):
    with inject_fault(site, rank):
        code = main([str(folder / "p.toml"), "-q"])
    assert code == EXIT[site]
    codes = COMM.allgather(code)
    assert codes == [code] * COMM.size  # every rank ended, with the same status
    assert files_in(folder / "out") == []  # nothing written, not even a staging folder
    err = capsys.readouterr().err
    if COMM.rank == 0:
        assert f"fault injected at {site!r}" in err
        if COMM.size > 1:
            assert f"on rank {rank}" in err


def test_outputs_of_a_failed_write_leave_the_old_ones(folder, capsys):
    """A run that fails while writing leaves the folder as it was: the old outputs of the same
    names untouched, no new file beside them."""
    assert main([str(folder / "p.toml"), "-q"]) == 0
    out = folder / "out"
    before = {name: (out / name).read_bytes() for name in files_in(out)}
    with inject_fault("outputs", LAST):
        assert main([str(folder / "p.toml"), "-q", "-feti_rtol", "1e-6"]) == 1
    assert {name: (out / name).read_bytes() for name in files_in(out)} == before
    if COMM.rank == 0:
        assert "none was written" in capsys.readouterr().err


def test_output_folder_is_an_existing_file(folder, capsys):
    """The hang of the issue: -o <an existing file> ran the solve, then rank 0 failed to make
    the folder and the other ranks waited. Now refused before the solve, on every rank."""
    write_text(folder / "taken", "a file")
    code = main([str(folder / "p.toml"), "-q", "-o", str(folder / "taken")])
    assert code == 2
    assert files_in(folder) == ["p.toml", "taken"]
    if COMM.rank == 0:
        err = capsys.readouterr().err
        assert "is a file, not a folder" in err and "taken" in err
        assert "feti: assembly" not in err


# ------------------------------------------------------------------------------------------
# User callbacks that raise on one rank only
# ------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def block():
    return df.build_mesh(sc.rectangle, 1.0, 1.0, 4)


def on_one_rank(value, rank=LAST):
    """A callback that raises on ``rank`` only and returns ``value(x)`` elsewhere."""

    def fn(x, *args):
        if COMM.rank == rank:
            raise RuntimeError(f"callback broken on rank {rank}")
        return value(x, *args)

    return fn


def labels(x):
    return (x[:, 0] > 0.5).astype(np.int64)


def plane(x):
    return x[:, 1] + 1e-3, np.tile([0.0, 1.0], (x.shape[0], 1))


CALLBACKS = {
    "ByFunction labeller": (
        lambda fn: {"decomposition": df.ByFunction(fn)}, labels, "ByFunction.fn"),
    "Dirichlet value": (
        lambda fn: {"dirichlet": [df.Dirichlet("top", fn)]},
        lambda x: np.zeros((x.shape[0], 2)), "Dirichlet('top').value"),
    "Tresca bound": (
        lambda fn: {"obstacles": [df.RigidObstacle("block_bottom", df.Plane((0, -1e-3), (0, 1)),
                                                   friction=df.Tresca(fn))]},
        lambda x: np.full(x.shape[0], 0.1), "Tresca bound on 'block_bottom'"),
    "signed distance": (
        lambda fn: {"obstacles": [df.RigidObstacle("block_bottom", df.SignedDistance(fn))]},
        plane, "obstacle on 'block_bottom'"),
}


@pytest.mark.parametrize("kind", sorted(CALLBACKS))
def test_a_callback_raising_on_one_rank_ends_every_rank(block, kind):
    """The callbacks of the decomposition and the rows run on rank 0, which holds the mesh."""
    make, good, words = CALLBACKS[kind]
    kw = make(on_one_rank(good, rank=0))
    dirichlet = kw.pop("dirichlet", [])
    problem = sc.block_on_plane(block, load=(0.0, -0.1), **kw)
    if dirichlet:
        problem = df.ContactProblem(problem.mesh, problem.forms, dirichlet=dirichlet,
                                    contact=problem.contact)
    with pytest.raises(df.InputError) as info:
        df.solve(problem)
    msg = str(info.value)
    assert words in msg and "callback broken on rank 0" in msg, msg
    if COMM.size > 1:
        assert "on rank 0" in msg.split("callback broken")[-1]
    assert COMM.allgather(msg) == [msg] * COMM.size  # the same message everywhere


def test_forms_raising_on_one_rank(block):
    inner = sc.ConstElasticity(1.0, 0.3)

    def forms(V, sub):
        if COMM.rank == LAST:
            raise RuntimeError("no forms here")
        return inner(V, sub)

    problem = df.ContactProblem(block, forms, value_size=2,
                                dirichlet=[df.Dirichlet("top", (0.0, -0.01))],
                                decomposition=df.Parts(2))
    with pytest.raises(df.SolveError) as info:
        df.solve(problem)
    msg = str(info.value)
    assert "RuntimeError: no forms here" in msg and "assembly" in msg
    assert COMM.allgather(msg) == [msg] * COMM.size


@pytest.mark.parametrize("line", ['report = "p.toml"', 'report = "../p.toml"'])
def test_outputs_never_overwrite_inputs(folder, line, capsys):
    text = PROBLEM.replace('directory = "out"', f'directory = "out"\n{line}')
    if "../" not in line:
        text = text.replace('directory = "out"', 'directory = "."')
    write_text(folder / "p.toml", text)
    assert main([str(folder / "p.toml"), "--check", "-q"]) == 2
    assert (folder / "p.toml").read_text() == text
    if COMM.rank == 0:
        assert "is an input of this run" in capsys.readouterr().err
