"""Folders that refuse writes, for the CLI's write-error tests (``tests/test_cli_permissions.py``,
``tests/test_cli_write_errors.py``): a real read-only bind mount where this machine allows one
(root), else the writers' calls made to fail with the error a disk gives (``EROFS``, ``ENOSPC``)."""

from __future__ import annotations

import builtins
import errno
import io
import os
import shutil
import subprocess
from pathlib import Path


def bind_read_only(folder: Path) -> bool:
    """Bind-mount ``folder`` read-only onto itself (root); False, and nothing mounted, if refused."""
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    if subprocess.run(["mount", "--bind", str(folder), str(folder)], capture_output=True).returncode != 0:
        return False
    if subprocess.run(["mount", "-o", "remount,bind,ro", str(folder)], capture_output=True).returncode != 0:
        subprocess.run(["umount", str(folder)], capture_output=True)
        return False
    return True


def unmount(folder: Path, check: bool = False) -> None:
    """Undo :func:`bind_read_only`."""
    subprocess.run(["umount", str(folder)], capture_output=True, check=check)


def refuse_writes(monkeypatch, folder: Path, code: int = errno.EROFS) -> None:
    """Every write under ``folder`` fails with ``OSError(code)`` from the calls the program's writers
    go through (the atomic writer's ``mkstemp`` uses ``os.open`` and commits with ``os.replace``;
    folders are made with ``os.mkdir``; ``open`` in a writing mode); reads pass."""
    root = Path(folder).absolute()
    real_root = root.resolve()

    def inside(path) -> bool:
        if isinstance(path, int):  # a file descriptor: already open
            return False
        p = Path(os.fsdecode(path)).absolute()
        return p == root or root in p.parents or real_root in p.resolve().parents or p.resolve() == real_root

    def check(path) -> None:
        if inside(path):
            raise OSError(code, os.strerror(code), os.fsdecode(path))

    real_os_open, real_open, real_mkdir, real_replace = os.open, io.open, os.mkdir, os.replace
    write_flags = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC

    def os_open(path, flags, *args, **kwargs):
        if flags & write_flags:
            check(path)
        return real_os_open(path, flags, *args, **kwargs)

    def open_(file, mode="r", *args, **kwargs):
        if isinstance(file, (str, bytes, os.PathLike)) and any(c in mode for c in "wax+"):
            check(file)
        return real_open(file, mode, *args, **kwargs)

    def mkdir(path, *args, **kwargs):
        if not os.path.exists(path):  # an existing folder: EEXIST, as on a disk
            check(path)
        return real_mkdir(path, *args, **kwargs)

    def replace(src, dst, *args, **kwargs):
        check(dst)
        return real_replace(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "open", os_open)
    monkeypatch.setattr(builtins, "open", open_)
    monkeypatch.setattr(io, "open", open_)
    monkeypatch.setattr(os, "mkdir", mkdir)
    monkeypatch.setattr(os, "replace", replace)
