"""Tests of photomodel.photos.video: a frame folder tracks like the video file it was taken from, and a
missing or unreadable video is named (by the library and by ``facestudio track``)."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from app.cli import main
from photomodel.photos.video import VideoError, VideoFrames, frame_files
from tracking.run import track_video
from tracking.track_result import load_track_results

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
VIDEO = SAMPLE / "video" / "james_track.mp4"


def test_a_frame_folder_tracks_like_the_video(straight, tmp_path, fitted_sample):
    folder = tmp_path / "frames"
    folder.mkdir()
    for i, frame in VideoFrames(VIDEO).frames(0, 2):  # lossless copies of the decoded frames
        cv2.imwrite(
            str(folder / f"f{i + 8}.png"), cv2.cvtColor(np.round(frame * 255).astype(np.uint8), cv2.COLOR_RGB2BGR)
        )
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
        path, words = tmp_path / "frames", "holds no images"
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


def test_a_frame_folder_takes_one_frame_name_pattern_and_lists_what_it_ignored(tmp_path):
    img = np.zeros((8, 10, 3), np.uint8)
    for name in ("frame_2.png", "frame_10.png", "frame_1.png", "contact_sheet.png", "poster_1.jpg"):
        cv2.imwrite(str(tmp_path / name), img if name.startswith("frame") else np.zeros((20, 20, 3), np.uint8))
    (tmp_path / "notes.txt").write_text("not an image")
    for name in ("._frame_1.png", "._frame_2.png", "._frame_10.png"):  # macOS's AppleDouble files: not frames
        (tmp_path / name).write_bytes(b"\0\5\x16\7")
    v = VideoFrames(tmp_path)
    assert [p.name for p in v.files] == ["frame_1.png", "frame_2.png", "frame_10.png"]  # natural order
    assert [p.name for p in v.ignored] == ["contact_sheet.png", "poster_1.jpg"]
    assert (v.width, v.height) == (10, 8)  # frame 0 is a frame, not the contact sheet that sorted first
    assert frame_files([tmp_path / "a.png", tmp_path / "b.png"]) == ([tmp_path / "a.png", tmp_path / "b.png"], [])
