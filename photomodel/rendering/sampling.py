"""Bilinear look-ups on the CPU: images at pixel positions, textures at texture coordinates.

* :func:`sample_image` — an image (photo, depth map, feather map) at sub-pixel positions, pixel
  centres at integers (:mod:`photomodel.camera`); what texturing and visibility read photos and
  maps with.
* :func:`sample_texture` — a texture at ``uv`` as the renderer's shaders sample it (``v`` up,
  clamped to the edge): the tracker's face model (colours at the pixels it covers) and the
  exports (vertex colours).

Both are one ``cv2.remap`` (bilinear): OpenCV 5 (the pinned version) interpolates with the float
weights of the float32 sample positions; OpenCV 4 rounded them to 1/32 pixel.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["sample_image", "sample_texture"]

# cv2.remap refuses destination images with a side of 32767 or more, so point lists are
# folded into rows of this many samples.
_REMAP_ROW = 4096


def sample_image(image: np.ndarray, uv: np.ndarray, *, border_value: float | None = 0.0) -> np.ndarray:
    """Bilinear samples of ``image`` at sub-pixel positions (``cv2.remap``).

    Parameters
    ----------
    image : (H, W) or (H, W, C) uint8 or float32
        pixel centres at integer coordinates (:mod:`photomodel.camera`); other dtypes are
        read as float32.
    uv : (n, 2) float
        positions ``(u, v)`` in pixels, ``u`` right, ``v`` down.
    border_value : float or None
        value of samples whose 2×2 neighbourhood leaves the image (constant border); None
        clamps to the edge instead (the border pixels are repeated).

    Returns
    -------
    (n,) or (n, C), dtype of ``image`` (float32 for other dtypes)
    """

    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.float32):
        img = img.astype(np.float32)
    uv = np.asarray(uv, dtype=np.float32).reshape(-1, 2)
    n = len(uv)
    C = img.shape[2] if img.ndim == 3 else 0
    if n == 0:
        return np.zeros((0, C) if C else (0,), img.dtype)
    rows = -(-n // _REMAP_ROW)
    pad = rows * _REMAP_ROW - n
    maps = np.concatenate([uv, np.full((pad, 2), -10.0, np.float32)]).reshape(rows, _REMAP_ROW, 2)
    if border_value is None:
        out = cv2.remap(img, maps, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    else:
        border = (float(border_value),) * 4
        out = cv2.remap(img, maps, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=border)
    return out.reshape(rows * _REMAP_ROW, *((C,) if C else ()))[:n]


def sample_texture(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear texture look-up at ``uv``, as the renderer samples: ``v`` up, texel ``(row r,
    column c)`` of an ``Ht × Wt`` image centred at ``u = (c + 0.5) / Wt``, ``v = 1 − (r + 0.5) / Ht``,
    clamped to the edge.

    Parameters
    ----------
    texture : (Ht, Wt, C) uint8 or float, row 0 = top (``v = 1``).
    uv : (..., 2) float, ``v`` up; texel positions are computed in its precision (float32 stays
        float32).

    Returns
    -------
    (..., C) float32
        colours in the texture's units (``0..255`` for ``uint8``), not rounded.
    """
    img = np.asarray(texture)
    if img.dtype != np.float32:
        img = img.astype(np.float32)
    uv = np.asarray(uv)
    if not np.issubdtype(uv.dtype, np.floating):
        uv = uv.astype(float)
    Ht, Wt = img.shape[:2]
    x = uv[..., 0] * Wt - 0.5  # texel centres at integers
    y = (1.0 - uv[..., 1]) * Ht - 0.5
    out = sample_image(img, np.stack([x, y], axis=-1).reshape(-1, 2), border_value=None)
    return out.reshape(uv.shape[:-1] + out.shape[1:])
