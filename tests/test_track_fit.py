"""Tests of tracking.frame_fit: Jacobians (§6.1.3, App. B), LM fitting (§6.1.2), prediction, first pose."""

import dataclasses

import cv2
import numpy as np
import pytest

from photomodel.camera import rodrigues, rotation_angle_deg
from photomodel.modeling.generic_mesh import load_generic_mesh
from tracking.frame_fit import (
    FrameFitter,
    FrameState,
    Phase,
    TrackOptions,
    nearest_rotation,
    pose_from_clicks,
    predict,
)
from tracking.synthetic_sequences.ground_truth import render_video_frame, sample_face_model, video_truth


@pytest.fixture(scope="module")
def setup():
    model = sample_face_model()
    truth = video_truth(8)
    return model, truth


def _state(model, truth, i):
    R = truth.R[i]
    return FrameState(R, truth.t[i] + R @ model.centre, model.alpha_of_weights(truth.weights[i]))


def test_analytic_jacobian_agrees_with_central_differences(setup):
    model, truth = setup
    # a smooth texture: Eq. (7) is a first-order (optical-flow) model, exact only where the
    # image is smooth at the scale of the motion; with the raw texture central differences see
    # texel-scale detail the 3×3 Sobel gradient cannot
    T = cv2.GaussianBlur(model.textures[0], (0, 0), 4)
    smooth = dataclasses.replace(model, textures=[T] * model.m, _texture_groups=[])
    fitter = FrameFitter(smooth, truth.focal_px, truth.width, truth.height)
    st = _state(smooth, truth, 5)
    blank = np.zeros((truth.height, truth.width, 3), np.float32)
    frame = fitter._evaluate(blank, st, False).render.image  # the model's own image
    params = np.arange(6 + fitter.n_alpha)
    for filtered in (False, True):
        ev = fitter._evaluate(frame, st, filtered)
        Ja = fitter.jacobian(frame, ev, params, "analytic", filtered)
        Jf = fitter.jacobian(frame, ev, params, "fd", filtered)
        # compare away from the silhouette (3 px): a moving edge flips whole pixels, which central
        # differences see as large jumps and the gradient model smooths
        y0, y1, x0, x1 = ev.box
        inner = cv2.erode(ev.render.mask.astype(np.uint8), np.ones((7, 7), np.uint8))[y0:y1, x0:x1]
        sel = np.repeat(inner.reshape(-1).astype(bool), 3)
        a, f = Ja[sel], Jf[sel]
        cos = (a * f).sum(0) / np.linalg.norm(a, axis=0) / np.linalg.norm(f, axis=0)
        ratio = np.linalg.norm(a, axis=0) / np.linalg.norm(f, axis=0)
        # measured (this frame): translation x/y and the smile/brow directions 0.95–0.998; rotations
        # and depth 0.70–0.88 (the nose's silhouette moves over the cheek: internal occlusion
        # edges flip pixels); the jaw-opening direction ~0.4 unfiltered (its stretched lips fold
        # over themselves); all columns point the same way, and most agree closely
        assert np.all(cos > 0.3), cos
        assert np.median(cos) > 0.85, cos
        assert np.sum(cos > 0.95) >= 4, cos
        assert np.all((ratio > 0.3) & (ratio < 1.5)), ratio


