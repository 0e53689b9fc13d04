"""The landmark checks found in a background thread (tracking/landmark_checks.py) are the ones
the detector finds frame by frame in the foreground: same frames, same positions — whatever the
thread's timing (stopped early, the rest is detected when asked)."""

from __future__ import annotations

import numpy as np

from photomodel.photos.video import VideoFrames
from tests.real_clips import short_clip
from tracking.detected_pose import detected_features
from tracking.landmark_checks import LandmarkChecks

NAMES = ["eye_l_outer", "eye_r_outer", "nose_tip", "mouth_l", "mouth_r"]


def _serial(clip, n, every):
    return {i: detected_features(f, NAMES) for i, f in VideoFrames(clip).frames(0, n) if i % every == 0}


def test_thread_finds_what_the_foreground_finds(tmp_path):
    clip = short_clip(tmp_path / "clip.mp4", 7)
    checks = LandmarkChecks(clip, NAMES, 3, 7)
    got = checks.detections(7)
    want = _serial(clip, 7, 3)
    assert sorted(got) == [0, 3, 6] == sorted(want)
    for i in want:
        assert want[i] is not None and set(got[i]) == set(want[i])
        # the same network on the same pixels: equal up to float noise of the forward pass
        np.testing.assert_allclose(
            [got[i][k] for k in NAMES if k in want[i]], [want[i][k] for k in NAMES if k in want[i]], atol=1e-2
        )


def test_stopped_early_the_rest_is_detected_when_asked(tmp_path):
    clip = short_clip(tmp_path / "clip.mp4", 5)
    checks = LandmarkChecks(clip, NAMES, 2, 5)
    checks.stop()  # before or after some frames: the answer must not depend on it
    got = checks.detections(5)
    assert sorted(got) == [0, 2, 4]
    assert all(got[i] is not None for i in got)
