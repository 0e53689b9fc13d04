"""Texture coordinates for export: checks, splitting and merging seams, texture sampling.

Conventions (as :mod:`photomodel.rendering.renderer` and OBJ): ``uv = (0, 0)`` is the bottom-left corner of
the texture image, ``(0, 1)`` its top-left (image row 0), so ``v`` points up; texel ``(row r,
column c)`` of an ``H × W`` image has its centre at ``u = (c + 0.5) / W``, ``v = 1 − (r + 0.5) / H``.

Texture coordinates come either per vertex, ``(n, 2)``, or per face corner, ``(m, 3, 2)`` (row
``i`` of face ``j`` → ``uv[j, i]``). Per-corner coordinates are what a seam needs: a vertex on the
seam of the cylindrical texture of Pighin et al. (2002), §5.2.2, where the angle wraps around,
has one ``u`` in the triangles on one side and another in the triangles on the other.
Formats with a single index per vertex (glTF, and what trimesh builds from an OBJ) then need
the vertex duplicated, one copy per distinct ``uv`` (:func:`split_uv_seams`);
:func:`merge_uv_seams` goes back, e.g. from :class:`photomodel.texturing.cylindrical.CylindricalTexture`'s
seam-split rendering mesh to per-corner coordinates. Textures are sampled clamped to the edge
(as :mod:`photomodel.rendering.renderer` does and as the glTF export declares), so ``uv`` should lie in
``[0, 1]``.
"""

from __future__ import annotations

import numpy as np

from photomodel.rendering.sampling import sample_texture


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
        raise ValueError(
            f"faces refer to vertex {f.min() if f.min() < 0 else f.max()}, but there are only {len(v)} vertices"
        )
    return v, f


def check_uv(uv, n_vertices: int, n_faces: int) -> np.ndarray:
    """Validated texture coordinates: ``(n, 2)`` per vertex or ``(m, 3, 2)`` per corner, float64."""
    t = np.asarray(uv, dtype=float)
    if not (t.shape == (n_vertices, 2) or t.shape == (n_faces, 3, 2)):
        raise ValueError(
            f"uv must be per vertex ({n_vertices}, 2) or per face corner ({n_faces}, 3, 2), got shape {t.shape}"
        )
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


def split_uv_seams(n_vertices: int, faces: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


def merge_uv_seams(faces: np.ndarray, source: np.ndarray, split_faces: np.ndarray, split_uv: np.ndarray) -> np.ndarray:
    """Per-corner texture coordinates of ``faces`` from a seam-split copy of the mesh.

    The inverse of :func:`split_uv_seams`, also when the split mesh lists the triangles in
    another order (as :attr:`photomodel.texturing.cylindrical.CylindricalTexture.seam_faces` does).

    Parameters
    ----------
    faces : (m, 3) int, the triangles over the original vertices.
    source : (n',) int, original vertex of each split vertex.
    split_faces : (m, 3) int, the same triangles over the split vertices, any order, same
        corner order within each triangle.
    split_uv : (n', 2) float, texture coordinates of the split vertices.

    Returns
    -------
    (m, 3, 2) float
    """
    faces = np.asarray(faces, dtype=np.int64)
    split_faces = np.asarray(split_faces, dtype=np.int64)
    tri = np.asarray(source, dtype=np.int64)[split_faces]
    if tri.shape != faces.shape:
        raise ValueError(f"the split mesh has {len(tri)} triangles, the mesh {len(faces)}")
    corner = np.asarray(split_uv, dtype=float)[split_faces]
    if np.array_equal(tri, faces):
        return corner
    ia, ib = np.lexsort(faces.T[::-1]), np.lexsort(tri.T[::-1])
    if not np.array_equal(faces[ia], tri[ib]):
        raise ValueError("the split mesh's triangles are not the mesh's triangles")
    out = np.empty_like(corner)
    out[ia] = corner[ib]
    return out


def vertex_colors_from_texture(texture: np.ndarray, faces: np.ndarray, uv: np.ndarray, n_vertices: int) -> np.ndarray:
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
        col = np.stack([np.bincount(idx, corner[:, c], minlength=n_vertices) for c in range(corner.shape[1])], axis=1)
        col = np.divide(col, count[:, None], out=np.zeros_like(col), where=count[:, None] > 0)
    return np.clip(np.round(col * scale), 0, 255).astype(np.uint8)
