"""Problem files: a contact problem described in TOML, checked completely before any solve.

A problem file names a gmsh ``.msh`` file and describes, on top of its physical groups, the
model (elasticity or a scalar Poisson problem) and its data, the Dirichlet conditions, the
contact conditions, the decomposition, the solver options and the outputs; see the "Problem
file reference" in ``docs/index.md``. A minimal example::

    mesh = "../meshes/hertz2d.msh"          # relative to this file

    [model]
    type = "elasticity"
    E = 200.0
    nu = 0.3
    tractions = { load = [0.0, -0.625] }

    [[dirichlet]]
    group = "bottom"

    [[contact]]
    type = "node_to_node"
    slave = "disk_contact"
    master = "block_contact"

:func:`load` reads the file, reads the mesh and checks every key against the schema and the
mesh's groups. All faults are collected and raised together as one :class:`ProblemFileError`
whose message names the file, the key path (``contact[1].master``) and what was expected.
Nothing heavy (assembly, factorization) happens before that check has passed.

This module is the reader; the keys each table accepts are in :mod:`.schema`, the condition
tables are built from the condition classes' own declarations by :mod:`.condition_tables`,
and the model pieces a file needs beyond the Python API in :mod:`dolfinx_feti.fem.file_models`.
"""

from __future__ import annotations

import difflib
import inspect
import os
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

from ..errors import InputError, SolveError, collective
from ..fem.file_models import AffineTraction, FilePoisson, SourceBox
from ..mesh import ByFunction, ByTags, MeshData, MixedMesh, Parts, read_gmsh
from ..mesh.gmsh_input import gmsh_initialize
from ..options import DECLARED, SolverOptions, kind, option_value, parse_text
from ..problem.contact_problem import ContactProblem
from .condition_tables import ConditionReader
from .loading_table import read_loading
from .mixed_checks import checking_view, method_fault, mixed_faults
from .schema import (
    AFFINE_KEYS,
    ALONG,
    BOX_KEYS,
    DECOMPOSITION_KEYS,
    GLUING,
    MODEL_KEYS,
    OUTPUT_KEYS,
    PLOT_KEYS,
    SOLIDS,
    SOLVER_KEYS,
    TOP_KEYS,
    Checker,
    Fault,
    ProblemFileError,
    describe,
    key_path,
)


def generators() -> dict[str, Any]:
    """The mesh generators that a problem file may name (``mesh = {generator = "<name>"}``).

    They are the public functions that build a model of :mod:`dolfinx_feti.io.meshes` and
    :mod:`dolfinx_feti.io.meshes_rubber` (the soft bodies of the large-deformation demos).
    """
    from . import meshes, meshes_rubber

    return {name: fn for module in (meshes, meshes_rubber) for name, fn in vars(module).items()
            if inspect.isfunction(fn) and fn.__module__ == module.__name__
            and not name.startswith("_") and name != "physical_groups"}


# ------------------------------------------------------------------------------------------
# The decomposition of a grid
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class GridLabels:
    """Labels of a regular grid of boxes of edge lengths ``size`` starting at ``origin``.

    Called on the cell midpoints (C, gdim), it returns the index of the box holding each one,
    numbered lexicographically with x running fastest (:class:`~dolfinx_feti.ByFunction`).
    """

    size: tuple[float, ...]
    origin: tuple[float, ...]

    def __call__(self, midpoints: np.ndarray) -> np.ndarray:
        """The box index of each midpoint."""
        idx = np.floor((midpoints - np.asarray(self.origin)) / np.asarray(self.size))
        idx = idx.astype(np.int64)
        idx -= idx.min(axis=0)
        label = np.zeros(midpoints.shape[0], dtype=np.int64)
        stride = 1
        for a in range(midpoints.shape[1]):
            label += stride * idx[:, a]
            stride *= int(idx[:, a].max()) + 1
        return label


# ------------------------------------------------------------------------------------------
# What load() returns
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PlotSpec:
    """The requested plot of the contact pressure along one contact surface."""

    path: Path
    contact: int  # index in problem.contact
    surface: str
    along: str  # "x", "y", "z" or "arclength"


