"""Texture coordinates for export (photomodel.exchange.uv): seam splitting and merging, sampling, checks.

Test data (seamed sphere, unique-colour texture) from :mod:`exchange_data`; the small known-answer
cases are worked out by hand from the conventions in the module docstring (``v`` up, texel
``(r, c)`` centred at ``((c + 0.5) / W, 1 − (r + 0.5) / H)``, clamped to the edge).
"""

from __future__ import annotations

import numpy as np
import pytest
from exchange_data import seam_corners, texel_uv

from photomodel.exchange.uv import (
    check_mesh,
    check_texture,
    check_uv,
    corner_uvs,
    merge_uv_seams,
    split_uv_seams,
    vertex_colors_from_texture,
)

# ----------------------------------------------------------------------------- known answers

#: Two triangles over a square; vertex 1 has u = 0.9 in the first and u = 0.0 in the second: a seam.
QUAD_FACES = np.array([[0, 1, 2], [1, 3, 2]])
QUAD_CORNERS = np.array(
    [
        [[0.1, 0.1], [0.9, 0.1], [0.5, 0.5]],
        [[0.0, 0.1], [0.2, 0.9], [0.5, 0.5]],
    ]
)


def test_split_uv_seams_of_two_triangles_copies_the_one_seam_vertex():
    source, uv_out, f_out = split_uv_seams(4, QUAD_FACES, QUAD_CORNERS)
    # four originals keep their index, one copy of vertex 1 follows
    np.testing.assert_array_equal(source, [0, 1, 2, 3, 1])
    # vertex 1's corners now point at 1 and 4 (one each), all others are unchanged
    assert sorted([f_out[0, 1], f_out[1, 0]]) == [1, 4]
    np.testing.assert_array_equal(f_out[0, [0, 2]], [0, 2])
    np.testing.assert_array_equal(f_out[1, 1:], [3, 2])
    np.testing.assert_array_equal(uv_out[f_out], QUAD_CORNERS)
    np.testing.assert_array_equal(sorted(map(tuple, uv_out[[1, 4]])), [(0.0, 0.1), (0.9, 0.1)])
    # and back
    np.testing.assert_array_equal(merge_uv_seams(QUAD_FACES, source, f_out, uv_out), QUAD_CORNERS)


def test_checks_name_the_problem():
    v = np.zeros((3, 3))
    with pytest.raises(ValueError, match=r"non-empty \(n, 3\)"):
        check_mesh(np.zeros((3, 2)), [[0, 1, 2]])
    with pytest.raises(ValueError, match="NaN or infinity"):
        check_mesh([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], [[0, 1, 2]])
    with pytest.raises(ValueError, match="only 3 vertices"):
        check_mesh(v, [[0, 1, 3]])
    with pytest.raises(ValueError, match="integer vertex indices"):
        check_mesh(v, [[0.0, 1.5, 2.0]])
    vv, ff = check_mesh(v, np.array([[0.0, 1.0, 2.0]]))  # whole floats are accepted as indices
    assert ff.dtype == np.int64 and vv.dtype == float
    with pytest.raises(ValueError, match=r"per vertex \(3, 2\) or per face corner \(1, 3, 2\)"):
        check_uv(np.zeros((2, 2)), 3, 1)
    with pytest.raises(ValueError, match="NaN"):
        check_uv([[0, 0], [np.inf, 0], [0, 0]], 3, 1)
    with pytest.raises(ValueError, match="RGB"):
        check_texture(np.zeros((4, 4), np.uint8))
    with pytest.raises(ValueError, match="uint8 or float"):
        check_texture(np.zeros((4, 4, 3), np.int32))
    np.testing.assert_array_equal(
        corner_uvs(QUAD_FACES, np.arange(8.0).reshape(4, 2))[1], [[2.0, 3.0], [6.0, 7.0], [4.0, 5.0]]
    )


# ----------------------------------------------------------------------------- on the sphere


def test_split_uv_seams_keeps_original_indices_and_duplicates_seam_vertices(sphere):
    v, f, uv = sphere
    c, seam = seam_corners(f, uv)
    assert seam.any() and np.all(v[f[seam]][:, :, 2].mean(axis=1) < 0)  # the cut is at the back
    source, uv_out, f_out = split_uv_seams(len(v), f, c)
    assert len(v) < len(source) <= len(v) + len(np.unique(f[seam]))  # only seam vertices copied
    np.testing.assert_array_equal(source[: len(v)], np.arange(len(v)))
    np.testing.assert_array_equal(source[f_out], f)  # same triangles over the same positions
    np.testing.assert_array_equal(uv_out[f_out], c)  # every corner keeps its coordinate
    # per-vertex input: nothing to split
    s2, uv2, f2 = split_uv_seams(len(v), f, uv)
    assert len(s2) == len(v) and np.array_equal(f2, f) and np.array_equal(uv2, uv)


def test_merge_uv_seams_inverts_a_split_in_any_triangle_order(sphere):
    v, f, uv = sphere
    c, _ = seam_corners(f, uv)
    source, uv_out, f_out = split_uv_seams(len(v), f, c)
    order = np.random.default_rng(2).permutation(len(f))
    np.testing.assert_array_equal(merge_uv_seams(f, source, f_out[order], uv_out), c)
    with pytest.raises(ValueError, match="not the mesh's triangles"):
        merge_uv_seams(f[::-1, ::-1], source, f_out, uv_out)


def test_vertex_colors_from_per_corner_uv_average_the_corners(texture):
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    corner = np.array([[texel_uv(1, 1, texture.shape)] * 3, [texel_uv(1, 3, texture.shape)] * 3])
    col = vertex_colors_from_texture(texture, faces, corner, 5)
    np.testing.assert_array_equal(col[1], texture[1, 1])
    np.testing.assert_array_equal(col[3], texture[1, 3])
    np.testing.assert_array_equal(col[0], np.round((texture[1, 1].astype(float) + texture[1, 3]) / 2))
    np.testing.assert_array_equal(col[4], 0)  # in no face
