"""Write the benchmark meshes of dolfinx_feti.io.meshes as gmsh 4.1 files.

Usage: python meshes/generate.py [--out DIR]   (DIR defaults to this script's directory)
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

import gmsh

from dolfinx_feti.io import meshes, meshes_occ, meshes_rubber

#: file name → function that builds the model in the current gmsh session.
MESHES: dict[str, Callable[[], object]] = {
    "membranes_8.msh": lambda: meshes.membranes(8),
    "membranes_16.msh": lambda: meshes.membranes(16),
    "hertz2d.msh": meshes.hertz2d,
    "blocks3d.msh": meshes.blocks3d,
    "disk_on_block.msh": lambda: meshes_occ.disk_on_block(0.1, 0.1),
    "stacked_blocks2d.msh": lambda: meshes_occ.stacked_blocks(2, 0.1, 0.17),
    "disk_on_block_17.msh": lambda: meshes_occ.disk_on_block(0.1, 0.17),
    "sphere_on_block.msh": lambda: meshes_occ.sphere_on_block(0.2, 0.34),
    "slab_with_inclusions.msh": meshes_occ.slab_with_inclusions,
    "rubber_quarter_disk.msh": lambda: meshes_rubber.quarter_disk(1.0, 0.03, 0.15),
}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().parent)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        for name, build in MESHES.items():
            build()
            path = args.out / name
            gmsh.write(str(path))
            nodes = gmsh.model.mesh.getNodes()[0].size
            dim = gmsh.model.getDimension()
            cells = sum(e.size for e in gmsh.model.mesh.getElements(dim)[1])
            print(f"{path}: {nodes} nodes, {cells} cells, {path.stat().st_size / 1024:.0f} kB")
            gmsh.model.remove()
    finally:
        gmsh.finalize()


if __name__ == "__main__":
    main()
