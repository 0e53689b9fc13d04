"""The real-footage sample's clip: fetched by package name with checksums, frames read in order."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from photomodel.errors import SampleDataError
from photomodel.project import load_project
from photomodel.samples.real_clip import (
    FRAMES,
    STAMP_FILE,
    clip_path,
    intake_fingerprint,
    read_frames,
    real_sample_project,
)


def test_the_sample_frames_are_read_from_the_verified_clip():
    frames = read_frames(clip_path(), FRAMES)
    assert sorted(frames) == sorted(FRAMES)
    images = [cv2.imdecode(np.frombuffer(b, np.uint8), cv2.IMREAD_COLOR) for b in frames.values()]
    assert all(im.shape == (360, 640, 3) for im in images)  # the clip is 640×360
    assert len({im.tobytes() for im in images}) == len(FRAMES)  # different frames, not one repeated


def test_a_frame_past_the_end_is_named():
    with pytest.raises(SampleDataError, match=r"\[472\]"):  # 472 frames: 0..471
        read_frames(clip_path(), (0, 472))


def test_a_cached_sample_made_by_other_landmark_code_is_made_again(tmp_path):
    """The cached real sample remembers what placed its landmarks: made by other code, it is
    made again rather than measured stale; made by this code, it is reused as it is."""
    path = real_sample_project(tmp_path)
    stamp = tmp_path / STAMP_FILE
    assert json.loads(stamp.read_text()) == {"intake": intake_fingerprint()}
    made = path.stat().st_mtime_ns
    assert real_sample_project(tmp_path) == path and path.stat().st_mtime_ns == made  # reused
    stamp.write_text(json.dumps({"intake": "an earlier detector"}))
    assert real_sample_project(tmp_path) == path
    assert path.stat().st_mtime_ns != made  # made again
    assert json.loads(stamp.read_text()) == {"intake": intake_fingerprint()}
    assert len(load_project(path).expressions[0].photos) == len(FRAMES)