@dataclass(frozen=True)
class OutputSpec:
    """Where the outputs go (None: not written)."""

    directory: Path
    xdmf: Path | None
    report: Path | None
    nodal_values: Path | None
    pressure_plot: PlotSpec | None
    history: Path | None = None  # a load path's JSON history ([loading])
    #: Bodies of several cell types: the cell type of each mesh (one XDMF file per mesh).
    cell_types: tuple[str, ...] = ()

    def xdmf_files(self) -> list[Path]:
        """The XDMF files written: ``xdmf``, or on several cell types one per mesh."""
        if self.xdmf is None:
            return []
        if not self.cell_types:
            return [self.xdmf]
        from ..results.mixed_solution import xdmf_paths
        return xdmf_paths(self.xdmf, self.cell_types)

    def paths(self) -> list[Path]:
        """Every file that a successful run writes (the XDMF's .h5 included)."""
        xdmf = self.xdmf_files()
        out = xdmf + [p for p in (self.report, self.nodal_values, self.history)
                      if p is not None]
        out += [p.with_suffix(".h5") for p in xdmf]
        if self.pressure_plot is not None:
            out.append(self.pressure_plot.path)
        return out


@dataclass
class ProblemFile:
    """A checked problem file: the problem ready to solve, its solver options and outputs.

    Attributes:
        path: The problem file.
        title: Its title (the file name when none is given).
        model: ``"elasticity"``, ``"neo-hookean"``, ``"svk"`` or ``"poisson"``.
        mesh: The mesh, on every rank (a :class:`~dolfinx_feti.MixedMesh` for bodies of
            several cell types: the problem is then solved by the mixed solve).
        mesh_source: The mesh file, or the generator call that built the mesh.
        problem: The :class:`~dolfinx_feti.ContactProblem`.
        solver: The ``[solver]`` table (fields of :class:`~dolfinx_feti.SolverOptions`).
        command_line: ``-feti_<name> value`` pairs given on the command line, checked.
        output: The outputs.
        loading: The load factors of a load path (``[loading] factors``), or None: one solve.
        loading_values: Per Dirichlet group, its value at each step (``[loading] values``;
            they replace the group's value times the factor).
        loading_translations: Per rigid obstacle's contact group, its translation at each step
            (``[loading] translations``).
        loading_friction: Per contact condition's first group, its friction value at each
            step (``[loading] friction``).
    """

    path: Path
    title: str
    model: str
    mesh: MeshData | MixedMesh
    mesh_source: str
    problem: ContactProblem
    solver: dict[str, Any]
    output: OutputSpec
    command_line: list[tuple[str, str]] = field(default_factory=list)
    loading: tuple[float, ...] | None = None
    loading_values: dict[str, tuple] = field(default_factory=dict)
    loading_translations: dict[str, tuple] = field(default_factory=dict)
    loading_friction: dict[str, tuple] = field(default_factory=dict)

    def problem_at(self, t: float) -> ContactProblem:
        """The problem at pseudo-time ``t`` of the load path: step ``t`` for an integer ``t``.

        Its loads times the step's factor; the Dirichlet groups of ``loading_values`` get
        their value of the step, the obstacles of ``loading_translations`` their position, the
        conditions of ``loading_friction`` their friction value. Between two steps (a Newton
        cut-back halves a step) every one of these is interpolated linearly, so that a halved
        step is half the way to the next load rather than the last one again.

        Raises:
            InputError: For ``t`` outside ``[0, number of steps - 1]``.
        """
        from ..drivers.scaled import moved, scaled, with_friction
        last = len(self.loading) - 1
        if not 0.0 <= t <= last:
            raise InputError(f"{self.path}: the load path has steps 0 to {last}; "
                             f"t = {t:g} is outside")
        k = min(int(np.floor(t)), max(last - 1, 0))
        w = float(t) - k  # 0 at step k, 1 at step k + 1

        def between(a, b):
            return a if w == 0.0 else (1.0 - w) * np.asarray(a, dtype=float) \
                + w * np.asarray(b, dtype=float)

        def at(table: dict) -> dict:
            return {g: between(v[k], v[min(k + 1, last)]) for g, v in table.items()}

        factor = float(between(self.loading[k], self.loading[min(k + 1, last)]))
        friction = {g: float(v) for g, v in at(self.loading_friction).items()}
        return with_friction(moved(scaled(self.problem, factor, at(self.loading_values)),
                                   at(self.loading_translations)), friction)

    def solver_options(self, defaults: Mapping[str, Any] | None = None,
                       **overrides) -> SolverOptions:
        """The solver options, each source over the previous ones.

        defaults < ``[solver]`` < the PETSc options database < the command line's ``-feti_*``
        options < overrides. ``overrides`` that are None are ignored. Nothing is written into
        PETSc's options database, so options given to an in-process run do not leak into the
        next.
        """
        argv = [token for pair in self.command_line for token in pair]
        return SolverOptions.create(argv=argv, defaults={**(defaults or {}), **self.solver},
                                    **overrides)

    def inputs(self) -> list[Path]:
        """The run's input files: the problem file and the mesh file (never overwritten)."""
        mesh = Path(self.mesh_source)
        return [self.path] + ([mesh] if mesh.suffix == ".msh" else [])

    def summary(self) -> dict[str, Any]:
        """What was solved, for the report (bodies of several cell types: ``cell_types``)."""
        m = self.mesh
        parts = getattr(m, "parts", (m,))
        out = {"file": str(self.path), "title": self.title, "model": self.model,
               "mesh": self.mesh_source, "gdim": m.gdim,
               "nodes": int(sum(p.num_nodes for p in parts)),
               "cells": int(sum(p.num_cells for p in parts)), "bodies": list(m.body_names),
               "dirichlet": len(self.problem.dirichlet), "contact": len(self.problem.contact),
               "decomposition": repr(self.problem.decomposition)}
        if len(parts) > 1:
            out["cell_types"] = [p.cell_type for p in parts]
            out["ties"] = len(self.problem.ties)
        return out


