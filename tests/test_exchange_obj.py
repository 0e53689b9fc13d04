"""Textured OBJ export (photomodel.exchange.obj): the exact text of a small mesh, and a seamed sphere
written and reopened with trimesh (an independent reader).

Test data from :mod:`exchange_data` (tolerances explained there).
"""

from __future__ import annotations

import io

import numpy as np
import pytest
import trimesh
from exchange_data import (
    POS_TOL_MM,
    assert_reopened_renders_like_the_original,
    seam_corners,
)
from PIL import Image
from scipy.spatial import cKDTree

from photomodel.exchange.obj import encode_textured_obj, write_textured_obj
from photomodel.exchange.uv import split_uv_seams


def content_lines(data: bytes) -> list[str]:
    return [ln for ln in data.decode().splitlines() if ln and not ln.startswith("#")]


# ----------------------------------------------------------------------------- known answers


def test_one_triangle_is_written_as_this_text(tmp_path):
    v = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [1.25, -2.5, 1.0 / 3.0]]
    uv = [[0.0, 0.0], [1.0, 0.0], [0.25, 0.75]]
    tex = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], np.uint8)
    out = encode_textured_obj(tmp_path / "tri.obj", v, [[0, 1, 2]], uv, tex)
    assert list(out.files) == [tmp_path / "tri.png", tmp_path / "tri.mtl", tmp_path / "tri.obj"]  # PNG first
    assert not list(tmp_path.iterdir())  # encoding writes nothing
    # the normal, by hand: (10, 0, 0) × (1.25, −2.5, 1/3) = (0, −10/3, −25) → unit (0, −0.132164, −0.991228)
    assert content_lines(out.files[tmp_path / "tri.obj"]) == [
        "mtllib tri.mtl",
        "v 0.000000 0.000000 0.000000",
        "v 10.000000 0.000000 0.000000",
        "v 1.250000 -2.500000 0.333333",
        "vt 0.0000000 0.0000000",
        "vt 1.0000000 0.0000000",
        "vt 0.2500000 0.7500000",
        "vn 0.000000 -0.132164 -0.991228",
        "vn 0.000000 -0.132164 -0.991228",
        "vn 0.000000 -0.132164 -0.991228",
        "usemtl face",
        "f 1/1/1 2/2/2 3/3/3",
    ]
    mtl = content_lines(out.files[tmp_path / "tri.mtl"])
    assert mtl[0] == "newmtl face" and mtl[-1] == "map_Kd tri.png"
    assert "Kd 1.000000 1.000000 1.000000" in mtl and "Ks 0.000000 0.000000 0.000000" in mtl
    png = Image.open(io.BytesIO(out.files[tmp_path / "tri.png"]))  # Pillow: an independent decoder
    assert png.mode == "RGB"
    np.testing.assert_array_equal(np.asarray(png), tex)


def test_a_seam_is_corners_of_one_vertex_with_different_vt(tmp_path):
    # a square of two triangles in z = 0, counter-clockwise from +z; vertex 1 (second row) has
    # u = 0.9 in the first triangle and u = 0.0 in the second
    v = [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0], [10.0, 10.0, 0.0]]
    f = [[0, 1, 2], [1, 3, 2]]
    corners = [[[0.1, 0.1], [0.9, 0.1], [0.5, 0.5]], [[0.0, 0.1], [0.2, 0.9], [0.5, 0.5]]]
    out = encode_textured_obj(tmp_path / "sq.obj", v, f, corners, np.zeros((2, 2, 3), np.uint8))
    lines = content_lines(out.files[out.obj_path])
    assert [ln for ln in lines if ln.startswith("v ")] == [
        "v 0.000000 0.000000 0.000000",
        "v 10.000000 0.000000 0.000000",
        "v 0.000000 10.000000 0.000000",
        "v 10.000000 10.000000 0.000000",
    ]
    assert [ln for ln in lines if ln.startswith("vn ")] == ["vn 0.000000 0.000000 1.000000"] * 4
    vt = [[float(x) for x in ln.split()[1:]] for ln in lines if ln.startswith("vt ")]
    assert len(vt) == 5 == out.n_texcoords  # six corners, (0.5, 0.5) shared
    faces = [[[int(i) for i in c.split("/")] for c in ln.split()[1:]] for ln in lines if ln.startswith("f ")]
    for tri, tri_corners, face in zip(faces, corners, f, strict=True):
        assert [c[0] - 1 for c in tri] == face  # positions by the mesh's own index
        assert [c[2] - 1 for c in tri] == face  # one normal per vertex
        np.testing.assert_allclose([vt[c[1] - 1] for c in tri], tri_corners, atol=5e-8)  # 7 decimals


