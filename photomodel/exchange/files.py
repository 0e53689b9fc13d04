"""Atomic file writes and PNG encoding shared by every exporter and by the project file.

Each exporter first *encodes* its file(s) to bytes in memory and only then writes them, so a
caller can prepare every output of a command, and a failure or Ctrl-C while encoding leaves the
disk untouched. A write goes to a temporary file in the destination folder, is flushed and
fsynced, and is moved over the destination with :func:`os.replace` (the folder is fsynced too,
so the rename itself survives a crash): a reader sees the old file or the new one, never half of
one. :func:`atomic_write_bytes` is the one such writer of the code base; the project file
(:func:`photomodel.project.io.save_project`) uses it with ``backup=True``.
"""

from __future__ import annotations

import os
import re
import stat
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path

import cv2
import numpy as np

#: Permissions of a new file (``mkstemp`` makes 0600; outputs are ordinary documents).
NEW_FILE_MODE = 0o644
#: A temporary file of an atomic write older than this (seconds) was left behind by a process
#: that was killed mid-write (a write takes seconds at most): :func:`remove_stale_temp_files`.
STALE_TEMP_S = 600.0
#: The name :func:`atomic_write_bytes` gives its temporary file: ``.<name>.<8 random>.tmp``.
_TEMP_NAME = re.compile(r"^\..+\.[a-z0-9_]{8}\.tmp$")


def atomic_write_bytes(path: str | os.PathLike, data: bytes, *, backup: bool = False, mode: int | None = None) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + fsync + :func:`os.replace`).

    Missing parent folders are created; on any error (or interruption) the destination is
    left as it was and the temporary file is removed; an :class:`OSError` (a read-only file
    system, a full disk) names ``path``. Returns the path written.

    Parameters
    ----------
    backup : bool
        keep the file being replaced as ``<path>.bak`` (itself written atomically, with the
        permissions of the file it copies), just before it is replaced.
    mode : int, optional
        permission bits of the new file; default: those of the file it replaces, or
        :data:`NEW_FILE_MODE` for a new file.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise _named(exc, path) from exc
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, _mode_for(path) if mode is None else mode)
        if backup and path.exists():
            _backup(path)
        os.replace(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise _named(exc, path) from exc
        raise
    _fsync_dir(path.parent)
    return path


def _named(exc: OSError, path: Path) -> OSError:
    """``exc`` naming the file that was being written (a full disk's write names no file)."""
    if exc.filename is not None and Path(exc.filename).parent == path.parent:
        return exc
    named = type(exc)(exc.errno, exc.strerror or str(exc), str(path))
    return named


def remove_stale_temp_files(folder: str | os.PathLike, max_age_s: float = STALE_TEMP_S) -> list[Path]:
    """Delete the temporary files that killed atomic writes left in ``folder``; returns them.

    Only files named as :func:`atomic_write_bytes` names its own (``.<name>.<8 random
    characters>.tmp``) and last modified more than ``max_age_s`` seconds ago: a write in
    progress elsewhere is seconds old. A folder that cannot be read or written is left as it is.
    """
    removed = []
    cutoff = time.time() - max_age_s
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        if not _TEMP_NAME.match(entry.name):
            continue
        try:
            if entry.is_file(follow_symlinks=False) and entry.stat().st_mtime < cutoff:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:
            continue  # gone meanwhile, or not ours to delete
    return removed


def _mode_for(path: Path) -> int:
    """Permission bits of the file at ``path`` (kept when it is replaced), else the default."""
    try:
        return stat.S_IMODE(path.stat().st_mode)
    except FileNotFoundError:
        return NEW_FILE_MODE


def _backup(path: Path) -> None:
    """Copy ``path`` to ``path.bak`` atomically, with ``path``'s permissions."""
    bak = path.with_name(path.name + ".bak")
    atomic_write_bytes(bak, path.read_bytes(), mode=_mode_for(path))


def _fsync_dir(folder: Path) -> None:
    """Persist a rename in ``folder`` (POSIX); not possible / not needed on Windows."""
    if os.name != "posix":
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    except OSError:
        pass  # some filesystems refuse fsync on directories; the data file itself is synced
    finally:
        os.close(fd)


def write_files(files: Mapping[str | os.PathLike, bytes]) -> list[Path]:
    """Write several encoded files, each atomically, in the mapping's order.

    Order matters for files that refer to each other: put the referenced file first (texture
    PNG, then MTL, then OBJ) so a reader never finds a reference to a file not yet written.
    """
    return [atomic_write_bytes(p, data) for p, data in files.items()]


def encode_png(image: np.ndarray) -> bytes:
    """PNG bytes of an image.

    Parameters
    ----------
    image : (H, W), (H, W, 1), (H, W, 3) RGB or (H, W, 4) RGBA
        ``uint8``, or float in ``[0, 1]`` (NaN → 0, clipped, rounded to 8 bits). Row 0 is the
        top of the image.

    Returns
    -------
    bytes
        a PNG file (8 bits per channel, grey/RGB/RGBA as given).
    """

    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in (3, 4)) or 0 in img.shape:
        raise ValueError(f"a PNG needs an (H, W), (H, W, 3) or (H, W, 4) image, got shape {img.shape}")
    if img.dtype != np.uint8:
        if not np.issubdtype(img.dtype, np.floating):
            raise ValueError(f"a PNG needs uint8 or float (0..1) pixels, got {img.dtype}")
        img = np.round(np.clip(np.nan_to_num(img, nan=0.0), 0.0, 1.0) * 255.0).astype(np.uint8)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2BGR if img.shape[2] == 3 else cv2.COLOR_RGBA2BGRA)
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(img))
    if not ok:
        raise ValueError(f"OpenCV could not encode a {img.shape} image as PNG")
    return buf.tobytes()


def decode_png(data: bytes) -> np.ndarray:
    """Inverse of :func:`encode_png`: ``(H, W)`` grey or ``(H, W, 3|4)`` RGB(A) ``uint8``."""

    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError("not a PNG (or any image) OpenCV can decode")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB if img.shape[2] == 3 else cv2.COLOR_BGRA2RGBA)
    return img
