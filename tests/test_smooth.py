"""The whole-clip smooth solve (tracking/smooth.py, Yang et al. 2012 §3.1.4, Eq. 15–23)."""

import numpy as np
import pytest

from photomodel.rendering.renderer import get_renderer
from tracking.blendshape_face import WEIGHT_RANGE, render_model
from tracking.frame_fit import FrameFitter, FrameState
from tracking.smooth import (
    SmoothOptions,
    _solve_in_range,
    difference_operator,
    jitter,
    smooth_clip,
    smoothness_matrix,
    solve_clip,
    weight_curves,
)
from tracking.synthetic_sequences.expressions import EXPRESSION_NAMES
from tracking.synthetic_sequences.ground_truth import BACKGROUND_RGB, sample_face_model, video_truth


def test_difference_penalties_are_the_stencils_of_eq_15():
    # Eq. 15: λ1 (−β_{t−1} + 2β_t − β_{t+1}) and λ2 (β_{t−2} − 4β_{t−1} + 6β_t − 4β_{t+1} + β_{t+2})
    K1, K2 = difference_operator(8, 1), difference_operator(8, 2)
    assert K1.shape == (7, 8) and K2.shape == (6, 8)
    np.testing.assert_array_equal((K1.T @ K1).toarray()[3, 2:5], [-1, 2, -1])
    np.testing.assert_array_equal((K2.T @ K2).toarray()[4, 2:7], [1, -4, 6, -4, 1])
    # Eq. 20–21: ⊗ I_a, frame-major
    H = smoothness_matrix(8, 2, 0.0, 1.0).toarray()
    np.testing.assert_array_equal(H[8:10, 8:10], 6 * np.eye(2))
    np.testing.assert_array_equal(H[8, 4:13:2], [1, -4, 6, -4, 1])


def test_clip_solve_removes_noise_around_a_known_smooth_curve():
    rng = np.random.default_rng(0)
    T, a = 60, 3
    s = np.linspace(0, 1, T)
    truth = np.column_stack([np.sin(2 * np.pi * s), np.exp(-0.5 * ((s - 0.5) / 0.15) ** 2), s])
    L = rng.normal(size=(T, a, a))
    A = L @ L.transpose(0, 2, 1) + 0.5 * np.eye(a)  # each frame's data term (Eq. 12), SPD
    noisy = truth + rng.normal(0, 0.05, truth.shape)  # what each frame alone would say
    B = np.einsum("tij,tj->ti", A, noisy)
    np.testing.assert_allclose(solve_clip(A, B, 0.0, 0.0), noisy, atol=1e-9)  # no smoothing: per frame
    lam = float(np.median(np.trace(A, axis1=1, axis2=2))) / a
    smooth = solve_clip(A, B, 0.0, 3.0 * lam)
    # the noise's second differences are ~2.4× its σ; a smooth curve's are ~1e-3: jitter falls by
    # far more than half, and the error against the truth by about half (noise averaged over a
    # few frames); bounds with margin over this seed
    assert jitter(smooth) < 0.3 * jitter(noisy)
    assert np.sqrt(np.mean((smooth - truth) ** 2)) < 0.7 * np.sqrt(np.mean((noisy - truth) ** 2))


@pytest.fixture(scope="module")
def model():
    return sample_face_model(EXPRESSION_NAMES)


def test_weights_stay_in_the_convex_range(model):
    T = 12
    a = sum(model.n_alpha)
    # data terms that want the mouth's smile weight at −0.4 and the brows at 1.4 in every frame
    W = np.tile(np.eye(model.m)[0], (T, len(model.bases), 1))
    mouth, fore = 1, 3
    W[:, mouth, 1], W[:, mouth, 0] = -0.4, 1.4
    W[:, fore, 3], W[:, fore, 0] = 1.4, -0.4
    want = np.array([model.alpha_of_weights(w) for w in W])
    A = np.tile(np.eye(a), (T, 1, 1)) * 100.0
    got = weight_curves(
        model,
        _solve_in_range(model, A, np.einsum("tij,tj->ti", A, want), want, np.full(T, 10000.0), 0.01, (0.0, 1.0, 0.0)),
    )
    # D (c = 0.01 × 10⁴ px = 100 per unit², as strong as the data) holds them halfway to [0, 1]
    assert got[:, mouth, 1].max() < -0.1 and got[:, mouth, 1].min() > -0.3
    assert got[:, fore, 3].min() > 1.1 and got[:, fore, 3].max() < 1.3
    lo, hi = WEIGHT_RANGE
    assert got.min() >= lo - 1e-9 and got.max() <= hi + 1e-9
    np.testing.assert_allclose(got.sum(axis=2), 1.0, atol=1e-9)


def test_smooth_clip_brings_jittered_tracking_back_to_the_truth(model):
    """Frames rendered from the model at the true weights; per-frame results = truth + jitter."""
    T = 10
    truth = video_truth(30)  # the sample motion; frames 8..17 hold the rising smile
    idx = np.arange(8, 8 + T)
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height)
    bg = np.broadcast_to(np.asarray(BACKGROUND_RGB, np.float32), (truth.height, truth.width, 3))
    frames, states, true_alpha = [], [], []
    rng = np.random.default_rng(3)
    for i in idx:
        Wv = model.vertex_weights(truth.weights[i])
        frames.append(render_model(get_renderer(), truth.camera(i), model, model.blend_geometry(Wv), Wv, bg).image)
        R = truth.R[i]
        alpha = model.alpha_of_weights(truth.weights[i])
        true_alpha.append(alpha)
        states.append(FrameState(R, truth.t[i] + R @ model.centre, alpha + rng.normal(0, 0.4, alpha.shape)))
    true_alpha = np.array(true_alpha)
    before = np.array([s.alpha for s in states])
    res = smooth_clip(fitter, frames, states, SmoothOptions(second_difference=1.0, rounds=1))
    after = np.array([s.alpha for s in res.states])
    # 0.4 mm of jitter per parameter; the images pin the truth (they are rendered from this model),
    # the smoothness removes what is left: the error must at least halve, and so must the jitter
    assert np.sqrt(np.mean((after - true_alpha) ** 2)) < 0.5 * np.sqrt(np.mean((before - true_alpha) ** 2))
    assert jitter(after) < 0.5 * jitter(before)
    np.testing.assert_allclose(res.weights, weight_curves(model, after))
