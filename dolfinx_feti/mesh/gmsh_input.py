"""Reading a gmsh model (in memory or a ``.msh`` file) into global NumPy arrays.

Every rank holds the whole mesh as plain arrays: the decomposition, the constraint rows and the
contact geometry are then computed identically everywhere, with no communication and no
dependence on the number of ranks. Only rank 0 talks to gmsh; the arrays are broadcast.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mpi4py import MPI

from ..errors import InputError, collective
from .data import MeshData
from .mixed import MixedMesh, mixed_mesh
from .topology import row_keys

#: gmsh element type → (cell name, geometry order, number of nodes): first-order cells and
#: the complete second-order ones (curved cells, nodes on edges, faces and interiors).
_GMSH_CELLS = {2: ("triangle", 1, 3), 4: ("tetrahedron", 1, 4), 3: ("quadrilateral", 1, 4),
               5: ("hexahedron", 1, 8), 9: ("triangle", 2, 6), 11: ("tetrahedron", 2, 10),
               10: ("quadrilateral", 2, 9), 12: ("hexahedron", 2, 27)}
_NUM_VERTICES = {"triangle": 3, "tetrahedron": 4, "quadrilateral": 4, "hexahedron": 8}
#: gmsh's vertex order → DOLFINx's (tensor-product order for quadrilaterals and hexahedra).
_GMSH_TO_DOLFINX = {"triangle": [0, 1, 2], "tetrahedron": [0, 1, 2, 3],
                    "quadrilateral": [0, 1, 3, 2], "hexahedron": [0, 1, 3, 2, 4, 5, 7, 6]}
#: cell type → (gmsh element types of its facets (order 1, 2), facet vertex order gmsh →
#: DOLFINx; the vertices come first among a second-order facet's nodes).
_GMSH_FACETS = {"triangle": ((1, 8), [0, 1]), "quadrilateral": ((1, 8), [0, 1]),
                "tetrahedron": ((2, 9), [0, 1, 2]), "hexahedron": ((3, 10), [0, 1, 3, 2])}
_UNSUPPORTED = {6: "prism", 7: "pyramid", 13: "second-order prism", 14: "second-order pyramid",
                16: "8-node (serendipity) quadrangle", 17: "20-node (serendipity) hexahedron",
                21: "third-order triangle", 29: "third-order tetrahedron"}


def read_gmsh(source, comm: MPI.Comm = MPI.COMM_WORLD, gdim: int | None = None,
              replicate: bool = True, distribute: bool = False) -> MeshData:
    """Read a gmsh model into :class:`MeshData`.

    Args:
        source: A path to a ``.msh`` file, or the ``gmsh.model`` module / ``None`` for the model
            that is current in this process's gmsh session (it only needs to exist on rank 0).
        comm: The ranks that will share the data.
        gdim: Geometric dimension; by default the cells' dimension (a 2D model has z = 0).
        replicate: Every rank receives the arrays (the default), or only rank 0 keeps them
            and the others hold the names and types (``root_only``): the solve then hands
            every rank only its share, so no other rank ever holds the whole mesh. Use it
            for large meshes under MPI; code of the user's that reads the arrays (``mesh.x``,
            ``mesh.cells``) then runs on rank 0.
        distribute: Spread the mesh over the ranks instead (``replicate`` is then not used):
            rank 0 reads and checks the model, hands every rank a compact block of the
            cells (consecutive along a space-filling curve, in the file's order within the
            block) with their vertices and boundary facets, and keeps only its own block;
            the arrays of each rank are its block, numbered locally
            (``mesh.part``: :class:`~.distributed.MeshPart`). No rank holds the whole mesh
            after the input; the decomposition and the rows are then computed on the
            distributed data.

    Returns:
        The mesh data, identical on every rank of ``comm`` (or on rank 0, see ``replicate``;
        or each rank's block, see ``distribute``). A model whose bodies are of several cell
        types (each body of one type) gives a :class:`~.mixed.MixedMesh`: one mesh per type
        (read replicated only).

    Raises:
        InputError: If the file is missing, the model has no physical groups of cells,
            the cells are not triangles, quadrilaterals, tetrahedra or hexahedra of order 1
            or 2 (complete: 6, 9, 10 or 27 nodes), a body mixes cell types or orders, bodies
            of different types share nodes, a cell is in two bodies, or the data is not
            finite.
    """
    data = None
    with collective(comm, "mesh"):
        if comm.rank == 0:
            data = _extract(source, gdim)
            from .checks import check_mesh  # degenerate or inverted cells, empty bodies

            for part in data.parts if isinstance(data, MixedMesh) else (data,):
                check_mesh(part)
            if isinstance(data, MixedMesh) and (distribute or not replicate):
                raise InputError("a model with bodies of several cell types "
                                 f"({data.describe()}) is read with every rank holding it "
                                 "(replicate=True, distribute=False)")
    if distribute:
        from .distributed import scatter_mesh

        with collective(comm, "mesh"):
            if comm.rank == 0 and data.high_order is not None:
                raise InputError("a curved (second-order) mesh cannot be distributed yet: "
                                 "read it with distribute=False")
        return scatter_mesh(data, comm)
    if not replicate and comm.size > 1:
        names = comm.bcast(data.names_only() if comm.rank == 0 else None, root=0)
        data = data if comm.rank == 0 else names
        data.root_only = comm
        return data
    data = comm.bcast(data, root=0)
    from .checks import mark_checked  # rank 0 checked it: the received copy needs no re-check

    if not isinstance(data, MixedMesh):
        mark_checked(data)
    return data


def build_mesh(generator, *args, comm: MPI.Comm = MPI.COMM_WORLD, gdim: int | None = None,
               replicate: bool = True, distribute: bool = False, **kwargs) -> MeshData:
    """Run a gmsh model generator on rank 0 and read the model it leaves current.

    Args:
        generator: A function that builds and meshes a model in the current gmsh session,
            e.g. one of :mod:`dolfinx_feti.io.meshes`; called as ``generator(*args, **kwargs)``.
        *args: Positional arguments of the generator.
        comm: The ranks that receive the mesh.
        gdim: Geometric dimension (default: that of the cells).
        replicate: Whether every rank receives the arrays (see :func:`read_gmsh`).
        distribute: Whether the mesh is spread over the ranks (see :func:`read_gmsh`).
        **kwargs: Keyword arguments of the generator.

    Returns:
        The mesh data, identical on every rank.
    """
    import gmsh

    with collective(comm, "mesh"):
        if comm.rank == 0:
            gmsh_initialize(gmsh)
            gmsh.option.setNumber("General.Terminal", 0)
            try:
                generator(*args, **kwargs)
            except Exception:
                gmsh.finalize()
                raise
    try:
        return read_gmsh(None, comm, gdim, replicate, distribute)
    finally:
        if comm.rank == 0:
            gmsh.finalize()


def _extract(source, gdim: int | None) -> MeshData:
    import gmsh

    if not isinstance(source, (str, Path)):
        return _extract_current(gmsh, gdim)
    if isinstance(source, str) and not source.strip():
        raise InputError("the mesh path is empty: expected the path of a gmsh .msh file (or "
                         "None for gmsh's current model)")
    path = Path(source)
    if path.is_dir():
        raise InputError(f"the mesh path {str(path)!r} is a folder, not a gmsh .msh file")
    if not path.is_file():
        raise InputError(f"mesh file not found: {path}")
    # gmsh 4.8 cannot tell whether it is initialized; initializing twice is harmless and keeps
    # the caller's models. The file is merged into a fresh model of its own (gmsh.open on a bad
    # file leaves gmsh locked and the broken model current), removed afterwards.
    gmsh_initialize(gmsh)
    gmsh.option.setNumber("General.Terminal", 0)
    previous = gmsh.model.getCurrent()
    name = f"dolfinx_feti_read_{path.stem}"
    declared = check_msh_file(path)  # before gmsh sees it: a script would run its commands
    gmsh.model.add(name)
    try:
        gmsh.logger.start()
        try:
            gmsh.merge(str(path))
        except Exception as e:
            raise InputError(f"gmsh cannot read {path}: {e}") from None
        finally:
            log = gmsh.logger.get()
            gmsh.logger.stop()
        _check_what_gmsh_kept(gmsh, path, declared, log)
        return _extract_current(gmsh, gdim)
    finally:
        gmsh.model.setCurrent(name)
        gmsh.model.remove()
        if previous in gmsh.model.list():
            gmsh.model.setCurrent(previous)


def gmsh_initialize(gmsh) -> None:
    """:func:`dolfinx_feti.compat.gmsh_initialize` (imported here only when gmsh is used)."""
    from ..compat import gmsh_initialize as initialize

    initialize(gmsh)


def check_msh_file(path: Path) -> tuple[int, int] | None:
    """Refuse a file that is not a gmsh mesh file, before gmsh opens it.

    gmsh chooses its reader by the file's extension, and a ``.geo`` script runs its ``System``
    commands when opened: so the name must end in ``.msh`` and the content must start with the
    ``$MeshFormat`` section of a version 2 or 4 mesh file.

    Returns:
        The numbers of nodes and elements that an ASCII file declares (None for binary).
    """
    if path.suffix != ".msh":
        raise InputError(f"{path}: not a gmsh mesh file (expected a name ending in .msh, not "
                         f"{path.suffix or 'no extension'!r}); a .geo script is not read: mesh "
                         "it with gmsh and save the mesh as .msh")
    with open(path, "rb") as f:
        head = f.read(64).split(b"\n")
    version = head[1].split() if len(head) > 1 else []
    if head[0].strip() != b"$MeshFormat" or not version or \
            version[0].split(b".")[0] not in (b"2", b"4"):
        raise InputError(f"{path}: not a gmsh mesh file (it does not start with the $MeshFormat "
                         "section of a version 2 or 4 .msh file)")
    if len(version) < 2 or version[1] != b"0":
        return None  # binary: the counts are not text
    import mmap

    counts = []
    with open(path, "rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as m:
        for section in (b"\n$Nodes\n", b"\n$Elements\n"):
            at = m.find(section)
            if at < 0:
                return None
            line = m[at + len(section):m.find(b"\n", at + len(section))].split()
            counts.append(int(line[0] if version[0].startswith(b"2") else line[1]))
    return counts[0], counts[1]


def _check_what_gmsh_kept(gmsh, path: Path, declared: tuple[int, int] | None,
                          log: list[str]) -> None:
    """Refuse a mesh file whose data gmsh repaired or dropped silently.

    gmsh skips a node whose tag repeats (with a warning in version 2 files, a mere "Info" line
    in version 4 files, where it still lists the node twice with the first coordinates: one
    node silently moved) and, in version 2 files, keeps one of two elements with the same tag
    (without a word): the mesh read would not be the one written.
    """
    bad = [line for line in log if line.startswith(("Warning", "Error"))
           or "duplicate" in line.lower()]
    if bad:
        raise InputError(f"{path}: malformed mesh data: gmsh says {bad[0]!r}"
                         + (f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""))
    tags = gmsh.model.mesh.getNodes()[0]
    nodes = tags.size
    uniq, count = np.unique(tags, return_counts=True)
    if uniq.size != nodes:
        raise InputError(f"{path}: malformed mesh data: node tag {int(uniq[count > 1][0])} is "
                         f"given {int(count.max())} times ({int((count > 1).sum())} repeated "
                         "tags); gmsh keeps one position for it")
    if declared is None:
        return
    elements = sum(t.size for t in gmsh.model.mesh.getElements()[1])
    if (nodes, elements) != declared:
        raise InputError(f"{path}: malformed mesh data: the file declares {declared[0]} nodes and "
                         f"{declared[1]} elements, gmsh read {nodes} and {elements} (repeated "
                         "tags?)")


def _facet_counts(gmsh, groups, tdim: int, kinds: list[tuple[str, int]]) -> dict[str, int]:
    """The number of facets of each boundary group of a kind some body has (a mixed model)."""
    types = {_GMSH_FACETS[ct][0][o - 1] for ct, o in kinds}
    out = {}
    for dim, tag in sorted(g for g in groups if g[0] == tdim - 1):
        n = 0
        for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            t, e, _ = gmsh.model.mesh.getElements(dim, ent)
            n += sum(int(ei.size) for ti, ei in zip(t, e, strict=True) if int(ti) in types)
        out[_group_name(gmsh, dim, tag)] = n
    return out


def _group_name(gmsh, dim: int, tag: int) -> str:
    return gmsh.model.getPhysicalName(dim, tag) or str(tag)


def _cell_type(gmsh_type: int, body: str) -> tuple[str, int]:
    """(cell type, order) of a gmsh element type, or an error that says what is supported."""
    if gmsh_type in _GMSH_CELLS:
        return _GMSH_CELLS[gmsh_type][:2]
    kind = _UNSUPPORTED.get(gmsh_type, f"gmsh element type {gmsh_type}")
    raise InputError(f"body {body!r} has {kind} cells: only triangles and quadrilaterals (2D), "
                     "tetrahedra and hexahedra (3D) of order 1 or 2 (complete second-order "
                     "elements: gmsh's Mesh.SecondOrderIncomplete = 0) are supported")


def _high_order_layout(gmsh, gmsh_type: int, cell_type: str) -> list[tuple[int, int, tuple]]:
    """Where a second-order gmsh element's extra nodes sit: (node, dim, DOLFINx vertices).

    Found from gmsh's reference coordinates (the node is the mean of its entity's vertices),
    so no table of gmsh's node order is needed.
    """
    from .dofpoints import degree2_entities

    props = gmsh.model.mesh.getElementProperties(gmsh_type)
    tdim, nodes = int(props[1]), int(props[3])
    ref = np.asarray(props[4]).reshape(nodes, tdim)
    corners = ref[np.array(_GMSH_TO_DOLFINX[cell_type])]  # reference coords, DOLFINx order
    out = []
    for j in range(_NUM_VERTICES[cell_type], nodes):
        hits = [(dim, ent) for dim, ents in degree2_entities(cell_type) for ent in ents
                if np.allclose(corners[list(ent)].mean(axis=0), ref[j], atol=1e-9)]
        if len(hits) != 1:
            raise InputError(f"gmsh element type {gmsh_type}: cannot place its node {j}")
        out.append((j, hits[0][0], hits[0][1]))
    return out


def _extract_current(gmsh, gdim: int | None) -> MeshData | MixedMesh:
    groups = gmsh.model.getPhysicalGroups()
    if not groups:
        raise InputError("the gmsh model has no physical groups: name the bodies (volumes, or "
                         "surfaces in 2D) and the boundary parts with physical groups")
    tdim = max(d for d, _ in groups)
    if tdim < 2:
        raise InputError("the gmsh model has no physical group of surfaces or volumes")

    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    coords = coords.reshape(-1, 3)
    model = _Model(gmsh, groups, tdim, tdim if gdim is None else gdim, node_tags, coords)
    bodies = [_body_of(gmsh, model, dim, tag) for dim, tag in
              sorted(g for g in groups if g[0] == tdim)]
    kinds = list(dict.fromkeys(b.kind for b in bodies if b.kind is not None))
    if len(kinds) <= 1:
        return _mesh_of(model, bodies, kinds[0] if kinds else None, whole=True)
    # Bodies of several cell types: one mesh per type (mesh/mixed.py), empty bodies in the
    # first (its checks refuse them by name).
    parts = [_mesh_of(model, [b for b in bodies if b.kind == k or
                              (b.kind is None and k == kinds[0])], k, whole=False)
             for k in kinds]
    return mixed_mesh(parts, _facet_counts(gmsh, groups, tdim, kinds),
                      [b.name for b in bodies])


@dataclass
class _Model:
    """What every mesh of a gmsh model reads: its groups and nodes."""

    gmsh: object
    groups: list
    tdim: int
    gdim: int
    node_tags: np.ndarray
    coords: np.ndarray

    @property
    def tag_to_row(self) -> np.ndarray:
        t = self.node_tags
        out = np.full(int(t.max()) + 1 if t.size else 1, -1, dtype=np.int64)
        out[t] = np.arange(t.size)
        return out


@dataclass
class _Body:
    """One physical group of cells: its name, tag, (cell type, order) and element blocks."""

    name: str
    tag: int
    kind: tuple[str, int] | None
    blocks: list  # (gmsh element type, node tags (n, nodes per element))


def _body_of(gmsh, model: _Model, dim: int, tag: int) -> _Body:
    """A body's elements; a body of two cell types (or orders) is refused by name."""
    name = _group_name(gmsh, dim, tag)
    kind, blocks = None, []
    for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
        types, _, nodes = gmsh.model.mesh.getElements(dim, ent)
        for t, nd in zip(types, nodes, strict=True):
            k = _cell_type(int(t), name)
            if kind is not None and k != kind:
                raise InputError(f"body {name!r} mixes {kind[0]} cells of order {kind[1]} and "
                                 f"{k[0]} cells of order {k[1]}: each body must be of one "
                                 "cell type and one order (bodies of different types may "
                                 "meet in one model)")
            kind = k
            blocks.append((int(t), nd.astype(np.int64).reshape(-1, _GMSH_CELLS[int(t)][2])))
    return _Body(name, tag, kind, blocks)