# ------------------------------------------------------------------------------------------
# Reading
# ------------------------------------------------------------------------------------------


def load(path: str | Path, comm: MPI.Comm = MPI.COMM_WORLD, *,
         output_dir: str | Path | None = None,
         command_line: Sequence[str] = ()) -> ProblemFile:
    """Read and check a problem file (collective on ``comm``).

    Args:
        path: The TOML file. Relative paths inside it are relative to its folder.
        comm: The ranks that will solve it (all receive the same data).
        output_dir: Overrides ``output.directory`` (relative to the current directory).
        command_line: ``-feti_<name> value`` tokens to check along with the file.

    Returns:
        The checked problem file.

    Raises:
        ProblemFileError: With every fault found (syntax, unknown keys, types, values, groups
            missing in the mesh, the command-line options), on every rank.
    """
    path = Path(path)
    text = None
    try:
        with collective(comm, "problem file"):
            if comm.rank == 0:
                text = _read_bytes(path)
    except (InputError, SolveError) as e:
        raise ProblemFileError(path, [Fault("", str(e))]) from None
    text = comm.bcast(text, root=0)
    try:
        data = tomllib.loads(text.decode("utf-8"))
    except UnicodeDecodeError as e:
        raise ProblemFileError(path, [Fault("", f"not a UTF-8 text file ({e.reason})")]) from None
    except tomllib.TOMLDecodeError as e:
        raise ProblemFileError(path, [Fault("", f"TOML syntax error: {e}")]) from None
    return _Reader(path, data, comm, output_dir, list(command_line)).read()


def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise InputError("the problem file does not exist") from None
    except OSError as e:
        raise InputError(f"cannot read the problem file: {e.strerror or e}") from None


def check_command_line(tokens: Sequence[str]) -> tuple[list[tuple[str, str]], list[Fault]]:
    """Pair ``-feti_<name> value`` tokens and check the names and values.

    Returns:
        The (option, value) pairs and the faults (key ``command line -feti_<name>``).
    """
    pairs, faults = [], []
    kinds = {name: kind(name) for name in DECLARED}
    i = 0
    while i < len(tokens):
        name = tokens[i]
        value = option_value(tokens, i)
        i += 1 if value is None else 2
        key = f"command line {name}"
        if not name.startswith("-feti_"):
            faults.append(Fault(key, "expected an option -feti_<name>"))
            continue
        field_name = name[len("-feti_"):]
        if field_name not in kinds:
            close = difflib.get_close_matches(field_name, list(kinds), n=1)
            hint = f" (did you mean -feti_{close[0]}?)" if close else ""
            faults.append(Fault(key, f"unknown solver option{hint}; the options are "
                                     f"{', '.join('-feti_' + k for k in kinds)}"))
            continue
        if value is None:
            faults.append(Fault(key, "expected a value after the option"))
            continue
        try:
            SolverOptions(**{field_name: parse_text(field_name, value)}).validate()
        except InputError as e:
            faults.append(Fault(key, str(e)))
            continue
        pairs.append((name, value))
    return pairs, faults


