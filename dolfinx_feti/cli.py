"""The command ``dolfinx-feti`` (also ``python -m dolfinx_feti``): solve a TOML problem file.

Usage::

    dolfinx-feti PROBLEM.toml [-o DIR] [-v | -q] [--check] [--plot] [-feti_<option> VALUE ...]
    mpirun -n 4 dolfinx-feti problems/hertz2d.toml -feti_rtol 1e-10

The problem file is read and checked completely (every fault reported, with the file and the
key) before anything heavy starts; then the problem is solved by FETI (the method of least
measured time unless the file or ``-feti_method`` names one) on all ranks of
``MPI.COMM_WORLD`` and the outputs are written, all or none: the output folder is checked before
the solve, the files are staged beside their targets and moved into place together
(:mod:`dolfinx_feti.io.staging`).

Exit status: 0 solved; 1 the solve failed (an ill-posed problem found during the solve, outputs
that could not be written: then none is); 2 the command line, the problem file or the output
folder is wrong (nothing written); 3 the solver did not converge (only the JSON report is
written); 130 interrupted by Ctrl-C (SIGINT, or SIGTERM as mpirun passes Ctrl-C on: one
line on stderr, no new output written).
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import time
from collections.abc import Sequence
from contextlib import contextmanager
from pathlib import Path

from mpi4py import MPI

from .errors import InputError, SolveError, collective
from .io.problemfile import ProblemFile, ProblemFileError, load
from .io.staging import check_outputs, staged
from .log import Progress, logger
from .options import option_value
from .results import postprocess

PROG = "dolfinx-feti"
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_NOT_CONVERGED = 0, 1, 2, 3
#: Stopped by Ctrl-C (SIGINT): the shells' 128 + signal number.
EXIT_INTERRUPTED = 130


class _Exit(Exception):
    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


class _Parser(argparse.ArgumentParser):
    """An argparse parser that prints on rank 0 only and raises instead of exiting."""

    def _print_message(self, message, file=None):
        if MPI.COMM_WORLD.rank == 0:
            super()._print_message(message, file)

    def exit(self, status=0, message=None):  # noqa: D102
        if message:
            self._print_message(message, sys.stderr)
        raise _Exit(status)


def _parser() -> _Parser:
    p = _Parser(
        prog=PROG,
        description="Solve a contact problem described in a TOML problem file by FETI "
                    "(method 'auto' unless given: FETI-1 or FETI-DP by the measured rule; "
                    "SMALBE/MPRGP). Runs the same under mpirun -n N.",
        epilog="Solver options: any field of dolfinx_feti.SolverOptions as -feti_<name> VALUE "
               "(e.g. -feti_rtol 1e-10 -feti_mprgp_gamma 1 -feti_smalbe_rho 2); these override "
               "the file's [solver] table. Exit status: 0 solved, 1 solve failed (nothing "
               "written), 2 bad command line, problem file or output folder (nothing written), "
               "3 not converged (only the report is written).")
    p.add_argument("problem", type=Path, help="the problem file (TOML)")
    p.add_argument("-o", "--output-dir", type=Path, default=None,
                   help="write the outputs here instead of the file's output.directory")
    v = p.add_mutually_exclusive_group()
    v.add_argument("-v", "--verbose", action="store_true",
                   help="also print every iteration (verbose 2)")
    v.add_argument("-q", "--quiet", action="store_true",
                   help="print nothing but errors (verbose 0)")
    p.add_argument("--check", action="store_true",
                   help="check the problem file and the mesh, then stop (no solve, no output)")
    p.add_argument("--plot", action="store_true",
                   help="also plot the contact pressure when the file asks for no plot")
    p.add_argument("--version", action="store_true", help="print the versions and stop")
    return p


def split_feti_options(argv: Sequence[str]) -> tuple[list[str], list[str]]:
    """Separate ``-feti_<name> [value]`` tokens (for PETSc) from the command's own arguments."""
    own, feti = [], []
    i = 0
    while i < len(argv):
        token = argv[i]
        if token.startswith("-feti_"):
            feti.append(token)
            nxt = option_value(argv, i)
            if nxt is not None:
                feti.append(nxt)
                i += 1
        else:
            own.append(token)
        i += 1
    return own, feti


