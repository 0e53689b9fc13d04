"""Face Studio's cache folder and the derived results kept in it, each under a key of the code that
built it (:func:`photomodel.data.keys.code_key`).

A result lives at ``<cache>/<stem>-<key>.npz`` (:func:`cached_arrays`) or ``<parent>/<key>/``
(:func:`cached_folder`). A new key (the code or the inputs changed) builds a new entry beside the
old ones; of each family only the :data:`KEEP` most recently used entries stay, so two versions of
the code (two branches, an upgrade) can share one cache while the folder does not grow with every
edit. A hit marks its entry used (its modification time).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from photomodel.data.arrays import load_npz, save_npz

#: Environment variable naming Face Studio's cache folder.
ENV_CACHE = "FACESTUDIO_CACHE"
#: Entries kept per family of derived results (the most recently used).
KEEP = 3


def cache_dir() -> Path:
    """Face Studio's cache folder (not created): ``$FACESTUDIO_CACHE``, else
    ``$XDG_CACHE_HOME/facestudio``, else ``~/.cache/facestudio``."""
    if os.environ.get(ENV_CACHE):
        return Path(os.environ[ENV_CACHE]).expanduser()
    if os.environ.get("XDG_CACHE_HOME"):
        return Path(os.environ["XDG_CACHE_HOME"]).expanduser() / "facestudio"
    return Path.home() / ".cache" / "facestudio"


def cached_arrays(
    stem: str,
    key: str,
    build: Callable[[], dict[str, np.ndarray]],
    *,
    folder: Path | None = None,
    legacy: tuple[str, ...] = (),
) -> dict[str, np.ndarray]:
    """The arrays of ``<folder>/<stem>-<key>.npz``, built by ``build()`` and saved when missing.

    Parameters
    ----------
    stem : str
        the family's name, e.g. ``"generic_mesh"``.
    key : str
        :func:`~photomodel.data.keys.code_key` of the builder and its inputs.
    build : callable
        makes the arrays (called only on a miss).
    folder : Path, optional
        default :func:`cache_dir` (created when needed).
    legacy : file names in ``folder`` written by earlier versions under another scheme, removed
        once the new entry is saved.
    """
    folder = cache_dir() if folder is None else Path(folder)
    path = folder / f"{stem}-{key}.npz"
    arrays = load_npz(path)
    if arrays is not None:
        _mark_used(path)
        return arrays
    arrays = build()
    folder.mkdir(parents=True, exist_ok=True)
    save_npz(path, arrays)
    _prune(folder.glob(f"{stem}-*.npz"), keep=path)
    for name in legacy:
        (folder / name).unlink(missing_ok=True)
    return arrays


def cached_folder(parent: Path, key: str, build: Callable[[Path], None]) -> Path:
    """The folder ``<parent>/<key>``, made by ``build(staging)`` into a fresh staging folder and
    renamed into place when missing (a reader never sees half of it; when another process
    finishes first, its copy is kept).

    Parameters
    ----------
    parent : Path
        the family's folder, e.g. ``cache_dir() / "fitted_james"`` (created when needed).
    key : str
        :func:`~photomodel.data.keys.code_key` of the builder and its inputs.
    build : callable
        fills the empty folder it is given.
    """
    parent = Path(parent)
    target = parent / key
    if target.is_dir():
        _mark_used(target)
        return target
    parent.mkdir(parents=True, exist_ok=True)
    staged = Path(tempfile.mkdtemp(prefix=".staging-", dir=parent))
    try:
        build(staged)
        try:
            os.replace(staged, target)
        except OSError:  # another process finished first: use its copy
            shutil.rmtree(staged, ignore_errors=True)
    except BaseException:
        shutil.rmtree(staged, ignore_errors=True)
        raise
    _prune((p for p in parent.iterdir() if p.is_dir() and not p.name.startswith(".")), keep=target)
    return target


def _mark_used(path: Path) -> None:
    try:
        os.utime(path)
    except OSError:  # a read-only cache still serves
        pass


def _prune(entries, keep: Path) -> None:
    """Remove all but the :data:`KEEP` most recently used of ``entries`` (``keep`` always stays)."""

    def used(p: Path) -> float:
        try:
            return p.stat().st_mtime
        except OSError:
            return 0.0

    others = sorted((p for p in entries if p != keep), key=used, reverse=True)
    for old in others[KEEP - 1 :]:
        if old.is_dir():
            shutil.rmtree(old, ignore_errors=True)
        else:
            old.unlink(missing_ok=True)
