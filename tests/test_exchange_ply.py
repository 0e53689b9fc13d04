"""Coloured PLY export (photomodel.exchange.ply): the exact bytes of one triangle (packed here with
:mod:`struct` from the PLY format), and a sphere written and reopened with trimesh.

Test data from :mod:`exchange_data` (tolerances explained there).
"""

from __future__ import annotations

import struct

import numpy as np
import pytest
import trimesh
from exchange_data import POS_TOL_MM, texel_uv

from photomodel.exchange.ply import encode_colored_ply, write_colored_ply

# ----------------------------------------------------------------------------- known answers


def test_one_triangle_is_these_bytes():
    v = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, -2.5]]  # exact in float32
    rgb = np.array([[255, 0, 0], [0, 128, 0], [1, 2, 3]], np.uint8)
    expected = (
        b"ply\n"
        b"format binary_little_endian 1.0\n"
        b"comment Face Studio mesh with vertex colours\n"
        b"comment units mm\n"
        b"element vertex 3\n"
        b"property float x\nproperty float y\nproperty float z\n"
        b"property uchar red\nproperty uchar green\nproperty uchar blue\n"
        b"element face 1\n"
        b"property list uchar int vertex_indices\n"
        b"end_header\n"
        + struct.pack("<fffBBB", 0.0, 0.0, 0.0, 255, 0, 0)
        + struct.pack("<fffBBB", 10.0, 0.0, 0.0, 0, 128, 0)
        + struct.pack("<fffBBB", 0.0, 10.0, -2.5, 1, 2, 3)
        + struct.pack("<Biii", 3, 0, 1, 2)
    )
    assert encode_colored_ply(v, [[0, 1, 2]], rgb) == expected


def test_float_colours_units_and_bad_input():
    v, f = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0, 1, 2]]
    # float colours: ×255, rounded (0.5 → 127.5 → 128, half to even), clipped, NaN → 0
    data = encode_colored_ply(v, f, np.array([[1.0, 0.5, 0.0], [2.0, -1.0, np.nan], [0.2, 0.4, 0.6]]), units="m")
    assert b"comment units m\n" in data
    body = data[data.index(b"end_header\n") + len(b"end_header\n") :]
    colours = [tuple(body[15 * i + 12 : 15 * i + 15]) for i in range(3)]  # 3 float32 then 3 uchar per vertex
    assert colours == [(255, 128, 0), (255, 0, 0), (51, 102, 153)]  # 0.2·255 = 51, 0.4·255 = 102, 0.6·255 = 153
    with pytest.raises(ValueError, match=r"\(3, 3\) RGB per vertex"):
        encode_colored_ply(v, f, np.zeros((2, 3), np.uint8))
    with pytest.raises(ValueError, match="uint8 or float"):
        encode_colored_ply(v, f, np.zeros((3, 3), np.int64))
    with pytest.raises(ValueError, match="single line"):
        encode_colored_ply(v, f, np.zeros((3, 3), np.uint8), units="mm\nend_header")
    with pytest.raises(ValueError, match=r"must end in \.ply"):
        write_colored_ply("x.obj", v, f, np.zeros((3, 3), np.uint8))


# ----------------------------------------------------------------------------- on the sphere


def test_ply_reopens_with_positions_and_given_colours(tmp_path, sphere):
    v, f, _ = sphere
    rgb = np.random.default_rng(0).integers(0, 256, (len(v), 3), dtype=np.uint8)
    write_colored_ply(tmp_path / "c.ply", v, f, rgb)
    m = trimesh.load(tmp_path / "c.ply", process=False)
    np.testing.assert_allclose(m.vertices, v, atol=POS_TOL_MM)
    np.testing.assert_array_equal(m.faces, f)
    np.testing.assert_array_equal(m.visual.vertex_colors[:, :3], rgb)
    assert b"comment units mm" in (tmp_path / "c.ply").read_bytes()[:300]


def test_ply_colours_sampled_from_the_texture_at_each_vertex(tmp_path, sphere, texture):
    v, f, _ = sphere
    # put every vertex on a texel centre, so its colour is that texel exactly
    rng = np.random.default_rng(1)
    rows, cols = rng.integers(0, texture.shape[0], len(v)), rng.integers(0, texture.shape[1], len(v))
    uv = np.stack([texel_uv(r, c, texture.shape) for r, c in zip(rows, cols, strict=True)])
    write_colored_ply(tmp_path / "t.ply", v, f, uv=uv, texture=texture)
    m = trimesh.load(tmp_path / "t.ply", process=False)
    np.testing.assert_array_equal(m.visual.vertex_colors[:, :3], texture[rows, cols])
    with pytest.raises(ValueError, match="colors"):
        encode_colored_ply(v, f)
