"""Binary glTF export (photomodel.exchange.gltf): one triangle's GLB container taken apart by hand
(:mod:`struct` and :mod:`json`, following the glTF 2.0 spec), and a seamed sphere reopened with
trimesh and pygltflib (independent readers).

Test data from :mod:`exchange_data` (tolerances explained there).
"""

from __future__ import annotations

import io
import json
import struct

import numpy as np
import pygltflib
import pytest
import trimesh
from exchange_data import (
    POS_TOL_MM,
    RADIUS,
    assert_reopened_renders_like_the_original,
    glb_accessor,
    seam_corners,
    texel_uv,
)
from PIL import Image

from photomodel.exchange.files import decode_png, encode_png
from photomodel.exchange.gltf import METRES_PER_MM, encode_glb, write_glb
from photomodel.exchange.uv import split_uv_seams
from photomodel.rendering.sampling import sample_texture

# glTF 2.0 constants, from the spec
GLB_MAGIC, JSON_CHUNK, BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942
FLOAT, UNSIGNED_INT, ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, TRIANGLES = 5126, 5125, 34962, 34963, 4


def glb_chunks(data: bytes) -> tuple[dict, bytes]:
    """(JSON document, BIN chunk) of a GLB file, checking its 12-byte header and chunk layout."""
    magic, version, length = struct.unpack_from("<III", data, 0)
    assert (magic, version, length) == (GLB_MAGIC, 2, len(data))
    n_json, kind = struct.unpack_from("<II", data, 12)
    assert kind == JSON_CHUNK and n_json % 4 == 0
    doc = json.loads(data[20 : 20 + n_json])
    n_bin, kind = struct.unpack_from("<II", data, 20 + n_json)
    assert kind == BIN_CHUNK and n_bin % 4 == 0 and 28 + n_json + n_bin == len(data)
    return doc, data[28 + n_json : 28 + n_json + n_bin]


def read_accessor(doc: dict, blob: bytes, index: int) -> list:
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    k = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[acc["type"]]
    fmt = {FLOAT: "f", UNSIGNED_INT: "I"}[acc["componentType"]]
    values = struct.unpack_from(f"<{acc['count'] * k}{fmt}", blob, view["byteOffset"] + acc.get("byteOffset", 0))
    return [list(values[i : i + k]) for i in range(0, len(values), k)] if k > 1 else list(values)


# ----------------------------------------------------------------------------- known answers


def test_one_untextured_triangle_in_metres():
    doc, blob = glb_chunks(encode_glb([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]], [[0, 1, 2]]))
    assert doc["asset"]["version"] == "2.0"
    node = doc["nodes"][doc["scenes"][doc["scene"]]["nodes"][0]]
    prim = doc["meshes"][node["mesh"]]["primitives"][0]
    assert prim.get("mode", TRIANGLES) == TRIANGLES and "TEXCOORD_0" not in prim["attributes"]
    pos = doc["accessors"][prim["attributes"]["POSITION"]]
    assert (pos["componentType"], pos["type"], pos["count"]) == (FLOAT, "VEC3", 3)
    assert doc["bufferViews"][pos["bufferView"]]["target"] == ARRAY_BUFFER
    # 10 mm = 0.01 m; float32(0.01) = 0.00999999977648258, so 1e-9 m (1e-6 mm) of slack
    np.testing.assert_allclose(
        read_accessor(doc, blob, prim["attributes"]["POSITION"]), [[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0]], atol=1e-9
    )
    np.testing.assert_allclose(pos["min"], [0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(pos["max"], [0.01, 0.01, 0], atol=1e-9)
    np.testing.assert_array_equal(read_accessor(doc, blob, prim["attributes"]["NORMAL"]), [[0, 0, 1]] * 3)
    idx = doc["accessors"][prim["indices"]]
    assert (idx["componentType"], idx["type"]) == (UNSIGNED_INT, "SCALAR")
    assert doc["bufferViews"][idx["bufferView"]]["target"] == ELEMENT_ARRAY_BUFFER
    assert read_accessor(doc, blob, prim["indices"]) == [0, 1, 2]
    pbr = doc["materials"][prim["material"]]["pbrMetallicRoughness"]
    assert pbr["baseColorFactor"] == [0.8, 0.8, 0.8, 1.0] and pbr["metallicFactor"] == 0.0
    assert pbr.get("roughnessFactor", 1.0) == 1.0


def test_one_textured_triangle_flips_v_and_embeds_the_png():
    tex = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], np.uint8)
    uv = [[0.25, 0.75], [0.75, 0.75], [0.25, 0.25]]  # v up: the top-left, top-right, bottom-left texels
    doc, blob = glb_chunks(
        encode_glb([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, 10.0, 0.0]], [[0, 1, 2]], uv=uv, texture=tex)
    )
    prim = doc["meshes"][0]["primitives"][0]
    # glTF's t runs down from the top: t = 1 − v (all exact in float32)
    assert read_accessor(doc, blob, prim["attributes"]["TEXCOORD_0"]) == [[0.25, 0.25], [0.75, 0.25], [0.25, 0.75]]
    info = doc["materials"][prim["material"]]["pbrMetallicRoughness"]["baseColorTexture"]
    t = doc["textures"][info["index"]]
    image, sampler = doc["images"][t["source"]], doc["samplers"][t["sampler"]]
    assert image["mimeType"] == "image/png"
    assert (sampler["wrapS"], sampler["wrapT"]) == (33071, 33071)  # CLAMP_TO_EDGE
    view = doc["bufferViews"][image["bufferView"]]
    png = blob[view["byteOffset"] : view["byteOffset"] + view["byteLength"]]
    np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(png))), tex)  # Pillow decodes it


# ----------------------------------------------------------------------------- on the sphere


