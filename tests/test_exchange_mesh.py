"""Plain mesh files (photomodel.exchange.mesh): OBJ and PLY of a small mesh, read back by hand
(OBJ text lines; PLY header and :mod:`struct`-unpacked binary body, as the PLY format lays them out).
"""

from __future__ import annotations

import struct

import numpy as np
import pytest

from photomodel.exchange.mesh import read_mesh, write_mesh

#: A square of two triangles, the last corner lifted; every value exact in float32.
V = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0], [10.0, 10.0, 0.5]])
F = np.array([[0, 1, 2], [1, 3, 2]])


def test_obj_lists_the_vertices_and_faces_in_order(tmp_path):
    path = write_mesh(tmp_path / "m.obj", V, F)
    lines = path.read_text().splitlines()
    v = [[float(x) for x in ln.split()[1:]] for ln in lines if ln.startswith("v ")]
    f = [[int(x) for x in ln.split()[1:]] for ln in lines if ln.startswith("f ")]
    np.testing.assert_array_equal(v, V)
    assert f == [[1, 2, 3], [2, 4, 3]]  # 1-based
    got_v, got_f = read_mesh(path)
    np.testing.assert_array_equal(got_v, V)
    np.testing.assert_array_equal(got_f, F)


def test_ply_header_and_binary_body(tmp_path):
    path = write_mesh(tmp_path / "m.ply", V, F)
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    assert header[:2] == ["ply", "format binary_little_endian 1.0"]
    assert "element vertex 4" in header and "element face 2" in header
    assert [h for h in header if h.startswith("property")] == [
        "property float x",
        "property float y",
        "property float z",
        "property list uchar int vertex_indices",
    ]
    body = data[end:]
    assert len(body) == 4 * 12 + 2 * 13  # 3 float32 per vertex; count byte + 3 int32 per face
    np.testing.assert_array_equal(np.reshape(struct.unpack_from("<12f", body, 0), (4, 3)), V)
    faces = [struct.unpack_from("<Biii", body, 48 + 13 * i) for i in range(2)]
    assert faces == [(3, 0, 1, 2), (3, 1, 3, 2)]
    got_v, got_f = read_mesh(path)
    np.testing.assert_array_equal(got_v, V)
    np.testing.assert_array_equal(got_f, F)


def test_other_suffixes_are_refused_and_nothing_is_left_behind(tmp_path):
    with pytest.raises(ValueError, match=r"must end in \.obj or \.ply"):
        write_mesh(tmp_path / "m.stl", V, F)
    write_mesh(tmp_path / "m.obj", V, F)
    assert [p.name for p in tmp_path.iterdir()] == ["m.obj"]  # written atomically: no temporary
