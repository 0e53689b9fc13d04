"""A fresh run of a long clip tracked as two segments at once (tracking.segments): the same files
as one chain of frames, the second segment's frames close to the chain's, a cancel keeping the
first segment's frames."""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import tracking.segments as segments
from tracking.run import track_video

VIDEO = Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "video" / "james_track.mp4"
FRAMES = 30


@pytest.fixture
def short_segments(monkeypatch):
    # the sample video has 40 frames: segments of at least 12 frames put the seam in 12..18
    monkeypatch.setattr(segments, "MIN_FRAMES", 12)


def _frames(out):
    return json.loads((out / "track.json").read_text())["frames"]


def test_two_segments_track_what_one_chain_tracks(fitted_sample, tmp_path, short_segments):
    seen = []
    two = track_video(
        fitted_sample, VIDEO, tmp_path / "two", max_frames=FRAMES, plots=False, progress=lambda d, t: seen.append(d)
    )
    one = track_video(fitted_sample, VIDEO, tmp_path / "one", max_frames=FRAMES, plots=False, overlay=False, segments=1)
    a, b = _frames(tmp_path / "one"), _frames(tmp_path / "two")
    assert [r["frame"] for r in b] == list(range(FRAMES)) and two.tracked == FRAMES
    assert [r["start"] for r in b] == ["first_pose"] + ["predicted"] * (FRAMES - 1)
    assert max(seen) == FRAMES and len(one.frames) == FRAMES
    # the second segment starts from the detector's pose and converges to the chain's fit: the
    # sample video is a render of the modeled face, tracked to ~0.6° and ~1 mm of the truth
    # (bench_track, sequence b), so two fits of a frame differ by at most about twice that
    for ra, rb in zip(a, b, strict=True):
        turn = Rotation.from_rotvec(ra["rotation_vector"]).inv() * Rotation.from_rotvec(rb["rotation_vector"])
        assert np.degrees(turn.magnitude()) < 1.2, ra["frame"]
        assert np.linalg.norm(np.subtract(ra["t_mm"], rb["t_mm"])) < 3.0, ra["frame"]
    # the overlay video holds every frame, the second segment's included
    cap = cv2.VideoCapture(str(tmp_path / "two" / "overlay.mp4"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == FRAMES
    cap.release()


def test_a_cancel_keeps_the_first_segments_frames_only(fitted_sample, tmp_path, short_segments):
    done = []

    def cancel():
        return len(done) >= 1 and done[-1] >= 8

    res = track_video(
        fitted_sample,
        VIDEO,
        tmp_path / "out",
        max_frames=FRAMES,
        plots=False,
        overlay=False,
        progress=lambda d, t: done.append(d),
        cancel=cancel,
    )
    frames = [r["frame"] for r in _frames(tmp_path / "out")]
    assert res.cancelled and frames == list(range(len(frames))) and 1 <= len(frames) < 12


def test_what_is_not_split(fitted_sample, tmp_path, short_segments):
    # a short clip, one segment asked for: one chain (no second process, frames as ever)
    res = track_video(fitted_sample, VIDEO, tmp_path / "out", max_frames=20, plots=False, overlay=False)
    assert [r["start"] for r in res.frames] == ["first_pose"] + ["predicted"] * 19
    from tracking.run import _Run

    run = _Run.open(fitted_sample, VIDEO, tmp_path / "x", None, None, None, None, None, FRAMES, None)
    assert segments.plan_split(run, 0, None, 1) is None  # one segment asked for
    assert segments.plan_split(run, 5, None, 2) is None  # a continued run
    assert segments.plan_split(run, 0, 3, 2) is None  # a correction
    split = segments.plan_split(run, 0, None, 2)
    assert split is not None and 12 <= split.begin <= 18 and split.seam == split.begin + segments.WARM_FRAMES
    assert len(split.spec["clicks"]) >= 6


def test_a_failed_second_process_leaves_its_frames_to_this_one(fitted_sample, tmp_path, short_segments, monkeypatch):
    # whatever stops the second process (here: its results refused), this process tracks the
    # frames after the seam itself, from its own prediction: the same frames as one chain
    from photomodel.errors import FaceStudioError

    def refuse(self, wait):
        self.stop()
        raise FaceStudioError("the second tracking segment's process ended without results (exit code 1)")

    monkeypatch.setattr(segments.SegmentWorker, "results", refuse)
    res = track_video(fitted_sample, VIDEO, tmp_path / "out", max_frames=FRAMES, plots=False, overlay=False)
    assert [r["frame"] for r in res.frames] == list(range(FRAMES))
    assert [r["start"] for r in res.frames] == ["first_pose"] + ["predicted"] * (FRAMES - 1)
