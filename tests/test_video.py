"""Tests of tracking.video: a frame folder tracks like the video file it was taken from, and a
missing or unreadable video is named (by the library and by ``facestudio track``)."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from app.cli import main
from tracking.results import load_track_results
from tracking.run import track_video
from tracking.video import VideoError, VideoFrames

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
VIDEO = SAMPLE / "video" / "james_track.mp4"


def test_a_frame_folder_tracks_like_the_video(straight, tmp_path, fitted_sample):
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, frame in VideoFrames(VIDEO).frames(0, 2):  # lossless copies of the decoded frames
        cv2.imwrite(str(folder / f"f{i + 8}.png"), cv2.cvtColor(np.round(frame * 255).astype(np.uint8),
                                                                 cv2.COLOR_RGB2BGR))  # fmt: skip
    # f8 before f9 in natural order (and f10 would come after f9)
    shutil.copy(VIDEO.with_name("james_track.first_pose.json"), folder / "first_pose.json")
    res = track_video(fitted_sample, folder, tmp_path / "out", overlay=False, plots=False)
    doc = load_track_results(res.out_dir)
    assert doc["complete"] and doc["video"]["kind"] == "frames" and len(doc["frames"]) == 2
    for a, b in zip(doc["frames"], straight.frames, strict=False):
        np.testing.assert_allclose(a["centre_mm"], b["centre_mm"], atol=1e-4)


@pytest.mark.parametrize("kind", ["missing", "corrupt", "empty_folder", "bad_frame"])
def test_unreadable_video_is_named(tmp_path, kind, fitted_sample):
    if kind == "missing":
        path, words = tmp_path / "nope.mp4", "does not exist"
    elif kind == "corrupt":
        path, words = tmp_path / "broken.mp4", "cannot be opened"
        path.write_bytes(b"\x00not a video" * 50)
    elif kind == "empty_folder":
        path, words = tmp_path / "frames", "no PNG or JPG"
        path.mkdir()
    else:
        path, words = tmp_path / "frames", "not an image"
        path.mkdir()
        (path / "0001.png").write_bytes(b"garbage")
    with pytest.raises(VideoError, match=words) as err:
        track_video(fitted_sample, path, tmp_path / "out")
    assert str(path.name) in str(err.value)


def test_cli_reports_a_bad_video_with_exit_code_2(tmp_path, capsys, fitted_sample):
    assert main(["track", str(fitted_sample), "--video", str(tmp_path / "none.mp4"), "--out", str(tmp_path / "o")]) == 2
    assert "none.mp4 does not exist" in capsys.readouterr().err