def test_fit_recovers_a_known_pose_and_expression(setup):
    model, truth = setup
    i = 5
    fitter = FrameFitter(
        model,
        truth.focal_px,
        truth.width,
        truth.height,
        TrackOptions(pose_iterations=8, expression_iterations=8, rounds=3),
    )
    true = _state(model, truth, i)
    blank = np.zeros((truth.height, truth.width, 3), np.float32)
    frame = fitter._evaluate(blank, true, False).render.image  # rendered from the model itself
    init = FrameState(
        rodrigues(np.radians([1.5, -1.0, 0.5])) @ true.R, true.t + [3.0, -2.0, 8.0], np.zeros_like(true.alpha)
    )
    rms0 = fitter._evaluate(frame, init, False).rms
    res = fitter.fit(frame, init)
    assert not res.diverged
    # the synthetic test of §6.2: from ~2° / 9 mm and a neutral face, pose to ≤ 0.2° and ≤ 1 mm
    assert rotation_angle_deg(res.state.R, true.R) < 0.2
    assert np.linalg.norm(res.state.t - true.t) < 1.0
    Xt, Xe = model.geometry_at(true.alpha), model.geometry_at(res.state.alpha)
    geom = np.linalg.norm(Xt - Xe, axis=1)[model.face_mask]
    assert geom.mean() < 0.5  # mm, the bar for sequence (a)
    assert res.rms < 0.5 * rms0
    np.testing.assert_array_less(-0.5 - 1e-9, res.weights)
    np.testing.assert_array_less(res.weights, 1.5 + 1e-9)


def test_the_clip_solves_seam_refines_a_pose_and_linearises_the_expression(setup):
    # FrameFitter's public seam for tracking.smooth: one LM phase (refine) and the expression
    # phase's linearisation (linearise_expression)
    model, truth = setup
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height)
    true = _state(model, truth, 5)
    blank = np.zeros((truth.height, truth.width, 3), np.float32)
    frame = fitter._evaluate(blank, true, False).render.image  # rendered from the model itself
    start = FrameState(rodrigues(np.radians([1.0, -0.5, 0.3])) @ true.R, true.t + [2.0, -1.0, 4.0], true.alpha.copy())
    pose = Phase(np.arange(6), 10, "analytic", filtered=False, reuse=False)
    done = fitter.refine(frame, start, pose)
    np.testing.assert_array_equal(done.alpha, true.alpha)  # the phase moves the pose only
    assert rotation_angle_deg(done.R, true.R) < 0.5 * rotation_angle_deg(start.R, true.R)
    assert np.linalg.norm(done.t - true.t) < 0.5 * np.linalg.norm(start.t - true.t)
    system = fitter.linearise_expression(frame, true)
    a = fitter.n_alpha
    assert system.JtJ.shape == (a, a) and system.Jtr.shape == (a,) and system.pixels > 200
    np.testing.assert_allclose(system.JtJ, system.JtJ.T, rtol=1e-6, atol=1e-9 * np.trace(system.JtJ))
    # at the state the frame was rendered from the residual, and so Jᵀr, vanishes
    assert np.abs(system.Jtr).max() < 1e-6 * np.sqrt(np.trace(system.JtJ))


def test_penalty_gradient_matches_differences(setup):
    model, truth = setup
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height)
    blank = np.zeros((truth.height, truth.width, 3), np.float32)
    st = _state(model, truth, 5)
    render = fitter._evaluate(blank, st, False).render
    alpha = np.array([2.0, -7.0, 1.5, -3.0])[: fitter.n_alpha]  # weights outside [0, 1]
    D, g, H = fitter._penalty(model.region_weights(alpha), render)
    assert D > 0
    h = 1e-6
    num = [
        (
            fitter._penalty(model.region_weights(alpha + h * e), render)[0]
            - fitter._penalty(model.region_weights(alpha - h * e), render)[0]
        )
        / (2 * h)
        for e in np.eye(len(alpha))
    ]
    np.testing.assert_allclose(g, num, rtol=1e-5, atol=1e-6 * abs(D))


def test_prediction_extrapolates_linearly():
    a = FrameState(np.eye(3), np.zeros(3), np.array([0.0, 1.0]))
    Rb = rodrigues(np.array([0.0, 0.1, 0.0]))
    b = FrameState(Rb, np.array([1.0, 2.0, 3.0]), np.array([0.5, 1.0]))
    p = predict([a, b])
    np.testing.assert_allclose(p.t, [2.0, 4.0, 6.0])
    np.testing.assert_allclose(p.alpha, [1.0, 1.0])
    np.testing.assert_allclose(p.R, rodrigues(np.array([0.0, 0.2, 0.0])), atol=1e-12)
    np.testing.assert_allclose(predict([b]).t, b.t)


