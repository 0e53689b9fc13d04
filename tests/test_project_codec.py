"""Tests of photomodel.project.codec: what a project looks like on disk — rounding, plain JSON reports,
relative paths (also after "save as"), optional keys omitted when unset, defaults when absent."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from project_samples import H, W, load_dict, sample_project, save_sample, textured_project

from photomodel.camera import orbit_camera
from photomodel.project import load_project, save_project


@pytest.fixture
def saved(tmp_path):
    """(path, dict) of a valid saved project with its photos on disk."""
    return save_sample(tmp_path)


def test_rounding_to_documented_precision(tmp_path):
    p = sample_project(tmp_path)
    p.expressions[0].result.cameras["left"] = ref = orbit_camera(90.0, W, H, focal_mm=35.0)
    p.expressions[0].photos[0].points["nose_tip"] = np.array([31.123456789, 20.987654321])
    p.expressions[0].result.points_3d["nose_tip"] = np.array([1.23456789, 2.0, 3.0])
    save_project(p)
    q = load_project(p.path)
    np.testing.assert_array_equal(q.expressions[0].photos[0].points["nose_tip"], [31.123, 20.988])
    np.testing.assert_array_equal(q.expressions[0].result.points_3d["nose_tip"], [1.2346, 2.0, 3.0])
    cam = q.expressions[0].result.cameras["left"]
    np.testing.assert_array_equal(cam.R, ref.R)  # full precision: stays orthonormal
    assert abs(cam.f - ref.f) <= 5e-7  # stored to 1e-6 px


def test_report_numpy_and_nan_become_plain_json(tmp_path):
    p = sample_project(tmp_path)
    p.expressions[0].result.report = {
        "rms": np.float32(0.5),
        "per_point": np.array([1.0, np.nan]),
        "n": np.int64(3),
        "ok": np.bool_(True),
    }
    save_project(p)
    r = load_project(p.path).expressions[0].result.report
    assert r == {"rms": 0.5, "per_point": [1.0, None], "n": 3, "ok": True}


def test_optional_fields_default(tmp_path, saved):
    _, d = saved
    del d["curves"]
    for e in d["expressions"]:
        e.pop("result", None)
        for ph in e["photos"]:
            for k in ("focal_mm_guess", "points", "hidden", "curves"):
                ph.pop(k, None)
    p = load_dict(tmp_path, d)
    ph = p.expressions[0].photos[0]
    assert p.curves == [] and ph.points == {} and ph.hidden == set() and ph.curves == {}
    assert ph.focal_mm_guess is None and p.expressions[0].result is None


# ---------------------------------------------------------------------------------------
# paths: relative to the project file, also after "save as"
# ---------------------------------------------------------------------------------------
def test_save_writes_paths_relative_to_the_project(tmp_path):
    p = sample_project(tmp_path)
    p.expressions[0].photos[0].path = str(tmp_path / "photos" / "x.png")  # e.g. from a file dialog
    save_project(p)
    assert load_project(p.path).expressions[0].photos[0].path == "photos/x.png"


def test_save_as_elsewhere_keeps_finding_the_photos(tmp_path, saved):
    path, _ = saved
    p = load_project(path)
    p.generic_mesh = "meshes/custom.ply"
    other = tmp_path / "elsewhere" / "copy.facestudio.json"
    save_project(p, other)
    assert p.path == other
    q = load_project(other)
    q.check_photos()  # the photos did not move; their paths now say where they are
    front = q.expressions[0].photos[0]
    assert Path(front.path).is_absolute() and q.photo_path(front) == tmp_path / "photos" / "neutral_front.png"
    assert q.generic_mesh == (tmp_path / "meshes" / "custom.ply").as_posix()
    # saving back into the original folder makes them relative again
    save_project(q, tmp_path / "back.facestudio.json")
    assert load_project(tmp_path / "back.facestudio.json").expressions[0].photos[0].path == "photos/neutral_front.png"


# ---------------------------------------------------------------------------------------
# optional keys: result.texture, cameras_from, camera_group (absent from files without them)
# ---------------------------------------------------------------------------------------
def test_texture_round_trip_and_absent_when_none(tmp_path, saved):
    path, d = saved
    assert "texture" not in d["expressions"][0]["result"]  # files without a texture are unchanged
    p = textured_project(tmp_path)
    save_project(p)
    d = json.loads(p.path.read_text())
    t = d["expressions"][0]["result"]["texture"]
    assert list(t["weight_maps"]) == ["front", "left"]  # photo order, like the cameras
    assert t["exports"]["glb"] == "results/neutral.glb"
    q = load_project(p.path)
    assert q == p and q.expression("neutral").result.texture.size == 512
    # save as elsewhere: the texture paths still reach the same files
    save_project(q, tmp_path / "sub" / "copy.facestudio.json")
    r = load_project(tmp_path / "sub" / "copy.facestudio.json")
    moved = r.expression("neutral").result.texture
    assert r.resolve(moved.image) == tmp_path / "results" / "neutral_texture.png"
    assert r.resolve(moved.weight_maps["left"]) == tmp_path / "results" / "neutral_weights_left.png"
    assert r.resolve(moved.exports["glb"]) == tmp_path / "results" / "neutral.glb"


def test_cameras_from_round_trip_and_absent_when_none(tmp_path, saved):
    _, d = saved
    assert all("cameras_from" not in e for e in d["expressions"])  # files without it are unchanged
    p = sample_project(tmp_path)
    p.expression("smile").cameras_from = "neutral"
    save_project(p)
    d = json.loads(p.path.read_text())
    assert d["expressions"][1]["cameras_from"] == "neutral"
    assert list(d["expressions"][1])[:2] == ["name", "cameras_from"]  # readable: next to the name
    q = load_project(p.path)
    assert q == p and q.expression("smile").cameras_from == "neutral"
    assert q.expression("neutral").cameras_from is None
    d["expressions"][1]["cameras_from"] = None  # an explicit null is the default
    assert load_dict(tmp_path, d).expression("smile").cameras_from is None


def test_camera_group_round_trip_and_absent_when_none(tmp_path, saved):
    _, d = saved
    assert all("camera_group" not in ph for e in d["expressions"] for ph in e["photos"])
    p = sample_project(tmp_path)
    p.expression("neutral").photos[0].camera_group = "video"
    p.expression("neutral").photos[1].camera_group = "video"
    p.expression("smile").photos[0].camera_group = "nikon 85 mm"
    save_project(p)
    d = json.loads(p.path.read_text())
    front = d["expressions"][0]["photos"][0]
    assert front["camera_group"] == "video"
    assert list(front)[5:7] == ["focal_mm_guess", "camera_group"]  # next to the lens guess
    q = load_project(p.path)
    assert q == p and q.expression("smile").photos[0].camera_group == "nikon 85 mm"
    q.expression("neutral").photos[1].camera_group = "other"
    assert q != p  # the group takes part in equality
    front["camera_group"] = None  # an explicit null is the default
    assert load_dict(tmp_path, d).expression("neutral").photos[0].camera_group is None
