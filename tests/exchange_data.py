"""Test data shared by the exchange tests (test_exchange_*.py): a seamed sphere and a texture whose
every texel has its own colour, made here with trimesh and numpy, independently of the writers.

The test mesh is a sphere of radius 80 mm (head-sized) with a cylindrical texture mapping
``u = (atan2(x, z) + π) / 2π``, so its ``u`` seam runs down the back (``z < 0``) as on a face;
:func:`seam_corners` gives the per-corner coordinates of a seamed texture atlas.
Tolerances: OBJ writes 6 decimals (≤ 5e-7 mm rounding); PLY and glTF store float32, whose
spacing at 80 mm / 0.08 m is ~8e-6 mm; :data:`POS_TOL_MM` = 1e-4 mm covers both with margin and is
far below any geometric accuracy we care about.
"""

from __future__ import annotations

import numpy as np
import pygltflib
import trimesh

from photomodel.camera import orbit_camera
from photomodel.exchange.uv import split_uv_seams
from photomodel.rendering.renderer import get_renderer

POS_TOL_MM = 1e-4  # see module docstring
RADIUS = 80.0


def sphere():
    """(vertices (n, 3) mm, faces (m, 3), per-vertex uv (n, 2)) of the icosphere described above."""
    s = trimesh.creation.icosphere(3, radius=RADIUS)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    u = (np.arctan2(v[:, 0], v[:, 2]) + np.pi) / (2 * np.pi) % 1.0
    uv = np.column_stack([u, (v[:, 1] + RADIUS) / (2 * RADIUS)])
    return v, f, uv


def texture():
    """64×128 texture whose every texel has a unique colour (red = column·2, green = row·4 … )."""
    H, W = 64, 128
    r, c = np.mgrid[0:H, 0:W]
    return np.stack([c * 2, r * 4, 255 - c], axis=2).astype(np.uint8)


def texel_uv(row, col, shape):
    """Texture coordinate (v up) of the centre of texel (row, col)."""
    H, W = shape[:2]
    return np.array([(col + 0.5) / W, 1.0 - (row + 0.5) / H])


def seam_corners(f, uv):
    """Per-corner uv in [0, 1] with a genuine seam: the triangles across the cut take the
    unwrapped ``u + 1`` and every ``u`` is halved, so a vertex on the cut has ``u`` near 0 in
    some triangles and near 0.5 in others (as a cylindrical texture that repeats its seam
    region, :mod:`photomodel.texturing.cylindrical`)."""
    c = uv[f].copy()
    u = c[:, :, 0]
    seam = np.ptp(u, axis=1) > 0.5
    u[seam[:, None] & (u < 0.5)] += 1.0
    u *= 0.5
    return c, seam


def glb_accessor(g: pygltflib.GLTF2, index: int) -> np.ndarray:
    """The data of accessor ``index`` of a loaded GLB, read from its binary chunk."""
    acc = g.accessors[index]
    view = g.bufferViews[acc.bufferView]
    dtype = {pygltflib.FLOAT: np.float32, pygltflib.UNSIGNED_INT: np.uint32}[acc.componentType]
    k = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[acc.type]
    start = view.byteOffset + (acc.byteOffset or 0)
    a = np.frombuffer(g.binary_blob(), dtype, acc.count * k, start)
    return a.reshape(acc.count, k) if k > 1 else a


def assert_reopened_renders_like_the_original(path, scale, v, f, corner_uv, texture_img):
    """The exported file at ``path``, reopened with trimesh (positions × ``scale`` → mm) and drawn
    by our renderer from the front, looks like the mesh that was exported."""

    cam = orbit_camera(0.0, 160, 160, distance_mm=400.0)  # from the front: no seam in view
    r = get_renderer()
    src, uv_split, f_split = split_uv_seams(len(v), f, corner_uv)
    ref = r.render(cam, v[src], f_split, uv=uv_split, texture=texture_img, cull_backfaces=True)
    m = trimesh.load(path, process=False, force="mesh")
    img = np.asarray(
        (m.visual.material.baseColorTexture if path.suffix == ".glb" else m.visual.material.image).convert("RGB")
    )
    got = r.render(cam, m.vertices * scale, m.faces, uv=m.visual.uv, texture=img, cull_backfaces=True)
    assert ref.mask.sum() > 5000 and np.array_equal(got.mask, ref.mask)
    # float32 positions / uv: a pixel may land a hair differently on a texel edge; 1/255 = 8 bits
    assert np.abs(got.color - ref.color).max() <= 1.0 / 255 + 1e-6, path.name
