"""Tests of tracking.review: tracking results opened for viewing without Qt (the tracking view's
state): records, footage, plots, overlays and the tracked feature positions of ``straight``
(tests/conftest.py: the first frames of the sample video)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from photomodel.errors import FaceStudioError
from photomodel.exchange.files import decode_png
from photomodel.photos.video import VideoFrames
from photomodel.project import load_project
from photomodel.rendering.renderer import get_renderer
from tracking.review import TrackReview
from tracking.synthetic_sequences.ground_truth import true_vertices
from tracking.track_result import load_track_results

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
VIDEO = SAMPLE / "video" / "james_track.mp4"
FRAMES = 6


def test_a_review_holds_the_results_their_footage_and_plots(straight):
    review = TrackReview.open(straight.out_dir)
    assert review.out_dir == straight.out_dir and review.doc == load_track_results(straight.out_dir)
    assert review.frame_count == FRAMES and review.records == review.doc["frames"]
    assert len(review.footage) == FRAMES and review.footage[0].dtype == np.uint8 and review.footage_error == ""
    for i, frame in VideoFrames(VIDEO).frames(0, FRAMES):  # 8-bit footage: kept exactly
        np.testing.assert_array_equal(review.footage_frame(i), frame)
    assert review.footage_frame(FRAMES) is None
    assert set(review.plots) == {"weights.png", "rotation.png", "translation.png", "rms.png"}
    for name, img in review.plots.items():  # the images the run wrote
        np.testing.assert_array_equal(img, decode_png((straight.out_dir / name).read_bytes()), err_msg=name)
    settings = review.correction_settings()
    assert settings == {
        "video": VIDEO.absolute(),
        "expressions": review.doc["model"]["expressions"],
        "first_pose": review.doc["first_pose"]["spec"],
        "focal_px": review.doc["camera"]["focal_px"],
    }


def true_silhouette(truth, i: int, faces: np.ndarray) -> np.ndarray:
    """(H, W) bool: the outline (1 px, inside) of the model's triangles at frame ``i``'s true geometry
    seen by the true camera — where the overlay's outline belongs (closed by 5×5 like the overlay's)."""
    mask = get_renderer().render(truth.camera(i), true_vertices(truth, i), faces).mask.astype(np.uint8)
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    return (mask - cv2.erode(mask, np.ones((3, 3), np.uint8))) > 0


def test_overlays_and_tracked_feature_positions(straight, fitted_sample, sample_video_truth):
    review = TrackReview.open(straight.out_dir)
    assert review.fitter() is review.fitter()  # built once
    last = FRAMES - 1
    img = review.overlay(last, review.footage_frame(last))
    # the code path of overlay.mp4: its last frame, as the run saved it
    written = decode_png(straight.files["overlay_last"].read_bytes()).astype(int)
    assert np.abs(np.round(img * 255).astype(int) - written).max() <= 1
    # ... and against the truth, which that code did not make: the green outline of the model lies
    # on the true silhouette of its triangles in that frame. Measured: 76 % of the outline's pixels
    # within 2 px of it — the rest at the ear, where the model from photos bulges out ~10 px; with
    # the previous frame's pose (the head moves ~0.9 px a frame) 52 %, frame 0's 38 %, a focal
    # length 3 % off 62 %
    green = (img[..., 1] - np.maximum(img[..., 0], img[..., 2])) > 0.3
    edge = true_silhouette(sample_video_truth, last, review.fitter().model.faces)
    dist = cv2.distanceTransform((~edge).astype(np.uint8), cv2.DIST_L2, 3)
    assert green.sum() > 300 and (dist[green] <= 2.0).mean() > 0.7
    # frame 0 was fitted from the first pose's clicks: the tracked model puts the clicked
    # features within a few pixels of them (the clicks carry 0.5 px noise; the model is fitted)
    clicks = json.loads(VIDEO.with_name("james_track.first_pose.json").read_text())["clicks"]
    uv = review.feature_positions(0, load_project(fitted_sample))
    assert set(clicks) <= set(uv)
    err = [np.hypot(uv[n][0] - u, uv[n][1] - v) for n, (u, v) in clicks.items()]
    assert np.median(err) < 3.0, err


def test_missing_results_and_footage_are_named(straight, tmp_path):
    with pytest.raises(FaceStudioError, match="holds no track.json"):
        TrackReview.open(tmp_path)
    (tmp_path / "track.json").write_text("{}")
    with pytest.raises(FaceStudioError, match="not a Face Studio tracking file"):
        TrackReview.open(tmp_path)
    out = tmp_path / "moved"
    shutil.copytree(straight.out_dir, out)
    doc = json.loads((out / "track.json").read_text())
    doc["video"]["path"] = str(tmp_path / "gone.mp4")
    (out / "track.json").write_text(json.dumps(doc))
    review = TrackReview.open(out)
    assert review.frame_count == FRAMES and review.footage == [] and "gone.mp4 does not exist" in review.footage_error
    assert review.footage_frame(0) is None and len(review.plots) == 4
