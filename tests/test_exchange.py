"""Exports (photomodel.exchange): write each format, reopen it with trimesh / pygltflib, compare.

The test mesh is a sphere of radius 80 mm (head-sized) with a cylindrical texture mapping
``u = (atan2(x, z) + π) / 2π``, so its ``u`` seam runs down the back (``z < 0``) as on a face;
:func:`seam_corners` gives the per-corner coordinates of a seamed texture atlas.
Tolerances: OBJ writes 6 decimals (≤ 5e-7 mm rounding); PLY and glTF store float32, whose
spacing at 80 mm / 0.08 m is ~8e-6 mm; 1e-4 mm covers both with margin and is far below any
geometric accuracy we care about.
"""

from __future__ import annotations

import numpy as np
import pygltflib
import pytest
import trimesh
from scipy.spatial import cKDTree

from photomodel.exchange.files import decode_png
from photomodel.exchange.gltf import METRES_PER_MM, encode_glb, write_glb
from photomodel.exchange.obj import write_textured_obj
from photomodel.exchange.ply import encode_colored_ply, write_colored_ply
from photomodel.exchange.uv import merge_uv_seams, sample_texture, split_uv_seams, vertex_colors_from_texture

POS_TOL_MM = 1e-4  # see module docstring
RADIUS = 80.0


@pytest.fixture(scope="module")
def sphere():
    s = trimesh.creation.icosphere(3, radius=RADIUS)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    u = (np.arctan2(v[:, 0], v[:, 2]) + np.pi) / (2 * np.pi) % 1.0
    uv = np.column_stack([u, (v[:, 1] + RADIUS) / (2 * RADIUS)])
    return v, f, uv


@pytest.fixture(scope="module")
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


# ----------------------------------------------------------------------------- uv helpers


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


def test_sample_texture_hits_texel_centres_v_up_and_clamps(texture):
    uv = np.array([texel_uv(0, 0, texture.shape), texel_uv(63, 5, texture.shape), texel_uv(10, 127, texture.shape)])
    np.testing.assert_allclose(sample_texture(texture, uv), texture[[0, 63, 10], [0, 5, 127]])  # v = 1: top row
    # beyond the edges: clamped, as the renderer and the glTF sampler do
    np.testing.assert_allclose(sample_texture(texture, [[1.2, 1.1], [-0.3, -2.0]]), texture[[0, 63], [127, 0]])
    # halfway between two columns of the same row: the mean
    mid = (texel_uv(3, 7, texture.shape) + texel_uv(3, 8, texture.shape)) / 2
    np.testing.assert_allclose(sample_texture(texture, mid), texture[3, 7:9].astype(float).mean(axis=0))


def test_vertex_colors_from_per_corner_uv_average_the_corners(texture):
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    corner = np.array([[texel_uv(1, 1, texture.shape)] * 3, [texel_uv(1, 3, texture.shape)] * 3])
    col = vertex_colors_from_texture(texture, faces, corner, 5)
    np.testing.assert_array_equal(col[1], texture[1, 1])
    np.testing.assert_array_equal(col[3], texture[1, 3])
    np.testing.assert_array_equal(col[0], np.round((texture[1, 1].astype(float) + texture[1, 3]) / 2))
    np.testing.assert_array_equal(col[4], 0)  # in no face


# ----------------------------------------------------------------------------- OBJ


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


# ----------------------------------------------------------------------------- PLY


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


# ----------------------------------------------------------------------------- glTF


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
    raw = _accessor(g, g.meshes[0].primitives[0].attributes.TEXCOORD_0)
    np.testing.assert_allclose(raw[0], [(5 + 0.5) / 64, (2 + 0.5) / 32], atol=1e-7)