class _Reader:
    """One pass over the file: checks every key and builds the objects when all is well."""

    def __init__(self, path: Path, data: dict, comm: MPI.Comm, output_dir, command_line) -> None:
        self.path, self.data, self.comm = path, data, comm
        self.base = path.parent
        self.output_dir = None if output_dir is None else Path(output_dir)
        self.command_line = command_line
        self.c = Checker()
        self.mesh: MeshData | None = None
        self.mesh_path: Path | None = None
        self.model: str | None = None
        self.mixed: MixedMesh | None = None  # a model of bodies of several cell types

    # --- top level ---------------------------------------------------------------------
    def read(self) -> ProblemFile:
        c, data = self.c, self.data
        c.table(data, "", TOP_KEYS, required=("mesh", "model"))
        title = data.get("title", self.path.stem)
        if "title" in data:
            title = c.string(title, "title") or self.path.stem
        method = None
        if "method" in data:  # the FETI method: the solver option ``method``, at the top
            method = c.string(data["method"], "method",
                              ("tfeti", "feti1", "fetidp", "auto", "tbeti"))
        mesh_source = self._mesh()
        model, forms = self._model()
        value_size = None if self.mesh is None or model is None else \
            (self.mesh.gdim if model in SOLIDS else 1)
        conditions = ConditionReader(c, self.mesh, model, value_size)
        dirichlet = conditions.section(data, "dirichlet")
        contact = conditions.section(data, "contact")
        ties = conditions.section(data, "tie")
        decomposition, gluing = self._decomposition()
        solver = self._solver()
        if method is not None:
            if solver.get("method", method) != method:
                c.fault("method", f"{method!r} here, but solver.method is "
                        f"{solver['method']!r}: give it once")
            solver["method"] = method
        loading = read_loading(c, self.data.get("loading"), model, dirichlet, contact,
                               value_size, None if self.mesh is None else self.mesh.gdim)
        output = self._output(contact, loading is not None)
        pairs, faults = check_command_line(self.command_line)
        c.faults.extend(faults)
        if self.mixed is not None and not c.faults:
            c.faults.extend(Fault(k, m) for k, m in mixed_faults(self.mixed, data, model,
                                                                  contact, ties))
        if c.faults:
            raise ProblemFileError(self.path, c.faults)
        mesh = self.mesh if self.mixed is None else self.mixed
        try:
            problem = ContactProblem(mesh, forms, value_size=value_size,
                                     dirichlet=dirichlet, contact=contact, ties=ties,
                                     decomposition=decomposition, gluing=gluing)
        except InputError as e:
            raise ProblemFileError(self.path, [Fault("", str(e))]) from None
        self._dry_run_contact(problem)
        if c.faults:
            raise ProblemFileError(self.path, c.faults)
        pf = ProblemFile(path=self.path, title=title, model=model, mesh=mesh,
                         mesh_source=mesh_source, problem=problem, solver=solver, output=output,
                         command_line=pairs, **({} if loading is None else {
                             "loading": loading.factors, "loading_values": loading.values,
                             "loading_translations": loading.translations,
                             "loading_friction": loading.friction}))
        try:  # the options together (e.g. mprgp_alpha 'bb' with an expansion other than 'fixed')
            opts = pf.solver_options()
        except InputError as e:
            raise ProblemFileError(self.path, [Fault("solver", str(e))]) from None
        if self.mixed is not None:  # the method from wherever it was given
            key = "method" if "method" in data else "solver.method" if "method" in \
                self.data.get("solver", {}) else "command line -feti_method"
            fault = method_fault(opts.method, key)
            if fault is not None:
                raise ProblemFileError(self.path, [Fault(*fault)])
        return pf

    def _mesh(self) -> str:
        c = self.c
        if "mesh" not in self.data:
            return ""
        if isinstance(self.data["mesh"], dict):
            return self._generated_mesh(self.data["mesh"])
        if not isinstance(self.data["mesh"], str):
            c.fault("mesh", "expected the path of a gmsh .msh file or a table {generator = "
                    f"'<name>', ...}}, got {describe(self.data['mesh'])}")
            return ""
        mesh_path = Path(os.path.normpath(self.base / self.data["mesh"]))
        self.mesh_path = mesh_path
        if not self.data["mesh"].strip():
            c.fault("mesh", "empty: expected the path of a gmsh .msh file (relative to the "
                    "problem file's folder) or a table {generator = '<name>', ...}")
            return ""
        kind = self.comm.bcast(("file" if mesh_path.is_file() else "folder" if
                                mesh_path.is_dir() else None) if self.comm.rank == 0 else None,
                               root=0)
        if kind == "folder":
            c.fault("mesh", f"{str(mesh_path)!r} is a folder, not a gmsh .msh file (paths are "
                    "relative to the problem file's folder)")
            return str(mesh_path)
        if kind is None:
            c.fault("mesh", f"mesh file not found: {str(mesh_path)!r} (paths are relative to "
                    "the problem file's folder); expected a gmsh .msh file")
            return str(mesh_path)
        try:
            self.mesh = read_gmsh(mesh_path, self.comm)
        except (InputError, SolveError) as e:
            c.fault("mesh", f"cannot use the mesh {str(mesh_path)!r}: {e}")
        self._one_cell_type()
        return str(mesh_path)

    def _one_cell_type(self) -> None:
        """A model of bodies of several cell types: checked on one view of its meshes."""
        if isinstance(self.mesh, MixedMesh):
            self.mixed = self.mesh
            self.mesh = checking_view(self.mixed)

    def _generated_mesh(self, t: dict) -> str:
        """A mesh built by a generator of :mod:`dolfinx_feti.io.meshes` (rank 0, collectively)."""
        c, comm = self.c, self.comm
        gens = generators()
        if "generator" not in t:
            c.fault("mesh.generator", f"missing: one of {sorted(gens)}")
            return ""
        name = c.string(t["generator"], "mesh.generator", sorted(gens))
        if name is None:
            return ""
        params = inspect.signature(gens[name]).parameters
        kwargs, good = {}, True
        for k, v in t.items():
            if k == "generator":
                continue
            if k not in params:
                close = difflib.get_close_matches(k, list(params), n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                c.fault(key_path("mesh", k), f"unknown parameter of meshes.{name}{hint}; expected "
                        f"one of: {', '.join(params)}")
                good = False
            elif isinstance(v, dict):
                c.fault(key_path("mesh", k), f"expected a number or an array, got {describe(v)}")
                good = False
            else:
                kwargs[k] = tuple(v) if isinstance(v, list) else v
        source = f"meshes.{name}({', '.join(f'{k}={v!r}' for k, v in kwargs.items())})"
        if not good:
            return source
        import gmsh

        err = None
        try:
            with collective(comm, "mesh"):
                if comm.rank == 0:
                    gmsh_initialize(gmsh)
                    gmsh.option.setNumber("General.Terminal", 0)
                    gens[name](**kwargs)
            self.mesh = read_gmsh(None, comm)
        except (InputError, SolveError) as e:  # reported as a fault on every rank
            err = str(e)
        finally:
            if comm.rank == 0:
                try:
                    gmsh.finalize()
                except Exception:  # noqa: BLE001, S110 - gmsh was not initialized
                    pass
        if err is not None:
            c.fault("mesh", f"{source} failed: {err}")
        self._one_cell_type()
        return source

    # --- model -------------------------------------------------------------------------
    def _model(self):
        c, mesh = self.c, self.mesh
        m = self.data.get("model")
        if m is None:  # reported as missing
            return None, None
        if not isinstance(m, dict):
            c.fault("model", f"expected a table, got {describe(m)}")
            return None, None
        kind = c.string(m.get("type", "elasticity"), "model.type", tuple(MODEL_KEYS))
        if kind is None:
            return None, None
        m = c.table(m, "model", MODEL_KEYS[kind],
                    required=("E", "nu") if kind in SOLIDS else ())
        if m is None:
            return None, None
        self.model = kind
        gdim = None if mesh is None else mesh.gdim
        if kind in SOLIDS:
            E = c.per_body(m.get("E"), "model.E", mesh, "a number > 0", lambda v: v > 0) \
                if "E" in m else None
            nu = c.per_body(m.get("nu"), "model.nu", mesh, "a number in (-1, 0.5)",
                            lambda v: -1.0 < v < 0.5) if "nu" in m else None
            tractions = {}
            t = c.table(m.get("tractions", {}), "model.tractions", None)
            for group, vec in (t or {}).items():
                key = key_path("model.tractions", group)
                g = c.group(group, key, mesh)
                if isinstance(vec, dict):
                    v = self._affine(vec, key, gdim)
                else:
                    v = c.vector(vec, key, gdim, "numbers (a traction vector), or a table "
                                 "{value, gradient}")
                if g is not None and v is not None:
                    tractions[g] = v
            body_force = None
            if "body_force" in m:
                body_force = c.vector(m["body_force"], "model.body_force", gdim)
            if E is None or nu is None:
                return kind, None
            return kind, SOLIDS[kind](E, nu, tractions=tractions, body_force=body_force)
        source = c.per_body(m.get("source", 0.0), "model.source", mesh, "a number",
                            None, complete=False)
        k = c.per_body(m.get("k", 1.0), "model.k", mesh, "a number > 0", lambda v: v > 0)
        flux = {}
        t = c.table(m.get("flux", {}), "model.flux", None)
        for group, val in (t or {}).items():
            key = key_path("model.flux", group)
            g = c.group(group, key, mesh)
            v = c.number(val, key, "a number (the flux k du/dn)")
            if g is not None and v is not None:
                flux[g] = v
        boxes = []
        for i, b in enumerate(c.array_of_tables(m.get("source_boxes"), "model.source_boxes")):
            key = key_path("model.source_boxes", i)
            b = c.table(b, key, BOX_KEYS, required=BOX_KEYS)
            if b is None or any(k_ not in b for k_ in BOX_KEYS):
                continue
            lo = c.vector(b["min"], key_path(key, "min"), gdim)
            hi = c.vector(b["max"], key_path(key, "max"), gdim)
            val = c.number(b["value"], key_path(key, "value"))
            if lo is not None and hi is not None and len(lo) != len(hi):
                c.fault(key, f"min and max have different lengths ({len(lo)}, {len(hi)})")
            elif lo is not None and hi is not None and not all(
                    a < b_ for a, b_ in zip(lo, hi, strict=True)):
                c.fault(key, f"expected min < max in every coordinate, got min {lo}, max {hi}")
            elif lo is not None and hi is not None and val is not None:
                boxes.append(SourceBox(tuple(lo), tuple(hi), float(val)))
        if source is None or k is None:
            return kind, None
        return kind, FilePoisson(source, boxes=boxes, flux=flux, k=k)

    def _affine(self, t: dict, key: str, gdim: int | None) -> AffineTraction | None:
        c = self.c
        t = c.table(t, key, AFFINE_KEYS, required=("value",))
        if t is None or "value" not in t:
            return None
        value = c.vector(t["value"], key_path(key, "value"), gdim)
        gradient = t.get("gradient")
        gkey = key_path(key, "gradient")
        if gradient is not None:
            if not isinstance(gradient, list) or (gdim is not None and len(gradient) != gdim):
                c.fault(gkey, f"expected an array of {gdim or 'gdim'} rows (row i: the "
                        f"derivatives of component i along x, y[, z]), got {describe(gradient)}")
                return None
            rows = [c.vector(r, key_path(gkey, i), gdim) for i, r in enumerate(gradient)]
            if any(r is None for r in rows):
                return None
            gradient = tuple(tuple(r) for r in rows)
        if value is None:
            return None
        return AffineTraction(tuple(value), gradient)

    def _dry_run_contact(self, problem: ContactProblem) -> None:
        """Pair the contact surfaces now (cheap), so that a mismatch is reported with its key.

        On bodies of several cell types: each mesh's own conditions on that mesh's problem
        (the conditions between meshes are paired by the solve).
        """
        from ..constraints.build import ROW_BUILDERS, SurfaceCondition

        index = {id(spec): i for i, spec in enumerate(problem.contact)}
        parts = [problem] if problem.mixed is None else problem.mixed.problems
        for part in parts:
            if not part.contact:
                continue
            points = part.dof_points
            node_ptr = np.arange(points.num_points + 1, dtype=np.int64)
            node_subs = np.zeros(points.num_points, dtype=np.int32)
            fixed = np.zeros((points.num_points, part.value_size), dtype=bool)
            for i, spec in enumerate(part.contact):
                try:  # the condition's own row builder, on one subdomain
                    ROW_BUILDERS[type(spec)](SurfaceCondition(part, spec, i, node_ptr,
                                                              node_subs, fixed))
                except InputError as e:
                    self.c.fault(key_path("contact", index[id(spec)]), str(e))
                except Exception:  # noqa: BLE001 - internals changed: the solve checks it again
                    pass

    # --- decomposition, solver, output -------------------------------------------------
    def _decomposition(self):
        c, mesh = self.c, self.mesh
        d = self.data.get("decomposition", {})
        key = "decomposition"
        if not isinstance(d, dict):
            c.fault(key, f"expected a table, got {describe(d)}")
            return ByTags(), "orthonormal"
        kind = c.string(d.get("type", "tags"), key_path(key, "type"), tuple(DECOMPOSITION_KEYS))
        if kind is None:
            return ByTags(), "orthonormal"
        allowed = DECOMPOSITION_KEYS[kind]
        for k in d:
            if k not in allowed:
                owner = [t for t, keys in DECOMPOSITION_KEYS.items() if k in keys]
                what = (f"not a key of decomposition type {kind!r} (it belongs to type "
                        f"{owner[0]!r})") if owner else "unknown key"
                c.fault(key_path(key, k), f"{what}; expected one of: {', '.join(allowed)}")
        gluing = c.string(d.get("gluing", "orthonormal"), key_path(key, "gluing"), GLUING)
        gluing = gluing or "orthonormal"
        if kind == "tags":
            return ByTags(), gluing
        gdim = None if mesh is None else mesh.gdim
        if kind == "parts":
            if "n" not in d:
                c.fault(key_path(key, "n"), "missing: the number of parts per body (an integer "
                        ">= 1, or a table body = integer)")
                return None, gluing
            n = d["n"]
            if isinstance(n, dict):
                ok = True
                for body, v in n.items():
                    ok &= c.number(v, key_path(key_path(key, "n"), body), "an integer >= 1",
                                   lambda v: v >= 1, integer=True) is not None
                    if mesh is not None and body not in mesh.body_names:
                        c.fault(key_path(key_path(key, "n"), body), "unknown body; the mesh's "
                                f"bodies are {list(mesh.body_names)}")
                        ok = False
                n = dict(n) if ok else None
            else:
                n = c.number(n, key_path(key, "n"), "an integer >= 1 (or a table body = integer)",
                             lambda v: v >= 1, integer=True)
            method = c.string(d.get("method", "rcb"), key_path(key, "method"), ("rcb", "ptscotch"))
            balance = c.string(d.get("balance", "cells"), key_path(key, "balance"),
                               ("cells", "volume"))
            if n is None or method is None or balance is None:
                return None, gluing
            if mesh is not None:
                counts = np.bincount(mesh.cell_body, minlength=len(mesh.body_names))
                for b, name in enumerate(mesh.body_names):
                    nb = n.get(name, 1) if isinstance(n, dict) else n
                    if nb > counts[b]:
                        c.fault(key_path(key, "n"), f"{nb} parts for body {name!r}, which has only "
                                f"{counts[b]} cells")
            if balance == "volume" and method != "rcb":
                c.fault(key_path(key, "balance"), "'volume' needs method = 'rcb'")
                return None, gluing
            return Parts(n, method, balance), gluing
        if "size" not in d:
            c.fault(key_path(key, "size"), "missing: the edge length of the grid's boxes (a number "
                    "> 0, or an array of one per coordinate)")
            return None, gluing
        size = d["size"]
        if isinstance(size, list):
            size = c.vector(size, key_path(key, "size"), gdim, "edge lengths")
            if size is not None and min(size) <= 0:
                c.fault(key_path(key, "size"), f"expected edge lengths > 0, got {size}")
                size = None
        else:
            size = c.number(size, key_path(key, "size"), "an edge length > 0 (or an array of one "
                            "per coordinate)", lambda v: v > 0)
            if size is not None and gdim is not None:
                size = [float(size)] * gdim
        origin = None
        if "origin" in d:
            origin = c.vector(d["origin"], key_path(key, "origin"), gdim)
            if origin is None:
                return None, gluing
        if size is None or mesh is None:
            return None, gluing
        lo, hi = mesh.x.min(axis=0), mesh.x.max(axis=0)
        origin = lo if origin is None else np.asarray(origin)
        boxes = np.prod(np.maximum(np.ceil((hi - np.minimum(origin, lo)) / size), 1.0))
        if boxes > mesh.cells.shape[0]:
            c.fault(key_path(key, "size"), f"a grid of {boxes:.0f} boxes of size {size} is finer "
                    f"than the mesh ({mesh.cells.shape[0]} cells): expected a larger size")
            return None, gluing
        return ByFunction(GridLabels(tuple(size), tuple(float(v) for v in origin))), gluing

    def _solver(self) -> dict[str, Any]:
        c = self.c
        s = c.table(self.data.get("solver", {}), "solver", SOLVER_KEYS)
        if s is None:
            return {}
        out = {}
        for k, v in s.items():
            if k not in DECLARED:
                continue
            key = key_path("solver", k)
            if kind(k) == "int":
                v = c.number(v, key, "an integer", integer=True)
            elif kind(k) == "float":
                v = c.number(v, key, "a number")
            elif kind(k) == "bool":
                if not isinstance(v, bool):
                    c.fault(key, f"expected true or false, got {describe(v)}")
                    v = None
            else:
                v = c.string(v, key)
            if v is None:
                continue
            try:
                SolverOptions(**{k: v}).validate()
            except InputError as e:
                c.fault(key, str(e))
                continue
            out[k] = v
        try:
            SolverOptions(**out).validate()
        except InputError as e:
            c.fault("solver", str(e))
        return out

    def _output(self, contact: list, path: bool = False) -> OutputSpec:
        c, stem = self.c, self.path.stem
        o = c.table(self.data.get("output", {}), "output", OUTPUT_KEYS) or {}
        directory = Path(os.path.normpath(
            self.base / (c.string(o.get("directory", "."), "output.directory") or ".")))
        if self.output_dir is not None:
            directory = self.output_dir

        def name(k: str, default: str | None, suffix: str | None) -> Path | None:
            v = o.get(k, default)
            if v is False or v is None:
                return None
            if not isinstance(v, str) or not v:
                c.fault(key_path("output", k), f"expected a file name or false, got {describe(v)}")
                return None
            if suffix is not None and not v.endswith(suffix):
                c.fault(key_path("output", k), f"expected a file name ending in {suffix}, got "
                        f"{v!r}")
                return None
            return directory / v

        xdmf = name("xdmf", f"{stem}.xdmf", ".xdmf")
        report = name("report", f"{stem}.json", None)
        nodal = name("nodal_values", None, ".npz")
        history = None
        if path:
            h = self.data["loading"].get("history", f"{stem}_history.json")
            if h is not False:
                if not isinstance(h, str) or not h.endswith(".json"):
                    c.fault("loading.history", "expected a file name ending in .json or false, "
                            f"got {describe(h)}")
                else:
                    history = directory / h
        plot = None
        p = o.get("pressure_plot", False)
        if p is True:
            p = {}
        if p is not False:
            plot = self._plot(p, directory, stem, contact)
        spec = OutputSpec(directory, xdmf, report, nodal, plot, history,
                          () if self.mixed is None else self.mixed.cell_types)
        paths = [q.resolve() for q in spec.paths()]
        if len(set(paths)) != len(paths):
            c.fault("output", "two outputs have the same file name: "
                    f"{sorted({str(q) for q in paths if paths.count(q) > 1})}")
        inputs = {self.path.resolve()} | ({self.mesh_path.resolve()} if self.mesh_path else set())
        for q in sorted({str(q) for q in paths if q in inputs}):
            c.fault("output", f"the output {q!r} is an input of this run (the problem file or "
                    "its mesh): outputs never overwrite inputs")
        return spec

    def _plot(self, p: Any, directory: Path, stem: str, contact: list) -> PlotSpec | None:
        c, mesh, key = self.c, self.mesh, "output.pressure_plot"
        p = c.table(p, key, PLOT_KEYS, what="a table or true/false")
        if p is None:
            return None
        file = p.get("file", f"{stem}_pressure.png")
        if not isinstance(file, str) or not file.endswith(".png"):
            c.fault(key_path(key, "file"), f"expected a file name ending in .png, got "
                    f"{describe(file)}")
            return None
        specs = self.data.get("contact")
        surfaces = []
        if isinstance(specs, list):
            for t in specs:
                if isinstance(t, dict):
                    surfaces.append(t.get("slave", t.get("group")))
        if not surfaces:
            c.fault(key, "a pressure plot needs a contact condition ([[contact]])")
            return None
        surface = p.get("surface", surfaces[0])
        if surface not in surfaces:
            c.fault(key_path(key, "surface"), f"expected the slave or obstacle group of a contact "
                    f"condition, one of {surfaces}, got {describe(surface)}")
            return None
        index = surfaces.index(surface)
        along = None
        if "along" in p:
            along = c.string(p["along"], key_path(key, "along"), ALONG)
            if along is None:
                return None
        if mesh is not None and isinstance(surface, str) and surface in mesh.facet_groups:
            if along is None:
                nodes = np.unique(mesh.facet_groups[surface])
                along = "xyz"[int(np.argmax(np.ptp(mesh.x[nodes], axis=0)))]
            elif along == "arclength":
                from ..results.postprocess import surface_arclength
                try:
                    surface_arclength(mesh, surface)
                except InputError as e:
                    c.fault(key_path(key, "along"), str(e))
                    return None
            elif "xyz".index(along) >= mesh.gdim:
                c.fault(key_path(key, "along"), f"the mesh is {mesh.gdim}D: expected one of "
                        f"{list('xyz'[:mesh.gdim]) + ['arclength']}, got {along!r}")
                return None
        if len(contact) != len(surfaces):  # a faulty contact entry: nothing to map
            return None
        return PlotSpec(directory / file, index, surface, along or "x")
