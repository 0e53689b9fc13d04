"""What the ``facestudio`` commands share: argument types, write checks, Ctrl-C around a commit, tables.

Writes: every command calls :func:`check_writable` on each folder it will write **before** its
long work, so that a read-only folder or file system (EROFS), a full disk (ENOSPC) or a refused
permission is an error naming the folder within a second, not a traceback after minutes. A write
that fails later anyway is reported by :func:`write_error_message` with the path, and
:func:`new_outputs` removes what the command had created so far, so nothing half-written stays.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import shlex
import shutil
import signal
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from photomodel.errors import ProjectError
from photomodel.project import load_project

#: The errors of a write the disk refuses: read-only, full, over quota, too big, not allowed.
WRITE_ERRNOS = frozenset({errno.EROFS, errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EACCES, errno.EPERM})
#: Free space a command needs before it starts (bytes): less is a full disk.
MIN_FREE_BYTES = 1 << 20
_REASONS = {
    errno.EROFS: "the file system is read-only",
    errno.ENOSPC: "the disk is full",
    errno.EDQUOT: "the disk quota is used up",
    errno.EFBIG: "the file is too large for the file system",
}


def write_error_message(exc: OSError, where: str | os.PathLike | None = None) -> str:
    """What a user reads when the disk refuses a write: the folder (or file), why, and what to do."""
    path = Path(where) if where is not None else (Path(exc.filename) if exc.filename else None)
    if path is not None and (path.is_file() or (not path.exists() and path.suffix)):
        path = path.parent  # a file: its folder is what to make writable
    folder = f"in {path}" if path is not None else "the results"
    why = _REASONS.get(exc.errno) or exc.strerror or str(exc)
    return (
        f"could not write {folder}: {why}; make the folder writable or free space on its disk (or "
        f"copy the project to a folder you can write to) and run the command again"
    )


def check_writable(*folders: str | os.PathLike | None, need_bytes: int = MIN_FREE_BYTES) -> None:
    """Raise :class:`~photomodel.errors.ProjectError` naming the first of ``folders`` that cannot be written to.

    A folder need not exist yet: its nearest existing parent must take a new file (a probe file
    is created there and removed, which is what a read-only file system or a permission
    refuses) and have ``need_bytes`` free. Nothing is left behind. ``None`` entries are skipped.
    """
    for folder in folders:
        if folder is None:
            continue
        folder = Path(folder).absolute()
        existing = folder
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        if not existing.is_dir():
            raise ProjectError(f"cannot write in {folder}: {existing} is a file, not a folder")
        try:
            fd, probe = tempfile.mkstemp(prefix=".facestudio-probe.", dir=existing)
            os.close(fd)
            os.unlink(probe)
            free = shutil.disk_usage(existing).free
        except OSError as exc:
            raise ProjectError(write_error_message(exc, folder)) from exc
        if free < need_bytes:
            raise ProjectError(write_error_message(OSError(errno.ENOSPC, "No space left on device"), folder))


def check_file_writable(*files: str | os.PathLike | None) -> None:
    """:func:`check_writable` on the folders of ``files`` (``None`` entries skipped)."""
    check_writable(*(None if f is None else Path(f).absolute().parent for f in files))


@contextlib.contextmanager
def new_outputs(paths: Iterable[str | os.PathLike]) -> Iterator[None]:
    """Remove those of ``paths`` (files or folders) that did not exist before, if the block fails.

    The outputs of a command that stops half-way (a write refused, Ctrl-C) are then not left
    half-written; what existed before the command is never removed.
    """
    fresh = [Path(p) for p in paths if not Path(p).exists()]
    try:
        yield
    except BaseException:
        for p in fresh:
            if p.is_dir():
                shutil.rmtree(p, ignore_errors=True)
            elif p.exists():
                with contextlib.suppress(OSError):
                    p.unlink()
        raise


@contextlib.contextmanager
def new_files_in(folder: str | os.PathLike) -> Iterator[None]:
    """Remove the files that appear in ``folder`` during the block, if it fails (a fit's meshes,
    whose names are made as they are written): :func:`new_outputs` for outputs not named ahead."""
    folder = Path(folder)
    before = set(folder.iterdir()) if folder.is_dir() else set()
    with new_outputs([folder] if not folder.exists() else []):
        try:
            yield
        except BaseException:
            for p in set(folder.iterdir()) - before if folder.is_dir() else ():
                with contextlib.suppress(OSError):
                    p.unlink()
            raise


@contextlib.contextmanager
def sigint_deferred():
    """Hold Ctrl-C while the outputs are being committed; yields a list that records it."""
    caught = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield caught
    finally:
        signal.signal(signal.SIGINT, previous)


def positive_int(text: str) -> int:
    """An argument that must be a whole number of at least 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is not at least 1")
    return value


def expression_names(text: str | None) -> list[str] | None:
    """``--expressions a,b`` as a list of names (``None`` when not given)."""
    return None if text is None else [n.strip() for n in text.split(",") if n.strip()]


def check_expression_names(project_path: str | os.PathLike, names: list[str] | None) -> None:
    """Each of ``names`` an expression of the project (which must load); a ProjectError naming the
    first unknown one otherwise, before any work."""
    if names:
        project = load_project(project_path)
        for name in names:
            project.expression(name)


def column_width(values: Iterable[str], header: str, at_most: int = 60) -> int:
    """The width of a table column: its longest value or header (a name longer than
    ``at_most`` widens only its own row)."""
    return min(max([len(header), *(len(str(v)) for v in values)]), at_most)


def quoted(*words: str | os.PathLike) -> str:
    """A command line to copy and paste: each word quoted for the shell where it needs to be."""
    return " ".join(shlex.quote(str(w)) for w in words)


def add_json_flag(parser: argparse.ArgumentParser, what: str = "the summary") -> None:
    parser.add_argument("--json", action="store_true", help=f"print one JSON object instead of {what}")


__all__ = [
    "MIN_FREE_BYTES",
    "WRITE_ERRNOS",
    "add_json_flag",
    "check_expression_names",
    "check_file_writable",
    "check_writable",
    "column_width",
    "expression_names",
    "new_files_in",
    "new_outputs",
    "positive_int",
    "quoted",
    "sigint_deferred",
    "write_error_message",
]
