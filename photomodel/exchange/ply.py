"""PLY with a colour per vertex — the textured face for point/mesh tools without texture support.

Binary little-endian PLY: ``x y z`` as float32 in the caller's units (Face Studio: mm, head frame
of :mod:`photomodel.camera`; float32 keeps 2e-5 mm at 200 mm), ``red green blue`` as uchar,
triangles as ``list uchar int``. The vertex order is the mesh's, unchanged (no seam copies: a
colour per vertex needs none). A ``comment units`` line records the unit. The colour of a
vertex is either given or sampled bilinearly from the texture at its ``uv``
(:func:`photomodel.exchange.uv.vertex_colors_from_texture`); with per-corner ``uv`` the mean
over the vertex's corners (they differ only across a seam, where they name the same texel).

Written with numpy rather than trimesh's exporter so the file carries exactly RGB (trimesh adds
an alpha channel) and the unit comment; trimesh, MeshLab and Blender read it back.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from photomodel.exchange.files import atomic_write_bytes
from photomodel.exchange.uv import check_mesh, check_texture, check_uv, vertex_colors_from_texture


def encode_colored_ply(vertices, faces, colors=None, *, uv=None, texture=None, units: str = "mm") -> bytes:
    """Encode a mesh with per-vertex RGB colours as binary PLY.

    Parameters
    ----------
    vertices : (n, 3) float
    faces : (m, 3) int
    colors : (n, 3) uint8, or float in [0, 1], optional
        the colours; if omitted they are sampled from ``texture`` at ``uv``.
    uv : (n, 2) or (m, 3, 2) float, ``v`` up; with ``texture``.
    texture : (H, W, 3|4) uint8 or float in [0, 1], row 0 = top; with ``uv``.
    units : str, written as ``comment units <units>``.

    Returns
    -------
    bytes
    """
    v, f = check_mesh(vertices, faces)
    if colors is None:
        if uv is None or texture is None:
            raise ValueError("give per-vertex colors, or uv and a texture to sample them from")
        rgb = vertex_colors_from_texture(check_texture(texture), f, check_uv(uv, len(v), len(f)), len(v))[:, :3]
    else:
        c = np.asarray(colors)
        if c.shape != (len(v), 3):
            raise ValueError(f"colors must be ({len(v)}, 3) RGB per vertex, got shape {c.shape}")
        if c.dtype == np.uint8:
            rgb = c
        elif np.issubdtype(c.dtype, np.floating):
            rgb = np.round(np.clip(np.nan_to_num(c, nan=0.0), 0.0, 1.0) * 255.0).astype(np.uint8)
        else:
            raise ValueError(f"colors must be uint8 or float in [0, 1], got {c.dtype}")
    if any(ch in units for ch in "\r\n"):
        raise ValueError("units must be a single line")

    header = (
        "ply\n"
        "format binary_little_endian 1.0\n"
        "comment Face Studio mesh with vertex colours\n"
        f"comment units {units}\n"
        f"element vertex {len(v)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        f"element face {len(f)}\n"
        "property list uchar int vertex_indices\n"
        "end_header\n"
    ).encode("ascii")
    vert = np.empty(len(v), dtype=[("p", "<f4", 3), ("c", "u1", 3)])
    vert["p"] = v
    vert["c"] = rgb
    face = np.empty(len(f), dtype=[("n", "u1"), ("i", "<i4", 3)])
    face["n"] = 3
    face["i"] = f
    return header + vert.tobytes() + face.tobytes()


def write_colored_ply(
    path: str | os.PathLike, vertices, faces, colors=None, *, uv=None, texture=None, units: str = "mm"
) -> Path:
    """:func:`encode_colored_ply` written atomically to ``path`` (``*.ply``); returns the path."""
    path = Path(path)
    if path.suffix.lower() != ".ply":
        raise ValueError(f"{path}: a PLY file name must end in .ply")
    return atomic_write_bytes(path, encode_colored_ply(vertices, faces, colors, uv=uv, texture=texture, units=units))