def test_prediction_keeps_rotations_orthonormal():
    # a head turning steadily, each frame's fit returning its prediction: the old extrapolation
    # (R₁ R₀ᵀ) R₁ grew round-off in the symmetric part by 1 + √2 per frame (≈ 1e-2 after 36
    # frames: the model shrank and the tracker drifted in depth); the projected one keeps
    # rotations to round-off and follows the true motion
    w = np.array([0.01, -0.02, 0.005])
    R0 = rodrigues(np.array([0.1, 0.2, -0.1])) @ np.diag([1.0, -1.0, -1.0])
    states = [FrameState(R0, np.zeros(3), np.zeros(1)), FrameState(rodrigues(w) @ R0, np.zeros(3), np.zeros(1))]
    for _ in range(60):
        states.append(predict(states[-2:]))
    R = states[-1].R
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(R, rodrigues(61 * w) @ R0, atol=1e-9)
    np.testing.assert_allclose(nearest_rotation(2.0 * R), R, atol=1e-12)


def test_fit_follows_a_fast_head_movement(setup):
    model, _ = setup
    # a 10-frame clip of the sample motion: frame 1 is ~9° and 3 mm from its prediction (frame 0),
    # frame 7 ~7° and 5 mm from the extrapolation of frames 5 and 6; the fixed budget of one pose
    # step and three expression steps stopped at 1.8° / 5 mm and 1.1° / 2.7 mm, and the errors
    # then grew from frame to frame until the track diverged
    truth = video_truth(10)
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height)
    for i, previous in ((1, [0]), (7, [5, 6])):
        res = fitter.fit(render_video_frame(truth, i), predict([_state(model, truth, j) for j in previous]))
        true = _state(model, truth, i)
        # measured 0.01–0.05° and 0.02–0.44 mm (the video is the scan, not the model: ~0.2 mm of
        # geometry error remain, mostly depth)
        assert rotation_angle_deg(res.state.R, true.R) < 0.2
        assert np.linalg.norm(res.state.t - true.t) < 1.5
        assert not res.diverged


def test_first_pose_from_clicks(setup):
    model, truth = setup

    mesh = load_generic_mesh()
    ids = np.array([mesh.features[n] for n in mesh.initial_features])
    cam = truth.camera(0)
    rng = np.random.default_rng(0)
    clicks = cam.project(model.geometry[0][ids]) + rng.normal(0, 0.5, (len(ids), 2))  # careful clicks
    st = pose_from_clicks(model, ids, clicks, truth.focal_px, truth.width, truth.height)
    true = _state(model, truth, 0)
    # 13 clicks with 0.5 px noise on a ~150 px face: about a degree and a few mm (depth)
    assert rotation_angle_deg(st.R, true.R) < 2.0
    assert np.linalg.norm(st.t - true.t) < 15.0
    with pytest.raises(Exception, match="at least 6"):
        pose_from_clicks(model, ids[:4], clicks[:4], truth.focal_px, truth.width, truth.height)


@pytest.fixture(scope="module")
def frown_model():
    from tracking.synthetic_sequences.expressions import EXPRESSION_NAMES, EXTRA_EXPRESSIONS

    return sample_face_model(EXPRESSION_NAMES + EXTRA_EXPRESSIONS)


def test_home_regions_are_where_the_expressions_were_made(frown_model):
    from tracking.blendshape_face import CONTROL_REGIONS
    from tracking.frame_fit import home_regions

    # the sample's fields (tracking.synthetic_sequences.expressions): smile and open mouth move the mouth and
    # jaw, brows raised and frown move the brows
    home = [CONTROL_REGIONS[r] if k else "neutral" for k, r in enumerate(home_regions(frown_model))]
    assert dict(zip(frown_model.names, home, strict=True)) == {
        "neutral": "neutral",
        "smile": "mouth",
        "open_mouth": "mouth",
        "brows_raised": "forehead",
        "frown": "forehead",
    }


