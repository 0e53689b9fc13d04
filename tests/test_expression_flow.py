"""Writing an edited frame by the expression flow (tracking/expression_flow.py, Yang et al. 2012 §4, Eq. 24)."""

import cv2
import numpy as np
import pytest

from photomodel.camera import Camera
from photomodel.rendering.renderer import get_renderer
from tracking.blendshape_face import render_model
from tracking.edit import scale_expression
from tracking.expression_flow import edit_frame, expression_flow
from tracking.synthetic_sequences.expressions import EXPRESSION_NAMES
from tracking.synthetic_sequences.ground_truth import BACKGROUND_RGB, sample_face_model, video_truth

SMILE = EXPRESSION_NAMES.index("smile")


@pytest.fixture(scope="module")
def scene():
    model = sample_face_model(EXPRESSION_NAMES)
    truth = video_truth(40)
    i = 12  # the smile's peak (0.8)
    R = truth.R[i]
    cam = Camera(R, truth.t[i], truth.focal_px, truth.width, truth.height)
    bg = np.broadcast_to(np.asarray(BACKGROUND_RGB, np.float32), (truth.height, truth.width, 3))

    def render(W):
        Wv = model.vertex_weights(W)
        return render_model(get_renderer(), cam, model, model.blend_geometry(Wv), Wv, bg)

    return model, cam, truth.weights[i], render


def psnr(a, b, mask):
    return 10 * np.log10(1.0 / float(((a - b) ** 2)[mask].mean()))


@pytest.mark.parametrize("factor", [0.0, 1.5])
def test_edited_frame_matches_the_model_rendered_with_the_edited_weights(scene, factor):
    """The model rendered at the true weights is the frame; rendered at the edited weights, the truth
    (the renderer, not the flow, makes both)."""
    model, cam, W, render = scene
    W_edit = scale_expression(W[None], SMILE, np.array([factor]))[0]
    (frame, a), (want, b) = ((r.image, r.mask) for r in (render(W), render(W_edit)))
    out = edit_frame(get_renderer(), model, cam, frame, model.alpha_of_weights(W), model.alpha_of_weights(W_edit))
    # where the edit shows, on the skin: this model has a gap down the middle (triangles across the
    # scan's texture charts are dropped) where the background shows through and does not move
    skin = cv2.erode((a & b).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    changed = (np.abs(want - frame).max(axis=2) > 2 / 255) & skin
    # the smile moves the mouth corners by ~4 px; the warp resamples the frame bilinearly (a
    # texture of 1/4 of the scan's resolution at ~1 texel per pixel): 30 dB is the bar
    assert changed.sum() > 300
    assert psnr(out.image, want, changed) > 30.0
    assert psnr(out.image, want, changed) > psnr(frame, want, changed) + 10.0  # far better than no edit
    # away from what moves, the frame's own pixels, bit for bit
    np.testing.assert_array_equal(out.image[~out.moved], frame[~out.moved])
    # ... and nothing moves beyond the flow's falloff (FALLOFF_CUT × extend_px = 12 px) around the model
    near = cv2.dilate((a | b).astype(np.uint8), np.ones((27, 27), np.uint8)).astype(bool)
    assert not (out.moved & ~near).any()


def test_flow_is_the_projected_motion_of_the_surface(scene):
    model, cam, W, _ = scene
    W_edit = scale_expression(W[None], SMILE, np.array([0.0]))[0]
    X_t, X_e = (model.geometry_at(model.alpha_of_weights(w)) for w in (W, W_edit))
    raster = get_renderer().rasterize_barycentric(cam, X_e, model.faces)
    flow = expression_flow(get_renderer(), model, raster, cam, X_t)
    # Eq. 24 at the pixels' surface points: the barycentric combination of the tracked projections
    b = raster.bary.astype(float)
    want = np.einsum("nc,ncd->nd", b, cam.project(X_t)[raster.corners])
    np.testing.assert_allclose(flow.source, want, atol=1e-3)  # float32 interpolation
    assert flow.hidden.mean() < 0.02  # a smile hides almost nothing