@contextmanager
def _console(verbose: int):
    """Send the package's log lines to the current stdout for the duration of the command."""
    handler = None
    if verbose > 0 and MPI.COMM_WORLD.rank == 0:
        handler = logging.StreamHandler(sys.stdout)
        handler.setFormatter(logging.Formatter("%(message)s"))
        saved = (list(logger.handlers), logger.level, logger.propagate)
        logger.handlers = [handler]
        logger.setLevel(logging.INFO)
        logger.propagate = False
    try:
        yield
    finally:
        if handler is not None:
            handler.flush()
            logger.handlers, level, logger.propagate = saved[0], saved[1], saved[2]
            logger.setLevel(level)


def _error(message: str) -> None:
    if MPI.COMM_WORLD.rank == 0:
        print(message, file=sys.stderr, flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; returns the exit status (collective over ``MPI.COMM_WORLD``).

    Args:
        argv: The arguments (without the program name); ``sys.argv[1:]`` by default.
    """
    comm = MPI.COMM_WORLD
    argv = list(sys.argv[1:] if argv is None else argv)
    own, feti = split_feti_options(argv)
    if "--version" in own:
        if comm.rank == 0:
            for k, v in postprocess.versions().items():
                print(f"{k} {v}")
        return EXIT_OK
    try:
        args = _parser().parse_args(own)
    except _Exit as e:
        return e.code
    verbose = 2 if args.verbose else 0 if args.quiet else None
    # a communicator of its own for the handshake after Ctrl-C (see _all_stopped)
    handshake = comm.Dup() if comm.size > 1 else None
    try:
        with _console(1 if verbose is None else verbose), _terminate_as_interrupt():
            return _run(args, feti, verbose, comm)
    except KeyboardInterrupt as e:
        # A line instead of the traceback of wherever the solve was; the staged outputs were
        # discarded on the way out (staging.staged), so no new output is left half-written.
        how = e.args[0] if e.args else "Ctrl-C"
        line = f"{PROG}: {args.problem}: interrupted ({how}); stopped, no new output written"
        _error(line)
        if handshake is not None and not _all_stopped(handshake):
            if comm.rank != 0:  # rank 0 may be the one still blocked: say it here
                print(line, file=sys.stderr, flush=True)
            comm.Abort(EXIT_INTERRUPTED)
        return EXIT_INTERRUPTED
    finally:
        if handshake is not None:
            handshake.Free()


#: How long a rank stopped by Ctrl-C waits for the others to stop too (seconds).
INTERRUPT_WAIT = 10.0


def _all_stopped(handshake: MPI.Comm) -> bool:
    """Whether every rank was stopped too (True) or some rank is still blocked (False).

    The signal reaches each rank at its own moment, and Python handles it only between two
    calls into C: a rank blocked in a collective call, waiting for a rank that has already
    stopped, would wait forever (MPICH's mpiexec then waits for it). So the stopped ranks meet
    in a non-blocking barrier on a communicator of its own; if some rank does not arrive
    within :data:`INTERRUPT_WAIT`, the caller aborts the job.
    """
    request = handshake.Ibarrier()
    end = time.monotonic() + INTERRUPT_WAIT
    try:
        while not request.Test():
            if time.monotonic() > end:
                return False
            time.sleep(0.01)
    except KeyboardInterrupt:  # Ctrl-C again: do not wait
        return False
    return True


@contextmanager
def _terminate_as_interrupt():
    """Take SIGTERM as Ctrl-C while the command runs.

    Under mpirun, Ctrl-C reaches the ranks as SIGTERM (Open MPI forwards SIGINT that way),
    which would end them without a word. A handler the caller installed is left alone.
    """
    def handler(signum, frame):
        raise KeyboardInterrupt("Ctrl-C or SIGTERM")

    try:
        previous = signal.getsignal(signal.SIGTERM)
        ours = previous == signal.SIG_DFL
        if ours:
            signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: signals cannot be handled here
        ours = False
    try:
        yield
    finally:
        if ours:
            signal.signal(signal.SIGTERM, previous)


def _run(args, feti: list[str], verbose: int | None, comm: MPI.Comm) -> int:
    t0 = time.perf_counter()
    try:
        pf = load(args.problem, comm, output_dir=args.output_dir, command_line=feti)
        # verbose: 1 by default, then [solver] verbose, then -feti_verbose, then -v / -q
        opts = pf.solver_options(defaults={"verbose": 1}, verbose=verbose)
    except ProblemFileError as e:
        _error(str(e))
        return EXIT_USAGE
    except InputError as e:
        _error(f"{args.problem}: {e}")
        return EXIT_USAGE
    progress = Progress(comm, opts.verbose)
    m = pf.summary()
    types = f", cell types {m['cell_types']}" if "cell_types" in m else ""
    progress.info(f"{pf.path}: {pf.model}, {m['gdim']}D mesh {pf.mesh_source} ({m['nodes']} "
                  f"nodes, {m['cells']} cells{types}, bodies {m['bodies']}), {comm.size} "
                  "rank(s)")
    progress.phase("problem file", time.perf_counter() - t0)
    if args.plot and hasattr(pf.mesh, "parts"):
        _error(f"{PROG}: {pf.path}: --plot: a pressure plot on bodies of several cell types is "
               "not implemented (the forces between meshes are in the report)")
        return EXIT_USAGE
    if args.check:
        progress.info(f"{pf.path}: the problem file is valid")
        return EXIT_OK
    try:  # before the solve: a folder that cannot be written is found now, not after it
        requested = [pf.output.directory / f"{pf.path.stem}_pressure.png"] if args.plot else []
        check_outputs(pf.output.paths() + requested, pf.inputs(), comm)
    except (InputError, SolveError) as e:
        _error(f"{PROG}: {pf.path}: {e}")
        return EXIT_USAGE if isinstance(e, InputError) else EXIT_FAILED

    from .drivers.load_path import solve_path
    from .solver import solve

    steps = None
    try:
        if pf.loading is None:
            solution = solve(pf.problem, comm=comm, options=opts)
        else:  # a load path: the outputs are those of every step
            steps = solve_path(pf.problem_at, range(len(pf.loading)), comm=comm, options=opts,
                               progress=opts.verbose > 0)
            solution = steps[-1]
    except (InputError, SolveError) as e:
        _error(f"{PROG}: {pf.path}: the solve failed: {e}")
        return EXIT_FAILED
    report = solution.report
    if steps is not None:
        from .drivers.path_output import History
        report.converged = all(s.report.converged for s in steps)
        report.extra["loading"] = [dict(History.record(s), factor=f)
                                   for s, f in zip(steps, pf.loading, strict=True)]
    report.extra["problem"] = pf.summary()
    report.extra["versions"] = postprocess.versions()
    mixed = getattr(solution, "meshes", None) is not None  # bodies of several cell types
    report.extra["results"] = solution.results() if mixed else postprocess.results(solution)
    report.extra["command"] = [PROG, str(args.problem), *feti]
    converged = report.converged
    try:
        written = _write_mixed_outputs(pf, solution, converged, comm, progress) if mixed else \
            _write_outputs(pf, solution, args.plot, converged, comm, progress, steps)
    except (InputError, SolveError) as e:
        _error(f"{PROG}: {pf.path}: cannot write the outputs (none was written): {e}")
        return EXIT_FAILED
    if comm.rank == 0 and opts.verbose > 0:
        print(report.summary(), flush=True)
        for path in written:
            print(f"wrote {path}", flush=True)
    if not converged:
        _error(f"{PROG}: {pf.path}: the solver did not converge ({report.reason}); only the "
               "report was written")
        return EXIT_NOT_CONVERGED
    return EXIT_OK


def _write_outputs(pf: ProblemFile, solution, plot_on_request: bool, converged: bool,
                   comm: MPI.Comm, progress: Progress, steps=None) -> list[Path]:
    """Write the outputs, all or none (collective; raises on every rank if one failed).

    A converged run writes every output; a run that did not converge only the report. A load
    path (``steps``: a Solution per step) writes the displacement and the contact fields of
    every step into the XDMF file (the step's index as its time) and the history; the other
    outputs are those of the last step.
    """
    t0 = time.perf_counter()
    out = pf.output
    plot = out.pressure_plot
    if plot is None and plot_on_request and pf.problem.contact:
        from .io.problemfile import PlotSpec

        spec = pf.problem.contact[0]
        group = getattr(spec, "slave", None) or spec.group
        nodes = solution.contact.of(0).x
        along = "xyz"[int(abs(nodes.max(axis=0) - nodes.min(axis=0)).argmax())] \
            if nodes.size else "x"
        plot = PlotSpec(out.directory / f"{pf.path.stem}_pressure.png", 0, group, along)
    with staged(comm) as stage:
        if converged:
            if out.xdmf is not None:
                stage.path(out.xdmf.with_suffix(".h5"))
                if steps is None:
                    solution.write_xdmf(stage.path(out.xdmf))  # collective
                else:
                    _write_series(stage.path(out.xdmf), steps, comm)
            if steps is not None and out.history is not None:
                from .drivers.path_output import History
                history = History(stage.path(out.history), comm)
                for rec in solution.report.extra["loading"]:
                    history.append(rec)
            solution.nodal_values()  # collective: computed (and cached) on every rank first
            solution.cell_subdomains()
            npz = None if out.nodal_values is None else stage.path(out.nodal_values)
            png = None if plot is None else stage.path(plot.path)
            with collective(comm, "outputs"):
                if comm.rank == 0 and npz is not None:
                    postprocess.save_nodal_values(solution, npz)
                if comm.rank == 0 and png is not None:
                    postprocess.plot_pressure(solution, png, plot.contact, plot.along,
                                              title=f"{pf.title}: contact pressure on "
                                                    f"{plot.surface!r}")
        _write_report(stage, out.report, solution, comm)
    progress.phase("output", time.perf_counter() - t0)
    return stage.committed


def _write_mixed_outputs(pf: ProblemFile, solution, converged: bool, comm: MPI.Comm,
                         progress: Progress) -> list[Path]:
    """The outputs of bodies of several cell types (a MixedSolution), all or none.

    One XDMF file per mesh (``<xdmf stem>_<cell type>.xdmf``), the nodal values of every mesh
    in one ``.npz`` (:meth:`MixedSolution.save_nodal_values`) and the JSON report; no pressure
    plot (the file's checks refuse one).
    """
    t0 = time.perf_counter()
    out = pf.output
    with staged(comm) as stage:
        if converged:
            files = out.xdmf_files()
            for p in files:
                stage.path(p)
                stage.path(p.with_suffix(".h5"))
            if files:
                solution.write_xdmf(stage.path(out.xdmf))  # collective: the files above
            for k in range(len(solution.meshes)):
                solution.nodal_values(k)  # collective: cached on every rank first
            npz = None if out.nodal_values is None else stage.path(out.nodal_values)
            with collective(comm, "outputs"):
                if comm.rank == 0 and npz is not None:
                    solution.save_nodal_values(npz)
        _write_report(stage, out.report, solution, comm)
    progress.phase("output", time.perf_counter() - t0)
    return stage.committed


def _write_report(stage, path: Path | None, solution, comm: MPI.Comm) -> None:
    """The JSON report, staged (written by rank 0; collective)."""
    if path is None:
        return
    report = stage.path(path)
    with collective(comm, "outputs"):
        if comm.rank == 0:
            solution.report.save_json(report)


def _write_series(path: Path, steps, comm: MPI.Comm) -> None:
    """The steps of a load path in one XDMF file, each at its index as the time."""
    from .drivers.path_output import TimeSeries
    series = TimeSeries(path, comm)
    try:
        for k, sol in enumerate(steps):
            series.write(sol, float(k))
        series.close()
    finally:
        series.abort()


__all__ = ["main", "split_feti_options"]