def _mesh_of(model: _Model, bodies: list[_Body], kind: tuple[str, int] | None,
             whole: bool) -> MeshData:
    """The mesh of some bodies of one cell type and order.

    ``whole``: the bodies are the whole model (every boundary facet must lie on them);
    else they are the bodies of one type of a mixed model, and a boundary group keeps the
    facets that lie on them (a group with none is left out).
    """
    gmsh, groups, tdim, gdim = model.gmsh, model.groups, model.tdim, model.gdim
    node_tags, coords, tag_to_row = model.node_tags, model.coords, model.tag_to_row
    cell_type, order = kind if kind is not None else (None, None)
    body_names, group_tags, cell_blocks, body_blocks = [], {}, [], []
    high: dict[int, list] = {}  # dim → [(entity vertex rows, node rows)] of curved cells
    for body in bodies:
        group_tags[body.name] = body.tag
        index = len(body_names)
        body_names.append(body.name)
        for t, nd in body.blocks:
            ct = _GMSH_CELLS[t][0]
            rows = tag_to_row[nd]
            block = rows[:, :_NUM_VERTICES[ct]][:, _GMSH_TO_DOLFINX[ct]]
            if order == 2:
                for j, edim, ent_vertices in _high_order_layout(gmsh, t, ct):
                    high.setdefault(edim, []).append((block[:, list(ent_vertices)], rows[:, j]))
            cell_blocks.append(block)
            body_blocks.append(np.full(block.shape[0], index, dtype=np.int32))
    if not cell_blocks:
        raise InputError(f"the physical groups of dimension {tdim} hold no cells")
    cells_g = np.concatenate(cell_blocks)
    cell_body = np.concatenate(body_blocks)

    # A cell listed under two bodies means the bodies overlap: refuse rather than guess.
    # One int64 per cell (np.unique on rows is far slower).
    key = row_keys(cells_g, int(cells_g.max()) + 1 if cells_g.size else 1)
    _, first, counts = np.unique(key, return_index=True, return_counts=True)
    if np.any(counts > 1):
        dup = np.flatnonzero(counts > 1)[0]
        same = np.flatnonzero(key == key[first[dup]])
        names = sorted({body_names[cell_body[c]] for c in same})
        raise InputError(f"bodies overlap: {int(np.sum(counts > 1))} cells belong to more than one "
                         f"physical group of dimension {tdim} (e.g. {names})")

    used = np.unique(cells_g)
    new_index = np.full(node_tags.size, -1, dtype=np.int64)
    new_index[used] = np.arange(used.size)
    cells = new_index[cells_g]
    x = coords[used, :gdim].astype(np.float64)  # native byte order (gmsh gives '<d')
    if gdim < 3 and np.any(np.abs(coords[used, gdim:]) > 1e-12 * max(1.0, np.abs(x).max())):
        raise InputError(f"the mesh is not planar: nodes have non-zero coordinates beyond "
                         f"dimension {gdim}")
    if not np.all(np.isfinite(x)):
        raise InputError("the mesh has non-finite node coordinates (NaN or Inf)")
    high_order = None
    if order == 2:
        high_order = {}
        for edim, parts in high.items():
            ent = new_index[np.concatenate([p[0] for p in parts])]
            pos = coords[np.concatenate([p[1] for p in parts]), :gdim]
            _, first = np.unique(np.sort(ent, axis=1), axis=0, return_index=True)
            high_order[edim] = (ent[first], pos[first])

    facet_groups = {}
    ftypes, fperm = _GMSH_FACETS[cell_type]
    nvf = len(fperm)
    ftype = ftypes[order - 1]
    for dim, tag in sorted(g for g in groups if g[0] == tdim - 1):
        name = _group_name(gmsh, dim, tag)
        if name in group_tags:
            raise InputError(f"physical group name {name!r} is used twice")
        group_tags[name] = tag
        blocks = []
        for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            types, _, nodes = gmsh.model.mesh.getElements(dim, ent)
            for t, nd in zip(types, nodes, strict=True):
                if t == ftype:
                    per = gmsh.model.mesh.getElementProperties(int(t))[3]
                    blocks.append(nd.astype(np.int64).reshape(-1, per)[:, :nvf][:, fperm])
        f = np.concatenate(blocks) if blocks else np.empty((0, nvf), dtype=np.int64)
        f = new_index[tag_to_row[f]]
        if not whole:  # a mixed model's group: its facets on these bodies (mixed_mesh checks)
            f = f[np.all(f >= 0, axis=1)]
            if f.shape[0] == 0:
                del group_tags[name]
                continue
        if np.any(f < 0):
            raise InputError(f"boundary group {name!r} has facets whose nodes belong to no cell "
                             "of any body")
        facet_groups[name] = f

    return MeshData(x=x, cells=cells, cell_type=cell_type, cell_body=cell_body,
                    body_names=tuple(body_names), facet_groups=facet_groups,
                    node_tags=node_tags[used].astype(np.int64), group_tags=group_tags,
                    high_order=high_order)
