"""Tests of tracking.detected_pose: the first pose from the landmark detector, re-initialisation of a
lost track, the video camera's focal length — and tracking with a neutral-only face model — on the
sample video against its truth (sample_projects/james/video_truth.json)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from photomodel.camera import rotation_angle_deg
from photomodel.photos.video import VideoFrames
from photomodel.project import load_project
from tracking import detected_pose
from tracking.detected_pose import DEFAULT_FOCAL_WIDTHS, Redetector, landmark_error_px, video_focal_px
from tracking.first_pose import pose_from_spec
from tracking.frame_fit import FrameFitter, FrameResult, FrameState
from tracking.run import WORK_FACE_PX, _work_fitter, _work_frame, track_video
from tracking.synthetic_sequences.ground_truth import fitted_sample_model, model_gauge
from tracking.track_result import load_track_results

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
FRAMES = 3


@pytest.fixture(scope="module")
def truth(sample_video_truth):
    return sample_video_truth


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    """The sample video alone in a folder: no first-pose file beside it."""
    d = tmp_path_factory.mktemp("video")
    shutil.copy(SAMPLE / "video" / "james_track.mp4", d / "clip.mp4")
    return d / "clip.mp4"


def pose_errors(rec: dict, truth, model) -> tuple[float, float]:
    """Rotation (deg) and model-centre (mm, true scale) errors of a frame record, through the
    model's gauge (a model from photos has its own head frame and scale)."""
    s, Rg, tg = model_gauge(model)
    i = rec["frame"]
    centre = truth.t[i] + truth.R[i] @ (s * Rg @ model.centre + tg)
    rot = rotation_angle_deg(np.array(rec["R"]), truth.R[i] @ Rg)
    return rot, float(np.linalg.norm(s * np.array(rec["centre_mm"]) - centre))


def test_a_neutral_only_model_tracks_the_head_from_the_detectors_first_pose(fitted_sample, video, truth, tmp_path):
    result = track_video(
        fitted_sample,
        video,
        tmp_path / "out",
        expressions=["neutral"],
        focal_px=truth.focal_px,
        max_frames=FRAMES,
        plots=False,
        overlay=False,
    )
    doc = load_track_results(result.out_dir)
    assert doc["first_pose"]["source"].startswith("landmark detector on frame 0")
    assert doc["first_pose"]["spec"]["detected"] is True and len(doc["first_pose"]["spec"]["clicks"]) >= 6
    assert doc["model"]["expressions"] == ["neutral"] and doc["model"]["regions_with_parameters"] == []
    model = fitted_sample_model(("neutral",))
    for rec in doc["frames"]:
        rot, centre = pose_errors(rec, truth, model)
        # the video's face smiles and opens its mouth, which a neutral model cannot follow: measured
        # 0.3–0.5° and 1.0–1.4 mm; the bars leave room for the fitted model's own error
        assert rot < 1.5 and centre < 5.0, (rec["frame"], rot, centre)
        assert not rec["diverged"]
        # the model's projected pose features, recorded per frame, near the true model's
        assert set(rec["landmarks_xy"]) >= {"nose_tip", "eye_r_outer"}


def test_a_lost_track_is_fitted_again_from_the_detector(fitted_sample, video, truth):
    model = fitted_sample_model()
    s, Rg, tg = model_gauge(model)
    fitter = FrameFitter(model, truth.focal_px, truth.width, truth.height)
    watch = Redetector(load_project(fitted_sample), truth.focal_px, every=1)
    frame = next(VideoFrames(video).frames(0, 1))[1]
    R0, t0 = truth.R[0] @ Rg, (truth.t[0] + truth.R[0] @ (s * Rg @ model.centre + tg)) / s
    alpha = np.zeros(fitter.n_alpha)
    held = FrameResult(FrameState(R0, t0, alpha), model.region_weights(alpha), 0.05, 1000, 1, False)
    full = []
    real_detected_spec = detected_pose.detected_spec
    detected_pose.detected_spec = lambda *a, **k: full.append(1) or real_detected_spec(*a, **k)
    try:
        assert watch.restart_spec(0, frame, fitter, held) is None  # the true pose: nothing lost
    finally:
        detected_pose.detected_spec = real_detected_spec
    assert not full  # one face-mesh pass where the model sees the face told; no full detection
    # 40 mm to the side at ~600 mm: ~37 px, beyond LOST_PX; the detector's pose is then the start
    lost = FrameResult(FrameState(R0, t0 + [40.0, 0.0, 0.0], alpha), held.weights, 0.05, 1000, 1, False)
    spec = watch.restart_spec(0, frame, fitter, lost)
    assert spec is not None and spec["focal_px"] == truth.focal_px
    pose = pose_from_spec(spec, "detector", watch.project, model, truth.width, truth.height, None, 0)
    rec = {"frame": 0, "R": pose.state.R.tolist(), "centre_mm": pose.state.t.tolist()}
    rot, centre = pose_errors(rec, truth, model)
    # the detector's 12 points through PnP, before any fitting: a few degrees, ~1 cm in depth
    assert rot < 5.0 and centre < 20.0, (rot, centre)
    # checks are due every `every` frames only (and after a diverged frame)
    watch.every = 10
    assert watch.restart_spec(3, frame, fitter, lost) is None