def test_glb_structure_with_pygltflib(tmp_path, sphere, texture):
    v, f, uv = sphere
    path = write_glb(tmp_path / "face.glb", v, f, uv=uv, texture=texture, name="james")
    g = pygltflib.GLTF2.load(path)
    prim = g.meshes[0].primitives[0]
    assert g.meshes[0].name == "james" and g.nodes[g.scenes[g.scene].nodes[0]].mesh == 0
    pos = _accessor(g, prim.attributes.POSITION)
    np.testing.assert_allclose(pos, v * METRES_PER_MM, atol=POS_TOL_MM * METRES_PER_MM)
    acc = g.accessors[prim.attributes.POSITION]
    np.testing.assert_allclose(acc.max, pos.max(axis=0))
    np.testing.assert_allclose(acc.min, pos.min(axis=0))
    normals = _accessor(g, prim.attributes.NORMAL)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6)
    assert np.mean(np.sum(normals * v / RADIUS, axis=1)) > 0.99  # outward on the sphere
    np.testing.assert_array_equal(_accessor(g, prim.indices).reshape(-1, 3), f)
    mat = g.materials[prim.material]
    assert mat.pbrMetallicRoughness.metallicFactor == 0.0 and mat.doubleSided
    assert "KHR_materials_unlit" in mat.extensions and "KHR_materials_unlit" in g.extensionsUsed
    tex = g.textures[mat.pbrMetallicRoughness.baseColorTexture.index]
    sampler, image = g.samplers[tex.sampler], g.images[tex.source]
    assert (sampler.wrapS, sampler.wrapT) == (pygltflib.CLAMP_TO_EDGE, pygltflib.CLAMP_TO_EDGE)
    assert image.mimeType == "image/png"
    view = g.bufferViews[image.bufferView]
    png = g.binary_blob()[view.byteOffset: view.byteOffset + view.byteLength]
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
    from photomodel.exchange.files import encode_png

    v, f, uv = sphere
    png = encode_png(texture)
    assert encode_glb(v, f, uv=uv, texture=png) == encode_glb(v, f, uv=uv, texture=texture)
    with pytest.raises(ValueError, match="PNG signature"):
        encode_glb(v, f, uv=uv, texture=b"GIF89a not a png")


def test_reopened_glb_and_obj_render_like_the_original(tmp_path, sphere, texture):
    """The exported files, reopened and drawn by our renderer, look like the mesh we exported."""
    from photomodel.camera import orbit_camera
    from photomodel.rendering.renderer import get_renderer

    v, f, uv = sphere
    c, _ = seam_corners(f, uv)
    write_glb(tmp_path / "face.glb", v, f, uv=c, texture=texture)
    write_textured_obj(tmp_path / "face.obj", v, f, c, texture)
    cam = orbit_camera(0.0, 160, 160, distance_mm=400.0)  # from the front: no seam in view
    r = get_renderer()
    src, uv_split, f_split = split_uv_seams(len(v), f, c)
    ref = r.render(cam, v[src], f_split, uv=uv_split, texture=texture, cull_backfaces=True)
    for path, scale in ((tmp_path / "face.glb", 1 / METRES_PER_MM), (tmp_path / "face.obj", 1.0)):
        m = trimesh.load(path, process=False, force="mesh")
        img = np.asarray((m.visual.material.baseColorTexture if path.suffix == ".glb"
                          else m.visual.material.image).convert("RGB"))
        got = r.render(cam, m.vertices * scale, m.faces, uv=m.visual.uv, texture=img, cull_backfaces=True)
        assert ref.mask.sum() > 5000 and np.array_equal(got.mask, ref.mask)
        # float32 positions / uv: a pixel may land a hair differently on a texel edge; 1/255 = 8 bits
        assert np.abs(got.color - ref.color).max() <= 1.0 / 255 + 1e-6, path.name


def _accessor(g: pygltflib.GLTF2, index: int) -> np.ndarray:
    acc = g.accessors[index]
    view = g.bufferViews[acc.bufferView]
    dtype = {pygltflib.FLOAT: np.float32, pygltflib.UNSIGNED_INT: np.uint32}[acc.componentType]
    k = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[acc.type]
    start = view.byteOffset + (acc.byteOffset or 0)
    a = np.frombuffer(g.binary_blob(), dtype, acc.count * k, start)
    return a.reshape(acc.count, k) if k > 1 else a
