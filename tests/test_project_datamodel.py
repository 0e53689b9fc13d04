"""Tests of photomodel.project.datamodel: look-ups, observations, default result paths, checks against
the generic mesh and the photos on disk, camera groups."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from project_samples import H, W, save_sample

from photomodel.errors import ProjectError
from photomodel.photos.reading import photo_size
from photomodel.project import Expression, Photo, Project, load_project


@pytest.fixture
def saved(tmp_path):
    """(path, dict) of a valid saved project with its photos on disk."""
    return save_sample(tmp_path)


def test_helpers(tmp_path, saved):
    path, _ = saved
    p = load_project(path)
    assert p.feature_names() == ["nose_tip", "eye_l", "jaw_00"]
    assert p.feature_names(pose_only=True) == ["nose_tip", "eye_l"]
    np.testing.assert_array_equal(p.feature_vertices(["eye_l", "jaw_00"]), [20, 30])
    assert p.photo_path(p.expression("smile").photos[0]) == tmp_path / "photos" / "smile_front.png"
    assert p.photo_path(p.expressions[0].photos[0]).is_absolute()
    assert p.default_result_paths("big smile") == ("results/big_smile.obj", "results/big_smile.ply")

    with pytest.raises(ProjectError) as ei:
        p.expression("angry")
    assert "'angry'" in str(ei.value) and "'neutral', 'smile'" in str(ei.value)
    with pytest.raises(ProjectError, match="did you mean 'nose_tip'"):
        p.observations("neutral", ["nose_tp"])


def test_observations(saved):
    p = load_project(saved[0])
    obs = p.observations("neutral", ["jaw_00", "nose_tip", "eye_l"])
    assert obs.shape == (2, 3, 2)
    assert np.isnan(obs[0, 0]).all()  # jaw_00 is clicked in 'front' but hidden there
    assert np.isnan(obs[1, 0]).all()  # not clicked in 'left'
    np.testing.assert_array_equal(obs[0, 1], [31.5, 20.25])
    np.testing.assert_array_equal(obs[1, 2], [-3.5, 13.0])
    assert p.observations("smile").shape == (1, 3, 2)  # default: all features, definition order


def test_check_vertices(saved):
    p = load_project(saved[0])
    p.check_vertices(31)
    with pytest.raises(ProjectError) as ei:
        p.check_vertices(30)
    assert "features[2].vertex" in str(ei.value) and "jaw_00" in str(ei.value)
    assert "30 vertices" in str(ei.value)
    with pytest.raises(ProjectError, match=r"curves\[1\].vertices\[1\]"):
        p.check_vertices(5)


# ---------------------------------------------------------------------------------------
# photos on disk
# ---------------------------------------------------------------------------------------
def test_check_photos_ok(saved):
    """Every photo present, readable and of its stored size: no problem raised — and ``read_size``
    does decode each photo (a check that skipped the read would pass a truncated file)."""
    p = load_project(saved[0])
    assert p.check_photos() is None
    decoded = []
    assert p.check_photos(read_size=lambda path: decoded.append(path) or photo_size(path)) is None
    assert sorted(decoded) == sorted(p.photo_path(ph) for e in p.expressions for ph in e.photos)


def test_check_photos_read_finds_a_truncated_photo(tmp_path, saved):
    p = load_project(saved[0])
    photo = tmp_path / "photos" / "smile_front.png"
    photo.write_bytes(photo.read_bytes()[:60])  # the PNG header and a part of its first chunk
    p.check_photos()  # header check only: passes
    with pytest.raises(ProjectError, match=r"photo 'front': photos/smile_front.png could not be decoded"):
        p.check_photos(read_size=photo_size)


def test_check_photos_names_each_missing_or_unreadable_photo(tmp_path, saved):
    p = load_project(saved[0])
    (tmp_path / "photos" / "neutral_left.png").unlink()
    (tmp_path / "photos" / "smile_front.png").write_bytes(b"this is not a PNG")
    with pytest.raises(ProjectError) as ei:
        p.check_photos()
    msg = str(ei.value)
    assert msg.startswith("james.facestudio.json: 2 problems")
    assert "expression 'neutral', photo 'left': photos/neutral_left.png does not exist" in msg
    assert "expression 'smile', photo 'front': photos/smile_front.png is not an image" in msg
    assert "neutral_front" not in msg


def test_check_photos_read_compares_size(tmp_path, saved):
    p = load_project(saved[0])
    cv2.imwrite(str(tmp_path / "photos" / "neutral_left.png"), np.zeros((H, W + 1), np.uint8))
    p.check_photos()  # header check only: passes
    with pytest.raises(ProjectError, match=r"photo 'left'.*65x48 but the project says 64x48"):
        p.check_photos(read_size=photo_size)


# ---------------------------------------------------------------------------------------
# format version 2: photo camera_group (photos sharing one camera and lens)
# ---------------------------------------------------------------------------------------
def test_camera_groups_index_array():
    """One index per camera, in photo order: a shared group one index, an ungrouped photo its own,
    numbered by first appearance."""

    def expression(groups):
        return Expression("e", [Photo(f"p{i}", f"p{i}.png", W, H, camera_group=g) for i, g in enumerate(groups)])

    assert expression(["a", None, "a", "b", None]).camera_groups() == [0, 1, 0, 2, 3]
    assert expression([None, None]).camera_groups() == [0, 1]
    assert expression(["x", "x", "x"]).camera_groups() == [0, 0, 0]
    assert expression(["b", "a", "b", "a"]).camera_groups() == [0, 1, 0, 1]
    assert expression([]).camera_groups() == []
    p = Project("p", expressions=[expression(["v", "v", None]), Expression("other")])
    assert p.camera_groups("e") == [0, 0, 1] and p.camera_groups("other") == []
    with pytest.raises(ProjectError, match="grin"):
        p.camera_groups("grin")


# ---------------------------------------------------------------------------------------
# format version 3: where a click came from
# ---------------------------------------------------------------------------------------
def test_set_click_by_hand_makes_an_automatic_click_the_users():
    ph = Photo("front", "front.png", W, H)
    ph.set_click("nose_tip", [30, 20], source="auto", confidence=0.9)
    assert ph.click_source("nose_tip") == "auto" and ph.confidence == {"nose_tip": 0.9}
    assert ph.click_meta() == {"nose_tip": {"source": "auto", "confidence": 0.9}}
    ph.set_click("nose_tip", [31, 21])  # the artist drags it
    assert ph.click_source("nose_tip") == "user"
    assert ph.sources == {} and ph.confidence == {} and ph.auto_clicks() == []
    np.testing.assert_array_equal(ph.points["nose_tip"], [31.0, 21.0])
    ph.set_click("chin", [30, 40], source="auto", confidence=0.2)
    np.testing.assert_array_equal(ph.remove_click("chin"), [30.0, 40.0])
    assert "chin" not in ph.sources and "chin" not in ph.confidence and ph.remove_click("chin") is None


@pytest.mark.parametrize(
    "uv, source, confidence, match",
    [
        ([np.nan, 1.0], "user", None, "not finite"),
        ([1.0, 1.0], "detector", None, "source is one of"),
        ([1.0, 1.0], "auto", 1.2, r"confidence lies in \[0, 1\]"),
    ],
)
def test_set_click_refuses_bad_input(uv, source, confidence, match):
    ph = Photo("front", "front.png", W, H)
    with pytest.raises(ValueError, match=match):
        ph.set_click("nose_tip", uv, source=source, confidence=confidence)
    assert ph.points == {}


def test_photos_differing_only_in_click_sources_are_not_equal():
    a = Photo("front", "front.png", W, H, points={"nose_tip": [1, 2]})
    b = Photo("front", "front.png", W, H, points={"nose_tip": [1, 2]}, sources={"nose_tip": "auto"})
    assert a != b
    assert a == Photo("front", "front.png", W, H, points={"nose_tip": [1, 2]}, sources={"nose_tip": "user"})
