"""A problem file on a model of bodies of several cell types: refused by name (not yet)."""

from __future__ import annotations

import gmsh
import pytest
from cli_helpers import remove_shared, shared_dir, write_text
from mpi4py import MPI

import dolfinx_feti as df
from dolfinx_feti.io import problemfile as pfile
from dolfinx_feti.io.meshes_occ import stacked_blocks


def test_mixed_model_in_a_problem_file_is_refused(capsys):
    folder = shared_dir("feti-problemfile-mixed-")
    try:
        msh = folder / "mixed.msh"
        if MPI.COMM_WORLD.rank == 0:
            gmsh.initialize()
            gmsh.option.setNumber("General.Terminal", 0)
            try:
                stacked_blocks(2, 0.5, 0.5, recombine="lower")
                gmsh.write(str(msh))
            finally:
                gmsh.finalize()
        assert isinstance(df.read_gmsh(MPI.COMM_WORLD.bcast(str(msh), root=0)), df.MixedMesh)
        toml = write_text(folder / "mixed.toml", f'''
mesh = "{msh.as_posix()}"

[model]
type = "elasticity"
E = 1.0
nu = 0.3

[[tie]]
slave = "upper_bottom"
master = "lower_top"
''')
        with pytest.raises(pfile.ProblemFileError) as info:
            pfile.load(toml)
        assert any(f.key == "mesh" and "bodies of several cell types" in f.message
                   for f in info.value.faults), info.value.faults
    finally:
        remove_shared(folder)
