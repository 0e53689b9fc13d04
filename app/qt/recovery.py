"""Recovery files of never-saved projects: where they live, how they are named and locked.

Each running studio autosaves a never-saved project to its *own* file,
``untitled-<pid>-<random>.recovery.facestudio.json``, and holds a :class:`QLockFile`
(``<file>.lock``) on it from before the first write until the project is saved, discarded or the
window closes. At start-up :meth:`~app.qt.main_window.MainWindow.offer_recovery` offers every
recovery file in the folder whose lock no live process holds (a crashed instance's lock is stale:
Qt checks its pid), so two studios running at once never overwrite, delete or recover each
other's data.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path

from PySide6.QtCore import QLockFile, QStandardPaths

from photomodel.project import FILE_SUFFIX

#: How the recovery file of a never-saved project ends; every such file in the recovery folder is
#: offered at start-up unless a running studio holds its lock.
RECOVERY_SUFFIX = ".recovery" + FILE_SUFFIX
#: The single recovery file of studios before one file per instance (still offered at start-up).
RECOVERY_NAME = "untitled" + RECOVERY_SUFFIX


def default_recovery_folder() -> Path:
    """Where never-saved projects are autosaved: ``QStandardPaths.AppDataLocation`` (else ``~/.facestudio``)."""
    folder = QStandardPaths.writableLocation(QStandardPaths.StandardLocation.AppDataLocation)
    return Path(folder or Path.home() / ".facestudio")


def default_recovery_file(folder=None) -> Path:
    """A new, unique recovery file for this instance: ``<folder>/untitled-<pid>-<8 hex>.recovery.facestudio.json``.

    ``folder`` defaults to :func:`default_recovery_folder`. The pid says which process wrote it
    (for a person looking at the folder); the random part keeps two windows of one process apart.
    """
    folder = Path(folder) if folder is not None else default_recovery_folder()
    return folder / f"untitled-{os.getpid()}-{uuid.uuid4().hex[:8]}{RECOVERY_SUFFIX}"


def recovery_files(folder) -> list[Path]:
    """The recovery files in ``folder`` (``*.recovery.facestudio.json``), newest first; [] if none."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    found = [f for f in folder.glob("*" + RECOVERY_SUFFIX) if f.is_file()]
    return sorted(found, key=lambda f: (-f.stat().st_mtime, f.name))


def lock_recovery_file(path) -> QLockFile | None:
    """Take the lock ``<path>.lock`` of a recovery file; None if a running process holds it.

    A lock left by a process that is no longer running is stale and taken over. Locks never go
    stale by age (``setStaleLockTime(0)``): a studio may run for days.
    """
    lock = QLockFile(str(path) + ".lock")
    lock.setStaleLockTime(0)
    return lock if lock.tryLock(0) else None
