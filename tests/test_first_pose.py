"""Tests of tracking.first_pose: the first-pose file format (a pose or clicks, the focal length,
a start expression) and its errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from photomodel.errors import FitError
from photomodel.project import load_project
from tracking.first_pose import load_first_pose
from tracking.synthetic_sequences.ground_truth import sample_face_model

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
VIDEO = SAMPLE / "video" / "james_track.mp4"


@pytest.fixture(scope="module")
def truth(sample_video_truth):
    return sample_video_truth


def test_first_pose_files(truth, tmp_path, fitted_sample):
    project = load_project(fitted_sample)
    model = sample_face_model()
    R, t = truth.R[0], truth.t[0]
    fp = load_first_pose(
        {"focal_px": 560.0, "R": R.tolist(), "t_mm": t.tolist(), "weights": {"mouth": {"smile": 0.5}}},
        project,
        model,
        300,
        300,
    )
    np.testing.assert_allclose(fp.state.t, t + R @ model.centre)
    assert abs(model.region_weights(fp.state.alpha)[1, 1] - 0.5) < 1e-9
    fp = load_first_pose(
        {"focal_mm": 50.0, "rotation_vector": [0.0, 0.0, 0.0], "t_mm": [0, 0, 600]}, project, model, 300, 300
    )
    assert fp.focal_px == pytest.approx(50.0 * 300 / 36.0)
    clicks = json.loads(VIDEO.with_name("james_track.first_pose.json").read_text())["clicks"]
    few = dict(list(clicks.items())[:4])
    cases = [
        ({"clicks": clicks}, "focal length is missing"),
        ({"focal_px": 560, "clicks": few}, "at least 6"),
        ({"focal_px": 560, "clicks": {**clicks, "nose_tipp": [1, 2]}}, "nose_tipp"),
        ({"focal_px": 560, "R": np.eye(3).tolist()}, "t_mm"),
        ({"focal_px": 560, "R": (2 * np.eye(3)).tolist(), "t_mm": [0, 0, 1]}, "not a rotation"),
        ({"focal_px": 560}, "either 'clicks'"),
        ({"focal_px": -1, "clicks": clicks}, "positive"),
    ]
    for spec, words in cases:
        with pytest.raises(FitError, match=words):
            load_first_pose(spec, project, model, 300, 300)
    with pytest.raises(FitError, match="does not exist"):
        load_first_pose(tmp_path / "missing.json", project, model, 300, 300)
