"""Tests of photomodel.rendering.sampling: bilinear look-ups of images (pixel positions) and textures
(uv, v up, clamped), by hand and against what the renderer draws."""

from __future__ import annotations

import numpy as np
from exchange_data import texel_uv

from photomodel.camera import orbit_camera
from photomodel.rendering.renderer import get_renderer
from photomodel.rendering.sampling import sample_image, sample_texture


def test_sample_image_is_bilinear_and_handles_long_point_lists():
    H, W = 40, 60
    v, u = np.mgrid[0:H, 0:W].astype(np.float32)
    img = np.dstack([2.0 * u + 3.0 * v, u - v, np.full_like(u, 7.0)]).astype(np.float32)
    rng = np.random.default_rng(1)
    n = 70_000  # more than cv2.remap's 32767-per-side limit
    uv = np.column_stack([rng.uniform(0, W - 1, n), rng.uniform(0, H - 1, n)])
    s = sample_image(img, uv)
    assert s.shape == (n, 3)
    # a linear ramp is reproduced exactly by bilinear interpolation, up to OpenCV's 1/32 px weights
    np.testing.assert_allclose(s[:, 0], 2.0 * uv[:, 0] + 3.0 * uv[:, 1], atol=5.0 / 32)
    np.testing.assert_allclose(s[:, 1], uv[:, 0] - uv[:, 1], atol=2.0 / 32)
    assert sample_image(img[..., 0], np.array([[-5.0, 3.0]]), border_value=-1.0)[0] == -1.0


def test_sample_texture_bilinear_known_values():
    tex = np.array([[[0.0], [100.0]], [[200.0], [40.0]]])  # 2×2, one channel; row 0 is the top (v = 1)
    # texel centres: (0.25, 0.75) → row 0 col 0; (0.75, 0.25) → row 1 col 1
    np.testing.assert_allclose(sample_texture(tex, [[0.25, 0.75], [0.75, 0.25]]), [[0.0], [40.0]])
    # the image centre is the mean of the four: (0 + 100 + 200 + 40) / 4 = 85
    np.testing.assert_allclose(sample_texture(tex, [0.5, 0.5]), [85.0])
    # halfway between the top two texel centres: (0 + 100) / 2 = 50; a quarter of the way from the
    # top-left centre to the bottom-left one (v = 0.75 − 0.25·0.5 = 0.625): 0.75·0 + 0.25·200 = 50
    np.testing.assert_allclose(sample_texture(tex, [[0.5, 0.75], [0.25, 0.625]]), [[50.0], [50.0]])
    # the corner of the image: clamped to the corner texel
    np.testing.assert_allclose(sample_texture(tex, [[0.0, 0.0], [1.0, 1.0]]), [[200.0], [100.0]])


def test_sample_texture_hits_texel_centres_v_up_and_clamps(texture):
    uv = np.array([texel_uv(0, 0, texture.shape), texel_uv(63, 5, texture.shape), texel_uv(10, 127, texture.shape)])
    np.testing.assert_allclose(sample_texture(texture, uv), texture[[0, 63, 10], [0, 5, 127]])  # v = 1: top row
    # beyond the edges: clamped, as the renderer and the glTF sampler do
    np.testing.assert_allclose(sample_texture(texture, [[1.2, 1.1], [-0.3, -2.0]]), texture[[0, 63], [127, 0]])
    # halfway between two columns of the same row: the mean
    mid = (texel_uv(3, 7, texture.shape) + texel_uv(3, 8, texture.shape)) / 2
    np.testing.assert_allclose(sample_texture(texture, mid), texture[3, 7:9].astype(float).mean(axis=0))


def test_sample_image_clamps_to_the_edge_without_a_border_value():
    img = np.arange(12, dtype=np.float32).reshape(3, 4)
    s = sample_image(img, np.array([[-3.0, 1.0], [10.0, -2.0], [1.5, 1.0]]), border_value=None)
    np.testing.assert_array_equal(s, [4.0, 3.0, 5.5])
    assert sample_image(img, np.zeros((0, 2))).shape == (0,)
    assert sample_image(np.zeros((3, 4, 2), np.uint8), np.zeros((0, 2))).shape == (0, 2)


def test_sample_texture_keeps_the_shape_of_uv_and_the_precision_of_float32_uv():
    rng = np.random.default_rng(6)
    tex = rng.uniform(0, 1, (40, 50, 3)).astype(np.float32)
    uv = rng.uniform(-0.05, 1.05, (20, 100, 2))
    out = sample_texture(tex, uv)
    assert out.shape == (20, 100, 3) and out.dtype == np.float32
    # float32 uv (the tracker's interpolated coordinates): texel positions in float32, same look-up
    np.testing.assert_allclose(sample_texture(tex, uv.astype(np.float32)), out, atol=1e-5)
    assert sample_texture(tex, uv[:0, 0]).shape == (0, 3)
    assert sample_texture(np.zeros((4, 4, 3), np.uint8), [0.5, 0.5]).shape == (3,)


def test_sample_texture_is_what_the_renderer_draws():
    """A textured quad facing the camera: the rendered colour at a pixel is the CPU look-up at the
    pixel's interpolated uv."""
    renderer = get_renderer()
    cam = orbit_camera(0.0, 200, 200, distance_mm=300.0)
    V = np.array([[-40.0, -40.0, 0.0], [40.0, -40.0, 0.0], [40.0, 40.0, 0.0], [-40.0, 40.0, 0.0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    tex = np.random.default_rng(7).uniform(0, 1, (16, 16, 3)).astype(np.float32)
    res = renderer.render(cam, V, F, uv=uv, texture=tex)
    at = renderer.render(cam, V, F, colors=uv).color[res.mask]
    np.testing.assert_allclose(res.color[res.mask], sample_texture(tex, at), atol=5e-3)  # GL: 8-bit weights
