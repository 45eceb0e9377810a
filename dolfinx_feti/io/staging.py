"""All the outputs of a run or none of them, and an output folder checked before the solve.

:func:`check_outputs` runs before any heavy work: the folder exists or can be made, files can
be created in it, no output is an existing folder or one of the run's inputs.

:class:`Staging` makes a set of outputs appear together: every file is written under its own
name into a hidden staging folder beside its target (the same file system, so a rename is
atomic), and :meth:`Staging.commit` moves them all into place. If a move fails, the files
already moved are put back (the old ones restored), so a run that fails while writing leaves
the folder as it was: no new file beside old ones of the same name.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from mpi4py import MPI

from ..errors import InputError, collective

_STAGING_PREFIX = ".dolfinx-feti-staging-"


def check_outputs(outputs: Iterable[Path], inputs: Iterable[Path], comm: MPI.Comm) -> None:
    """Refuse outputs that cannot be written, before the solve (collective; checked on rank 0).

    Args:
        outputs: The files a run would write.
        inputs: The run's input files (the problem file, the mesh): never overwritten.
        comm: The ranks of the run.

    Raises:
        InputError: On every rank, naming the output and why.
    """
    outputs = [Path(p) for p in outputs]
    with collective(comm, "output folder"):
        if comm.rank == 0:
            _check_outputs(outputs, [Path(p) for p in inputs])


def _check_outputs(outputs: list[Path], inputs: list[Path]) -> None:
    sources = {p.resolve() for p in inputs}
    for out in outputs:
        if out.resolve() in sources:
            raise InputError(f"output {str(out)!r} is an input of the run: outputs never "
                             "overwrite inputs; choose another output name or folder")
        if out.is_dir():
            raise InputError(f"output {str(out)!r} is an existing folder, not a file")
    for folder in sorted({p.parent for p in outputs}):
        _check_folder(folder)


def _check_folder(folder: Path) -> None:
    """The folder exists or can be made, and a file can be created in it."""
    existing = folder
    while not existing.exists():
        if existing.parent == existing:
            break
        existing = existing.parent
    if not existing.is_dir():
        raise InputError(f"output folder {str(folder)!r} cannot be made: {str(existing)!r} is a "
                         "file, not a folder")
    try:  # create and remove a file: os.access says yes to root even on a read-only mount
        fd, probe = tempfile.mkstemp(dir=existing, prefix=".dolfinx-feti-probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        what = "folder" if existing == folder else f"folder {str(folder)!r} under"
        raise InputError(f"output {what} {str(existing)!r} is not writable: "
                         f"{e.strerror or e}") from None


class Staging:
    """Outputs written under staging names, made visible together by :meth:`commit`.

    Used through :func:`staged`; the writers write to :meth:`path` of each final path.
    """

    def __init__(self, comm: MPI.Comm) -> None:
        self.comm = comm
        self._files: dict[Path, Path] = {}  # final path -> staged path
        self._dirs: dict[Path, Path] = {}  # target folder -> its staging folder
        self.committed: list[Path] = []  # the files moved into place by commit()

    def path(self, final: str | os.PathLike) -> Path:
        """The staged path of the output ``final`` (collective: all ranks get the same)."""
        final = Path(final)
        folder = final.parent
        if folder not in self._dirs:
            staged = None
            with collective(self.comm, "outputs"):
                if self.comm.rank == 0:
                    folder.mkdir(parents=True, exist_ok=True)
                    staged = Path(tempfile.mkdtemp(dir=folder, prefix=_STAGING_PREFIX))
            self._dirs[folder] = self.comm.bcast(staged, root=0)
        self._files[final] = self._dirs[folder] / final.name
        return self._files[final]

    def commit(self) -> list[Path]:
        """Move every staged file that exists into place, all or none (collective)."""
        moved: list[Path] = []
        with collective(self.comm, "outputs"):
            if self.comm.rank == 0:
                moved = _move_all(self._files)
        self.discard()
        self.committed = self.comm.bcast(moved, root=0)
        return self.committed

    def discard(self) -> None:
        """Remove the staging folders and what is left in them (collective)."""
        with collective(self.comm, "outputs"):
            if self.comm.rank == 0:
                for d in self._dirs.values():
                    shutil.rmtree(d, ignore_errors=True)
        self._dirs.clear()
        self._files.clear()


def _move_all(files: dict[Path, Path]) -> list[Path]:
    """os.replace each staged file onto its final path; on a failure undo the moves done."""
    done: list[tuple[Path, Path | None]] = []  # (final, backup of the old file or None)
    try:
        for final, staged in files.items():
            if not staged.exists():
                continue
            backup = None
            if final.exists():
                backup = staged.with_name(f".old-{final.name}")
                os.replace(final, backup)
            done.append((final, backup))
            os.replace(staged, final)
    except BaseException:
        for final, backup in reversed(done):
            if backup is not None:
                os.replace(backup, final)
            else:
                final.unlink(missing_ok=True)
        raise
    return [final for final, _ in done]


@contextmanager
def staged(comm: MPI.Comm) -> Iterator[Staging]:
    """A :class:`Staging` committed when the block succeeds, discarded when it raises."""
    stage = Staging(comm)
    try:
        yield stage
    except BaseException:
        stage.discard()
        raise
    stage.commit()


__all__ = ["Staging", "check_outputs", "staged"]
