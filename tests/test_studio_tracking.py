"""The studio's tracking (app/studio/tracking.py) without Qt: the first frames of the sample video
tracked with the fitted sample's saved project file, the poses checked against video_truth.json."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.studio.tracking import TrackJob
from photomodel.camera import rotation_angle_deg
from photomodel.errors import ProjectError
from tracking.synthetic_sequences.ground_truth import fitted_sample_model, model_gauge
from tracking.track_result import load_track_results

REPO = Path(__file__).resolve().parents[1]
FRAMES = 3


def test_imports_no_qt():
    code = "import sys, app.studio.tracking; assert not [m for m in sys.modules if m.startswith('PySide6')]"
    subprocess.run([sys.executable, "-c", code], cwd=REPO, check=True)


def test_tracking_needs_a_saved_project(tmp_path):
    with pytest.raises(ProjectError, match="save the project first"):
        TrackJob.prepare(None, tmp_path / "clip.mp4")
    job = TrackJob.prepare(tmp_path / "p" / "x.facestudio.json", "clip.mp4", max_frames=5, plots=False)
    assert job.out_dir == tmp_path / "p" / "results" / "track_clip"  # beside the project, as `facestudio track`
    assert job.video == Path("clip.mp4").absolute() and job.settings == {"plots": False}


def test_track_job_follows_the_true_motion(fitted_project_copy, sample_video_truth):
    video = fitted_project_copy.parent / "video" / "james_track.mp4"
    job = TrackJob.prepare(fitted_project_copy, video, max_frames=FRAMES, plots=False, overlay=False)
    heard = []
    result = job.run(progress=lambda message, fraction: heard.append((message, fraction)))
    assert result.tracked == FRAMES and not result.cancelled
    assert heard[-1] == (f"tracked frame {FRAMES} of {FRAMES}", 1.0)  # of the frames asked for
    assert [fraction for _, fraction in heard] == sorted(fraction for _, fraction in heard)
    doc = load_track_results(job.out_dir)
    assert [f["frame"] for f in doc["frames"]] == list(range(FRAMES))
    # the fitted model's head frame and scale → the truth's (as tests/test_run.py); tolerances as
    # there: 1° in rotation, 8 mm of the centre at ~600 mm, the smile weight within 0.1
    model = fitted_sample_model(tuple(doc["model"]["expressions"]))
    s, Rg, tg = model_gauge(model)
    truth = sample_video_truth
    for f in doc["frames"]:
        i = f["frame"]
        assert rotation_angle_deg(np.array(f["R"]), truth.R[i] @ Rg) < 1.0
        centre = truth.t[i] + truth.R[i] @ (s * Rg @ model.centre + tg)
        assert np.linalg.norm(s * np.array(f["centre_mm"]) - centre) < 8.0
        assert abs(f["weights"]["mouth"]["smile"] - truth.weights[i, 1, 1]) < 0.1
