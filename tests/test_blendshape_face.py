"""Tests of tracking.blendshape_face: the blend-shape model (§6.1.1) and its rendering (Eq. 5)."""

import numpy as np
import pytest

from photomodel.camera import Camera
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.rendering.renderer import get_renderer
from photomodel.samples.sample_data import load_james_scan
from tracking.blendshape_face import CONTROL_REGIONS, expression_basis, render_model
from tracking.synthetic_sequences.expressions import EXPRESSION_NAMES, true_expression_geometry
from tracking.synthetic_sequences.ground_truth import render_video_frame, sample_face_model, video_truth


@pytest.fixture(scope="module")
def model():
    return sample_face_model()


def test_basis_spans_the_sum_zero_plane_and_is_orthonormal_in_the_region(model):
    for r, Q in enumerate(model.bases):
        if r == 0:
            assert Q.shape[1] == 0  # rest is constant
            continue
        assert Q.shape[1] >= 1
        np.testing.assert_allclose(Q.sum(0), 0.0, atol=1e-12)  # Σ_k w_k stays 1
        mu = model.membership[:, r]
        sw = np.sqrt(mu / mu.sum())
        G = (model.geometry * sw[None, :, None]).reshape(model.m, -1).T
        # orthonormal in the region's geometric inner product: α = 1 moves the region 1 mm RMS
        np.testing.assert_allclose((G @ Q).T @ (G @ Q), np.eye(Q.shape[1]), atol=1e-9)


def test_pca_basis_spans_the_same_expressions(model):
    mu = model.membership[:, CONTROL_REGIONS.index("mouth")]
    Qg = expression_basis(model.geometry, mu, "gram_schmidt")
    Qp = expression_basis(model.geometry, mu, "pca")
    assert Qp.shape == Qg.shape
    # the same geometric directions: both are orthonormal in the region's metric and span the
    # same expressions' differences, so one basis is an orthogonal transform of the other
    sw = np.sqrt(mu / mu.sum())
    G = (model.geometry * sw[None, :, None]).reshape(model.m, -1).T
    A, B = G @ Qg, G @ Qp
    np.testing.assert_allclose(B @ (B.T @ A), A, atol=1e-6)
    with pytest.raises(ValueError, match="basis"):
        expression_basis(model.geometry, mu, "ica")


def test_neutral_parameters_give_the_neutral_geometry(model):
    alpha = model.alpha_of_weights(np.eye(model.m)[0])
    W = model.region_weights(alpha)
    np.testing.assert_allclose(W, np.tile(np.eye(model.m)[0], (len(CONTROL_REGIONS), 1)), atol=1e-12)
    np.testing.assert_allclose(model.geometry_at(alpha), model.geometry[0], atol=1e-9)
    np.testing.assert_allclose(model.membership.sum(1), 1.0, atol=1e-12)


def test_full_expression_in_its_region_matches_the_true_geometry(model):

    E = true_expression_geometry(load_generic_mesh(), load_james_scan())
    k = EXPRESSION_NAMES.index("smile")
    W = np.tile(np.eye(model.m)[0], (len(CONTROL_REGIONS), 1))
    W[CONTROL_REGIONS.index("mouth")] = np.eye(model.m)[k]
    X = model.geometry_at(model.alpha_of_weights(W))
    inside = model.membership[:, CONTROL_REGIONS.index("mouth")] > 0.999
    # deep inside the mouth region the blend is the smile: membership ≥ 0.999 leaves ≤ 0.1 % of
    # the ≤ 7 mm smile displacement to the neighbouring (neutral) regions, < 0.01 mm
    np.testing.assert_allclose(X[inside], E[k][inside], atol=0.01)


def test_rendered_model_matches_the_video_frame_at_the_true_parameters(model):
    truth = video_truth(8)
    i = 4
    frame = render_video_frame(truth, i)

    cam = truth.camera(i)
    Wv = model.vertex_weights(truth.weights[i])
    r = render_model(get_renderer(), cam, model, model.blend_geometry(Wv), Wv, background=frame)
    assert r.mask.sum() > 10_000  # the face covers a good part of the 300×300 frame
    rms = np.sqrt(((r.image - frame)[r.mask] ** 2).mean())
    # measured 0.011: the model samples a 4× prefiltered texture through a ~3 mm mesh, the video
    # the full texture on the scan's own mesh with 3× supersampling; a wrong pose or blend
    # (e.g. a 1 px shift) gives > 0.04
    assert rms < 0.025
    # Eq. (5): with every expression sharing one texture, the weights sum to one everywhere
    np.testing.assert_allclose(r.interpolate(Wv).sum(1), 1.0, atol=1e-5)


def test_barycentric_render_agrees_with_the_renderer(model):
    """render_model's own pass (bounding box only, geometry shader) sees what Renderer.render sees."""

    truth = video_truth(8)
    cam = truth.camera(3)
    Wv = model.vertex_weights(truth.weights[3])
    X = model.blend_geometry(Wv)
    r = render_model(get_renderer(), cam, model, X, Wv)
    ref = get_renderer().render(cam, X, model.faces)
    np.testing.assert_array_equal(r.mask, ref.mask)  # same rasteriser, same fill rule
    same = np.all(model.faces[ref.face_id.reshape(-1)[r.pixels]] == r.corners, axis=1)
    # the same triangle everywhere but at a few z-ties (touching surfaces, lips; measured: 1 pixel)
    assert same.mean() > 0.999
    # the interpolated camera-space depth equals the z-buffer's (float32: ~1e-4 mm at 650 mm)
    np.testing.assert_allclose(r.X_cam[same, 2], ref.depth.reshape(-1)[r.pixels][same], atol=0.01)
    y0, y1, x0, x1 = r.box
    assert not r.mask[:y0].any() and not r.mask[y1:].any() and not r.mask[:, :x0].any() and not r.mask[:, x1:].any()
    np.testing.assert_allclose(r.bary.sum(1), 1.0, atol=1e-5)


def test_a_face_covering_more_than_32767_pixels_renders_like_a_small_one(model):
    """Regression (issue 15): the texture sampling crashed in ``cv2.remap`` (``dst.cols < SHRT_MAX``)
    once the face covered more than 32 767 pixels (a 640×360 close-up). The same view rendered at
    three times the focal length and size, averaged back over 3×3 blocks, is the small rendering."""
    truth = video_truth(1)
    cam = truth.camera(0)
    Wv = model.vertex_weights(model.region_weights(model.alpha_of_weights(np.eye(model.m)[0])))
    X = model.blend_geometry(Wv)
    small = render_model(get_renderer(), cam, model, X, Wv)
    big_cam = Camera(cam.R, cam.t, 3 * cam.f, 3 * cam.width, 3 * cam.height)
    big = render_model(get_renderer(), big_cam, model, X, Wv)
    assert big.mask.sum() > 32767 * 3  # far beyond the old limit
    down = big.image.reshape(cam.height, 3, cam.width, 3, 3).mean(axis=(1, 3))
    inner = small.mask & (big.mask.reshape(cam.height, 3, cam.width, 3).all(axis=(1, 3)))
    # the same surface sampled 9× more densely: colours agree up to the texture's detail at the
    # small view's pixel scale (texels ~1 px there), well under the tracker's image RMS (0.06)
    err = np.abs(down[inner] - small.image[inner])
    assert float(np.median(err)) < 0.02 and float(err.mean()) < 0.03, (np.median(err), err.mean())
