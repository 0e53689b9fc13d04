"""Texture coordinates for export: checks, the cylindrical seam, per-corner → per-vertex, sampling.

Conventions (as :mod:`photomodel.render` and OBJ): ``uv = (0, 0)`` is the bottom-left corner of
the texture image, ``(0, 1)`` its top-left (image row 0), so ``v`` points up; texel ``(row r,
column c)`` of an ``H × W`` image has its centre at ``u = (c + 0.5) / W``, ``v = 1 − (r + 0.5) / H``.

Texture coordinates come either per vertex, ``(n, 2)``, or per face corner, ``(m, 3, 2)`` (row
``i`` of face ``j`` → ``uv[j, i]``). Per-corner coordinates are what a seam needs: a vertex on the
seam of the cylindrical texture of Pighin et al. (2002), §5.2.2, where ``u`` wraps from 1 back
to 0, has one ``u`` in the triangles on one side and another in the triangles on the other.
Formats with a single index per vertex (glTF, and what trimesh builds from an OBJ) then need
the vertex duplicated, one copy per distinct ``uv`` (:func:`split_uv_seams`).
"""

from __future__ import annotations

import numpy as np


def check_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """Validated ``(vertices (n, 3) float64, faces (m, 3) int64)``; ``ValueError`` naming the problem."""
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise ValueError(f"vertices must be a non-empty (n, 3) array, got shape {v.shape}")
    if not np.isfinite(v).all():
        raise ValueError(f"vertices contain NaN or infinity (first at row {np.argwhere(~np.isfinite(v))[0, 0]})")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise ValueError(f"faces must be a non-empty (m, 3) array of triangles, got shape {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        if not np.array_equal(f, np.round(f)):
            raise ValueError(f"faces must hold integer vertex indices, got {f.dtype} values")
    f = f.astype(np.int64)
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError(f"faces refer to vertex {f.min() if f.min() < 0 else f.max()}, "
                         f"but there are only {len(v)} vertices")
    return v, f


def check_uv(uv, n_vertices: int, n_faces: int) -> np.ndarray:
    """Validated texture coordinates: ``(n, 2)`` per vertex or ``(m, 3, 2)`` per corner, float64."""
    t = np.asarray(uv, dtype=float)
    if not (t.shape == (n_vertices, 2) or t.shape == (n_faces, 3, 2)):
        raise ValueError(f"uv must be per vertex ({n_vertices}, 2) or per face corner ({n_faces}, 3, 2), "
                         f"got shape {t.shape}")
    if not np.isfinite(t).all():
        raise ValueError("uv contains NaN or infinity")
    return t


def check_texture(texture) -> np.ndarray:
    """A texture image as given, checked: ``(H, W, 3|4)`` uint8 or float in [0, 1], row 0 = top."""
    img = np.asarray(texture)
    if img.ndim != 3 or img.shape[2] not in (3, 4) or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"texture must be an (H, W, 3) RGB or (H, W, 4) RGBA image, got shape {img.shape}")
    if img.dtype != np.uint8 and not np.issubdtype(img.dtype, np.floating):
        raise ValueError(f"texture pixels must be uint8 or float in [0, 1], got {img.dtype}")
    return img


