"""Tests of tracking.review: tracking results opened for viewing without Qt (the tracking view's
state): records, footage, plots, overlays and the tracked feature positions of ``straight``
(tests/conftest.py: the first frames of the sample video)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from photomodel.errors import FaceStudioError
from photomodel.exchange.files import decode_png
from photomodel.photos.video import VideoFrames
from photomodel.project import load_project
from tracking.review import TrackReview
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


def test_overlays_and_tracked_feature_positions(straight, fitted_sample):
    review = TrackReview.open(straight.out_dir)
    assert review.fitter() is review.fitter()  # built once
    last = FRAMES - 1
    img = review.overlay(last, review.footage_frame(last))
    # the code path of overlay.mp4: its last frame, as the run saved it
    written = decode_png(straight.files["overlay_last"].read_bytes()).astype(int)
    assert np.abs(np.round(img * 255).astype(int) - written).max() <= 1
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