def test_the_focal_length_comes_from_the_projects_cameras_of_the_videos_size(fitted_sample):
    project = load_project(fitted_sample)
    cams = [c for e in project.expressions for c in e.result.cameras.values()]
    w, h = cams[0].width, cams[0].height
    same = [c.f for c in cams if (c.width, c.height) == (w, h)]
    f, source = video_focal_px(project, w, h)
    assert f == pytest.approx(float(np.median(same))) and "fitted cameras" in source
    f, source = video_focal_px(project, 123, 45)  # no camera of that size: estimated from the width
    assert f == pytest.approx(DEFAULT_FOCAL_WIDTHS * 123) and source.startswith("estimated")
    # a phone held upright: the same lens, so the same focal length as the landscape frame's
    assert video_focal_px(project, 45, 123)[0] == pytest.approx(f)


def test_landmark_error_is_the_mean_distance_over_common_features():
    a = {"x": [0.0, 0.0], "y": [10.0, 0.0], "z": [5.0, 5.0]}
    b = {"x": [3.0, 4.0], "y": [10.0, 0.0]}
    assert landmark_error_px(a, b) == pytest.approx(2.5)
    assert landmark_error_px(a, {}) == float("inf")


def _frame0(truth):
    """The fitted sample's model and its true pose in the sample video's frame 0 (neutral face)."""
    model = fitted_sample_model()
    s, Rg, tg = model_gauge(model)
    state = FrameState(
        truth.R[0] @ Rg, (truth.t[0] + truth.R[0] @ (s * Rg @ model.centre + tg)) / s, np.zeros(sum(model.n_alpha))
    )
    return model, state


def test_a_large_face_is_fitted_on_frames_reduced_by_an_integer_factor(truth):
    model, state = _frame0(truth)
    small = FrameFitter(model, truth.focal_px, truth.width, truth.height)
    assert _work_fitter(small, state) is small  # the sample's ~150 px face: fitted as it is
    big = FrameFitter(model, 2 * truth.focal_px, 2 * truth.width, 2 * truth.height)  # a ~300 px face
    work = _work_fitter(big, state)
    assert (work.W, work.H, work.f) == (truth.width, truth.height, truth.focal_px)
    # the same pose seen by both cameras: pixel centres map exactly as the k × k area average does
    X = model.geometry[0][model.face_mask][::50]
    np.testing.assert_allclose(big.camera(state).project(X), 2 * (work.camera(state).project(X) + 0.5) - 0.5, atol=1e-9)
    frame = np.random.default_rng(0).random((2 * truth.height, 2 * truth.width, 3)).astype(np.float32)
    np.testing.assert_allclose(_work_frame(frame, work)[5, 7], frame[10:12, 14:16].mean(axis=(0, 1)), atol=1e-6)


def test_a_face_on_its_side_is_reduced_as_an_upright_one(truth):
    # a phone clip whose rotation was not applied shows the face lying on its side: its longer
    # extent (~254 px here, ~224 across) runs across the frame, and it costs as many pixels as the
    # upright face; measured by its height alone it would be fitted at full size (4× the pixels)
    model, state = _frame0(truth)
    roll = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90° about the optical axis
    side = FrameState(roll @ state.R, roll @ state.t, state.alpha)
    big = FrameFitter(model, 1.6 * truth.focal_px, 480, 480)
    uv = big.camera(side).project(model.geometry_at(side.alpha)[model.face_mask])
    width, height = np.ptp(uv, axis=0)
    assert height < 2 * WORK_FACE_PX <= width  # lying on its side, longer than two working faces
    upright, lying = _work_fitter(big, state), _work_fitter(big, side)
    assert (lying.W, lying.H, lying.f) == (upright.W, upright.H, upright.f) == (240, 240, 0.8 * truth.focal_px)