def test_coherence_prior_costs_what_a_region_shows_beyond_the_home_region(frown_model, setup):
    from tracking.blendshape_face import CONTROL_REGIONS

    truth = setup[1]
    model = frown_model
    eyes, fore = CONTROL_REGIONS.index("eyes"), CONTROL_REGIONS.index("forehead")
    frown = model.names.index("frown")
    W = np.zeros((len(CONTROL_REGIONS), model.m))
    W[:, 0] = 1.0
    W[eyes, [0, frown]] = [0.7, 0.3]  # the eyes frown 0.3, their home region (forehead) only 0.1
    W[fore, [0, frown]] = [0.9, 0.1]
    alpha = model.alpha_of_weights(W)
    blank = np.zeros((truth.height, truth.width, 3), np.float32)
    on = FrameFitter(model, truth.focal_px, truth.width, truth.height)
    off = FrameFitter(model, truth.focal_px, truth.width, truth.height, TrackOptions(coherence=0.0))
    st = FrameState(truth.R[0], truth.t[0] + truth.R[0] @ model.centre, alpha)
    render = on._evaluate(blank, st, False).render
    weights = model.region_weights(alpha)
    D_on, D_off = on._penalty(weights, render)[0], off._penalty(weights, render)[0]
    assert D_off == pytest.approx(0.0, abs=1e-9)  # every weight within [0, 1]
    c = on.options.penalty * len(render.pixels)
    assert D_on == pytest.approx(c * 0.2**2, rel=1e-6)  # κ = 1: c (0.3 − 0.1)²
    # the gradient and Hessian of the active pieces agree with differences of D
    h = 1e-5
    num = np.array(
        [
            (
                on._penalty(model.region_weights(alpha + h * e), render)[0]
                - on._penalty(model.region_weights(alpha - h * e), render)[0]
            )
            / (2 * h)
            for e in np.eye(len(alpha))
        ]
    )
    _, g, H = on._penalty(weights, render)
    # atol: weights exactly at a bound of [0, 1] (the other regions' neutral) make the central
    # difference of D's one-sided piece c·h²/(2h) there
    np.testing.assert_allclose(g, num, rtol=1e-5, atol=2 * c * h)
    step = 1e-3 * np.random.default_rng(0).normal(size=len(alpha))
    # on the same quadratic pieces, the gradient changes by H·step
    g2 = on._penalty(model.region_weights(alpha + step), render, on._sides(weights))[1]
    np.testing.assert_allclose(g2 - g, H @ step, rtol=1e-6, atol=1e-9 * np.abs(g).max())


def test_colour_match_undoes_a_change_of_the_footages_colour(setup):
    # TrackOptions.colour_match: footage whose channels are scaled and offset (another camera's
    # white balance) against the model's texture; the match is the inverse map, learnt from the
    # fitted frames (smoothing 1: each frame's own estimate)
    model, truth = setup
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height, TrackOptions(colour_smoothing=1.0))
    assert fitter.colour is None
    gain, offset = np.float32([1.10, 0.92, 1.05]), np.float32([0.04, -0.03, 0.0])
    blank = np.zeros((truth.height, truth.width, 3), np.float32)
    for i in (4, 5, 6):  # each frame from the one before's true state (8 frames: fast motion)
        true = _state(model, truth, i)
        frame = fitter._evaluate(blank, true, False).render.image * gain + offset
        fitter.fit(frame, _state(model, truth, i - 1))
    a, b = fitter.colour
    # exact inverse: gain 1/g, offset −o/g; the tolerance (1 %, 0.01) allows for the last frame's
    # fit being off by a fraction of a pixel (its residual enters the regression)
    np.testing.assert_allclose(a, 1.0 / gain, rtol=0.01)
    np.testing.assert_allclose(b, -offset / gain, atol=0.01)


@pytest.mark.parametrize("bad", [{"robust_window": 2}, {"robust_window": 0}, {"colour_smoothing": 0.0}])
def test_track_options_refuse_a_bad_window_or_smoothing(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        TrackOptions(**bad)
