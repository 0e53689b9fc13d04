"""Atomic file writes and PNG encoding shared by every exporter.

Each exporter first *encodes* its file(s) to bytes in memory and only then writes them, so a
caller can prepare every output of a command, and a failure or Ctrl-C while encoding leaves the
disk untouched. A write goes to a temporary file in the destination folder, is flushed and
fsynced, and is moved over the destination with :func:`os.replace`: a reader sees the old file
or the new one, never half of one.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + fsync + :func:`os.replace`).

    Missing parent folders are created; on any error (or interruption) the destination is
    left as it was and the temporary file is removed. Returns the path written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes 0600; exports are ordinary documents
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


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
    import cv2  # local: encoding is the only thing here that needs OpenCV

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
    import cv2

    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ValueError("not a PNG (or any image) OpenCV can decode")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB if img.shape[2] == 3 else cv2.COLOR_BGRA2RGBA)
    return img