def corner_uvs(faces: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """``(m, 3, 2)`` per-corner texture coordinates from per-vertex ``(n, 2)`` or per-corner ones."""
    uv = np.asarray(uv, dtype=float)
    return uv if uv.ndim == 3 else uv[np.asarray(faces)]


def unwrap_cylindrical_seam(faces: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Per-corner coordinates in which no triangle jumps across the ``u`` seam of a cylinder.

    A cylindrical texture (§5.2.2) has ``u`` = angle around the axis / 2π in ``[0, 1)``; a
    triangle straddling the cut has corners near ``u = 1`` and near ``u = 0``, and would
    otherwise be stretched backwards across the whole texture. Such a triangle is recognised
    by a ``u`` span over one half (no real triangle covers half of the turn) and its corners
    with ``u < 0.5`` are moved up by one period, into ``(1, 1.5)``.

    Parameters
    ----------
    faces : (m, 3) int
    uv : (n, 2) per-vertex or (m, 3, 2) per-corner float, ``u`` periodic with period 1.

    Returns
    -------
    (m, 3, 2) float
        per-corner coordinates; only seam triangles differ from ``uv``. Their ``u > 1`` need
        the texture sampled with *repeat* wrapping in ``u`` — glTF's default, set explicitly by
        :mod:`photomodel.exchange.gltf`; OBJ viewers repeat unless an MTL map says ``-clamp on``.
    """
    c = corner_uvs(faces, uv).copy()
    u = c[:, :, 0]
    seam = (u.max(axis=1) - u.min(axis=1)) > 0.5
    low = seam[:, None] & (u < 0.5)
    u[low] += 1.0
    return c


def split_uv_seams(n_vertices: int, faces: np.ndarray, uv: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One vertex per distinct ``(vertex, uv)`` pair, for formats with a single index per vertex.

    Parameters
    ----------
    n_vertices : int, ``n``
    faces : (m, 3) int
    uv : (n, 2) per-vertex or (m, 3, 2) per-corner float

    Returns
    -------
    source : (n',) int
        the original vertex of each output vertex. ``source[:n] == arange(n)`` — every
        original vertex keeps its index (so per-vertex data, e.g. blend-shape offsets, index
        the output directly) — and the ``n' − n`` copies for seams follow, in vertex order.
    uv_out : (n', 2) float
        one coordinate per output vertex; ``(0, 0)`` for an original vertex that no face uses
        (only possible with per-corner input, which gives such a vertex no coordinate).
    faces_out : (m, 3) int
        the triangles over the output vertices (same order and winding).
    """
    faces = np.asarray(faces, dtype=np.int64)
    uv = np.asarray(uv, dtype=float)
    n = int(n_vertices)
    if uv.ndim == 2:
        return np.arange(n), uv.copy(), faces.copy()
    rows = np.column_stack([faces.reshape(-1).astype(float), uv.reshape(-1, 2)])
    unique, inverse = np.unique(rows, axis=0, return_inverse=True)  # sorted by vertex, then u, v
    vertex = unique[:, 0].astype(np.int64)
    first = np.r_[True, vertex[1:] != vertex[:-1]]  # the first uv of each vertex keeps its index
    index = np.where(first, vertex, n + np.cumsum(~first) - 1)
    source = np.concatenate([np.arange(n), vertex[~first]])
    uv_out = np.zeros((len(source), 2))
    uv_out[index] = unique[:, 1:]
    return source, uv_out, index[inverse.reshape(-1)].reshape(faces.shape)


def sample_texture(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear texture look-up at ``uv``, repeating in ``u`` and clamped in ``v``.

    Parameters
    ----------
    texture : (H, W, C) uint8 or float, row 0 = top (``v = 1``).
    uv : (..., 2) float, ``v`` up.

    Returns
    -------
    (..., C) float
        colours in the texture's units (``0..255`` for ``uint8``).
    """
    img = np.asarray(texture)
    H, W = img.shape[:2]
    uv = np.asarray(uv, dtype=float)
    x = uv[..., 0] * W - 0.5  # texel centres at integers
    y = (1.0 - uv[..., 1]) * H - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    xa, xb = np.mod(x0, W), np.mod(x0 + 1, W)
    ya, yb = np.clip(y0, 0, H - 1), np.clip(y0 + 1, 0, H - 1)
    img = img.astype(float)
    top = img[ya, xa] * (1 - fx) + img[ya, xb] * fx
    bottom = img[yb, xa] * (1 - fx) + img[yb, xb] * fx
    return top * (1 - fy) + bottom * fy


def vertex_colors_from_texture(texture: np.ndarray, faces: np.ndarray, uv: np.ndarray,
                               n_vertices: int) -> np.ndarray:
    """Per-vertex colour: the texture at the vertex's ``uv`` (mean over its corners if per-corner).

    Parameters
    ----------
    texture : (H, W, C) uint8 or float in [0, 1]
    faces : (m, 3) int
    uv : (n, 2) per-vertex or (m, 3, 2) per-corner float
    n_vertices : int

    Returns
    -------
    (n, C) uint8
        a vertex that no face uses (per-corner input) is black.
    """
    img = np.asarray(texture)
    scale = 1.0 if img.dtype == np.uint8 else 255.0
    uv = np.asarray(uv, dtype=float)
    if uv.ndim == 2:
        col = sample_texture(img, uv)
    else:
        corner = sample_texture(img, uv.reshape(-1, 2))
        idx = np.asarray(faces).reshape(-1)
        count = np.bincount(idx, minlength=n_vertices).astype(float)
        col = np.stack([np.bincount(idx, corner[:, c], minlength=n_vertices) for c in range(corner.shape[1])],
                       axis=1)
        col = np.divide(col, count[:, None], out=np.zeros_like(col), where=count[:, None] > 0)
    return np.clip(np.round(col * scale), 0, 255).astype(np.uint8)