def test_file_names_are_checked(tmp_path):
    v, f, uv = [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], [[0, 0], [1, 0], [0, 1]]
    tex = np.zeros((2, 2, 3), np.uint8)
    with pytest.raises(ValueError, match=r"must end in \.obj"):
        encode_textured_obj(tmp_path / "tri.ply", v, f, uv, tex)
    with pytest.raises(ValueError, match="whitespace"):
        encode_textured_obj(tmp_path / "my tri.obj", v, f, uv, tex)


# ----------------------------------------------------------------------------- on the sphere


def test_obj_reopens_with_positions_uv_and_texture(tmp_path, sphere, texture):
    v, f, uv = sphere
    out = write_textured_obj(tmp_path / "face.obj", v, f, uv, texture)
    assert out.png_path == tmp_path / "face.png" and "map_Kd face.png" in out.mtl_path.read_text()
    m = trimesh.load(tmp_path / "face.obj", process=False)
    assert len(m.vertices) == len(v)  # per-vertex uv: no seam copies
    np.testing.assert_allclose(m.vertices, v, atol=POS_TOL_MM)
    np.testing.assert_allclose(m.visual.uv, uv, atol=1e-7)
    assert m.visual.material.image.size == (texture.shape[1], texture.shape[0])
    np.testing.assert_array_equal(np.asarray(m.visual.material.image.convert("RGB")), texture)
    np.testing.assert_array_equal(m.faces, f)


def test_obj_with_a_seam_keeps_the_vertex_list_and_splits_only_on_import(tmp_path, sphere, texture):
    v, f, uv = sphere
    c, _ = seam_corners(f, uv)
    out = write_textured_obj(tmp_path / "face.obj", v, f, c, texture)
    lines = out.obj_path.read_text().splitlines()
    written = np.array([[float(x) for x in ln.split()[1:]] for ln in lines if ln.startswith("v ")])
    np.testing.assert_allclose(written, v, atol=POS_TOL_MM)  # file vertex i is mesh vertex i
    assert out.n_texcoords == len(np.unique(c.reshape(-1, 2), axis=0))
    m = trimesh.load(out.obj_path, process=False)
    source, uv_split, _ = split_uv_seams(len(v), f, c)
    assert len(m.vertices) == len(source)  # trimesh splits exactly where we would
    # the reopened (position, uv) pairs are ours, one to one (uv scaled to mm-like magnitudes)
    ours = np.column_stack([v[source], uv_split * 100])
    theirs = np.column_stack([m.vertices, m.visual.uv * 100])
    dist, nearest = cKDTree(ours).query(theirs)
    assert dist.max() < POS_TOL_MM and len(np.unique(nearest)) == len(ours)


def test_obj_refers_to_an_existing_texture_by_relative_name(tmp_path, sphere, texture):
    v, f, uv = sphere
    png = tmp_path / "maps" / "skin.png"
    png.parent.mkdir()
    png.write_bytes(b"")  # existence is all that is checked
    out = write_textured_obj(tmp_path / "face.obj", v, f, uv, None, texture_path=png)
    assert "map_Kd maps/skin.png" in out.mtl_path.read_text()
    assert png not in out.files
    with pytest.raises(ValueError, match="in the OBJ's folder"):
        write_textured_obj(tmp_path / "sub" / "face.obj", v, f, uv, None, texture_path=png)
    with pytest.raises(ValueError, match="no such file"):
        write_textured_obj(tmp_path / "face.obj", v, f, uv, None, texture_path=tmp_path / "none.png")


def test_reopened_obj_renders_like_the_original(tmp_path, sphere, texture):
    """The exported files, reopened and drawn by our renderer, look like the mesh we exported."""
    v, f, uv = sphere
    c, _ = seam_corners(f, uv)
    write_textured_obj(tmp_path / "face.obj", v, f, c, texture)
    assert_reopened_renders_like_the_original(tmp_path / "face.obj", 1.0, v, f, c, texture)
