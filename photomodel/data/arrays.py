"""Array files: named numpy arrays in an ``.npz``, written atomically and read back without pickles.

Every derived cache of Face Studio (the generic mesh, ICT's registration, the parsed template and
scan, the scan correspondence) is one such file, named by :func:`photomodel.data.cache.cached_arrays`.
"""

from __future__ import annotations

import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

#: The layout marker written into every file (key ``format``); a file without it, or with another
#: value, reads as missing. What the arrays mean is in the file's name (its code key), not here.
FORMAT = 1


def load_npz(path: Path) -> dict[str, np.ndarray] | None:
    """The arrays of ``path`` (without the ``format`` marker), or None when the file is missing,
    unreadable, truncated or of another layout: the caller builds it again."""
    path = Path(path)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            if "format" not in z.files or int(z["format"]) != FORMAT:
                return None
            return {k: z[k] for k in z.files if k != "format"}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None  # unreadable or torn: rebuild it


def save_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Write ``arrays`` to ``path`` atomically (a temporary file in the same folder, then a rename),
    so a reader never sees half a file; the folder must exist."""
    path = Path(path)
    if "format" in arrays:
        raise ValueError("'format' is the file's layout marker; name the array otherwise")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, format=np.array(FORMAT), **arrays)
        os.chmod(tmp, 0o644)  # mkstemp makes it private; the cache is as readable as its folder
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