def test_glb_reopens_in_trimesh_in_metres_with_seam_copies_and_texture(tmp_path, sphere, texture):
    v, f, uv = sphere
    c, _ = seam_corners(f, uv)
    write_glb(tmp_path / "face.glb", v, f, uv=c, texture=texture)
    m = trimesh.load(tmp_path / "face.glb", process=False, force="mesh")
    source, uv_split, f_split = split_uv_seams(len(v), f, c)
    assert len(m.vertices) == len(source)
    np.testing.assert_allclose(m.vertices / METRES_PER_MM, v[source], atol=POS_TOL_MM)
    np.testing.assert_array_equal(m.faces, f_split)
    np.testing.assert_allclose(m.visual.uv, uv_split, atol=1e-6)  # trimesh flips glTF's t back to v up
    img = m.visual.material.baseColorTexture
    assert img.size == (texture.shape[1], texture.shape[0])
    np.testing.assert_array_equal(np.asarray(img.convert("RGB")), texture)


def test_glb_uv_orientation_texel_marker(tmp_path, sphere):
    """A vertex placed on a marker texel near the top-left samples the marker after reopening."""
    v, f, uv = sphere
    tex = np.full((32, 64, 3), 40, np.uint8)
    tex[2, 5] = (255, 0, 0)  # marker: row 2 (near the top), column 5
    uv = uv.copy()
    uv[0] = texel_uv(2, 5, tex.shape)
    write_glb(tmp_path / "m.glb", v, f, uv=uv, texture=tex)
    m = trimesh.load(tmp_path / "m.glb", process=False, force="mesh")
    img = np.asarray(m.visual.material.baseColorTexture.convert("RGB"))
    np.testing.assert_array_equal(sample_texture(img, m.visual.uv[0]), [255, 0, 0])
    # in the raw file, TEXCOORD_0 has glTF's top-left origin: t = (row + 0.5) / H
    g = pygltflib.GLTF2.load(tmp_path / "m.glb")
    raw = glb_accessor(g, g.meshes[0].primitives[0].attributes.TEXCOORD_0)
    np.testing.assert_allclose(raw[0], [(5 + 0.5) / 64, (2 + 0.5) / 32], atol=1e-7)


def test_glb_structure_with_pygltflib(tmp_path, sphere, texture):
    v, f, uv = sphere
    path = write_glb(tmp_path / "face.glb", v, f, uv=uv, texture=texture, name="james")
    g = pygltflib.GLTF2.load(path)
    prim = g.meshes[0].primitives[0]
    assert g.meshes[0].name == "james" and g.nodes[g.scenes[g.scene].nodes[0]].mesh == 0
    pos = glb_accessor(g, prim.attributes.POSITION)
    np.testing.assert_allclose(pos, v * METRES_PER_MM, atol=POS_TOL_MM * METRES_PER_MM)
    acc = g.accessors[prim.attributes.POSITION]
    np.testing.assert_allclose(acc.max, pos.max(axis=0))
    np.testing.assert_allclose(acc.min, pos.min(axis=0))
    normals = glb_accessor(g, prim.attributes.NORMAL)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6)
    assert np.mean(np.sum(normals * v / RADIUS, axis=1)) > 0.99  # outward on the sphere
    np.testing.assert_array_equal(glb_accessor(g, prim.indices).reshape(-1, 3), f)
    mat = g.materials[prim.material]
    assert mat.pbrMetallicRoughness.metallicFactor == 0.0 and mat.doubleSided
    assert "KHR_materials_unlit" in mat.extensions and "KHR_materials_unlit" in g.extensionsUsed
    tex = g.textures[mat.pbrMetallicRoughness.baseColorTexture.index]
    sampler, image = g.samplers[tex.sampler], g.images[tex.source]
    assert (sampler.wrapS, sampler.wrapT) == (pygltflib.CLAMP_TO_EDGE, pygltflib.CLAMP_TO_EDGE)
    assert image.mimeType == "image/png"
    view = g.bufferViews[image.bufferView]
    png = g.binary_blob()[view.byteOffset : view.byteOffset + view.byteLength]
    np.testing.assert_array_equal(decode_png(png), texture)


def test_glb_without_texture_and_bad_input(tmp_path, sphere):
    v, f, uv = sphere
    m = trimesh.load(trimesh.util.wrap_as_stream(encode_glb(v, f)), file_type="glb", process=False, force="mesh")
    assert len(m.vertices) == len(v)
    with pytest.raises(ValueError, match="both uv and texture"):
        encode_glb(v, f, uv=uv)
    with pytest.raises(ValueError, match="uv must be"):
        write_glb(tmp_path / "x.glb", v, f, uv=uv[:-1], texture=np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ValueError, match="only 642 vertices"):
        encode_glb(v, f + 1)
    assert not list(tmp_path.iterdir())  # nothing written, no temporary left behind


def test_glb_from_encoded_png_bytes_is_the_same_file(sphere, texture):
    """Already-encoded PNG bytes (as the texture job passes them) give byte-identical output."""

    v, f, uv = sphere
    png = encode_png(texture)
    assert encode_glb(v, f, uv=uv, texture=png) == encode_glb(v, f, uv=uv, texture=texture)
    with pytest.raises(ValueError, match="PNG signature"):
        encode_glb(v, f, uv=uv, texture=b"GIF89a not a png")


def test_reopened_glb_renders_like_the_original(tmp_path, sphere, texture):
    """The exported file, reopened and drawn by our renderer, looks like the mesh we exported."""
    v, f, uv = sphere
    c, _ = seam_corners(f, uv)
    write_glb(tmp_path / "face.glb", v, f, uv=c, texture=texture)
    assert_reopened_renders_like_the_original(tmp_path / "face.glb", 1 / METRES_PER_MM, v, f, c, texture)
