"""Tests of photomodel.project.validate: format and version, the shipped JSON Schema, cross-references;
each message names the file and the JSON path of the field; an invalid project is never written."""

from __future__ import annotations

import copy
import json
from importlib import resources
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from project_samples import (
    H,
    W,
    load_dict,
    load_text,
    photo_dict,
    sample_project,
    save_sample,
    temp_files,
    textured_project,
)

from photomodel.camera import PRESET_AZIMUTH_DEG, orbit_camera
from photomodel.errors import ProjectError
from photomodel.project import FORMAT_VERSION, load_person, load_project, project_schema, save_project
from photomodel.project.codec import project_to_dict
from photomodel.project.validate import _validator


@pytest.fixture
def saved(tmp_path):
    """(path, dict) of a valid saved project with its photos on disk."""
    return save_sample(tmp_path)


CASES = [
    # (id, mutation of the valid dict, substrings expected in the message)
    (
        "short point",
        lambda d: photo_dict(d)["points"].__setitem__("nose_tip", [12.0]),
        [
            "james.facestudio.json: expressions[0].photos[0].points.nose_tip: "
            "expected [u, v] of two finite numbers, got [12.0]"
        ],
    ),
    (
        "string coordinate",
        lambda d: photo_dict(d)["points"].__setitem__("eye_l", [1, "2"]),
        ["expressions[0].photos[0].points.eye_l: expected [u, v]"],
    ),
    (
        "three coordinates",
        lambda d: photo_dict(d, 0, 1)["points"].__setitem__("eye_l", [1, 2, 3]),
        ["expressions[0].photos[1].points.eye_l: expected [u, v]"],
    ),
    (
        "missing width",
        lambda d: photo_dict(d).pop("width"),
        ["expressions[0].photos[0]: 'width' is a required property"],
    ),
    (
        "misspelt field",
        lambda d: photo_dict(d).__setitem__("pionts", {}),
        ["expressions[0].photos[0]: ", "'pionts' was unexpected"],
    ),
    (
        "width not integer",
        lambda d: photo_dict(d).__setitem__("width", 64.5),
        ["expressions[0].photos[0].width: expected the image width in pixels"],
    ),
    (
        "negative feature vertex",
        lambda d: d["features"][1].__setitem__("vertex", -3),
        ["features[1].vertex: expected a generic-mesh vertex index (an integer >= 0, below 2^31), got -3"],
    ),
    (
        "negative curve vertex",
        lambda d: d["curves"][0]["vertices"].__setitem__(2, -1),
        ["curves[0].vertices[2]: expected a generic-mesh vertex index"],
    ),
    (
        "pose not bool",
        lambda d: d["features"][0].__setitem__("pose", "yes"),
        ["features[0].pose: expected true or false"],
    ),
    (
        "one-point curve",
        lambda d: photo_dict(d)["curves"].__setitem__("brow_r", [[1, 2]]),
        ["expressions[0].photos[0].curves.brow_r: expected a polyline of at least two [u, v] points"],
    ),
    (
        "bad result",
        lambda d: d["expressions"][0].__setitem__("result", 3),
        ["expressions[0].result: expected null or a result object, got 3"],
    ),
    (
        "short rotation row",
        lambda d: d["expressions"][0]["result"]["cameras"]["front"]["rotation"][1].pop(),
        ["expressions[0].result.cameras.front.rotation: expected a 3x3 rotation matrix"],
    ),
    (
        "negative focal guess",
        lambda d: photo_dict(d).__setitem__("focal_mm_guess", -50),
        ["expressions[0].photos[0].focal_mm_guess: expected null or a positive focal length"],
    ),
    (
        "duplicate feature",
        lambda d: d["features"].append({"name": "eye_l", "vertex": 7, "pose": False}),
        ["features[3].name: feature name 'eye_l' is used twice (also at features[1])"],
    ),
    (
        "duplicate curve",
        lambda d: d["curves"].append({"name": "brow_r", "vertices": [7, 8]}),
        ["curves[2].name: curve name 'brow_r' is used twice"],
    ),
    (
        "duplicate expression",
        lambda d: d["expressions"][1].__setitem__("name", "neutral"),
        ["expressions[1].name: expression name 'neutral' is used twice"],
    ),
    (
        "duplicate photo id",
        lambda d: photo_dict(d, 0, 1).__setitem__("id", "front"),
        ["expressions[0].photos[1].id: photo id 'front' is used twice (also at expressions[0].photos[0])"],
    ),
    (
        "undefined feature",
        lambda d: photo_dict(d)["points"].__setitem__("nose_tp", [1, 2]),
        ["expressions[0].photos[0].points.nose_tp: no feature named 'nose_tp' is defined", "did you mean 'nose_tip'"],
    ),
    (
        "undefined hidden",
        lambda d: photo_dict(d)["hidden"].append("ear_r"),
        ["expressions[0].photos[0].hidden[1]: no feature named 'ear_r'"],
    ),
    (
        "undefined curve",
        lambda d: photo_dict(d)["curves"].__setitem__("brow_l", [[1, 2], [3, 4]]),
        ["expressions[0].photos[0].curves.brow_l: no curve named 'brow_l' is defined", "did you mean 'brow_r'"],
    ),
    (
        "unknown preset",
        lambda d: photo_dict(d, 1, 0).__setitem__("preset", "frnt"),
        ["expressions[1].photos[0].preset: unknown camera preset 'frnt'; choose one of front"],
    ),
    (
        "point far outside",
        lambda d: photo_dict(d)["points"].__setitem__("eye_l", [1000.0, 12.0]),
        ["expressions[0].photos[0].points.eye_l: [1000, 12] lies far outside the 64x48 photo"],
    ),
    (
        "point far above",
        lambda d: photo_dict(d)["points"].__setitem__("eye_l", [0.5, -0.7 * H]),
        ["expressions[0].photos[0].points.eye_l: ", "lies far outside"],
    ),
    (
        "curve point far outside",
        lambda d: photo_dict(d)["curves"]["brow_r"].__setitem__(1, [10, 200]),
        ["expressions[0].photos[0].curves.brow_r[1]: [10, 200] lies far outside"],
    ),
    (
        "camera of unknown photo",
        lambda d: d["expressions"][0]["result"]["cameras"].__setitem__(
            "right", copy.deepcopy(d["expressions"][0]["result"]["cameras"]["front"])
        ),
        ["expressions[0].result.cameras.right: camera for photo 'right', which is not a photo"],
    ),
    (
        "camera size mismatch",
        lambda d: d["expressions"][0]["result"]["cameras"]["left"].__setitem__("width", 640),
        ["expressions[0].result.cameras.left: camera image size 640x48 differs"],
    ),
    (
        "not a rotation",
        lambda d: d["expressions"][0]["result"]["cameras"]["front"]["rotation"][0].__setitem__(0, 0.9),
        ["expressions[0].result.cameras.front.rotation: not a rotation matrix"],
    ),
    (
        "3d point of unknown feature",
        lambda d: d["expressions"][0]["result"]["points_3d"].__setitem__("chin", [0, 0, 0]),
        ["expressions[0].result.points_3d.chin: no feature named 'chin'"],
    ),
    (
        "key with spaces",
        lambda d: photo_dict(d)["points"].__setitem__("left eye", [1, 2]),
        ['expressions[0].photos[0].points["left eye"]: no feature named'],
    ),
    ("wrong format", lambda d: d.__setitem__("format", "blender"), ["not a Face Studio project file", '"blender"']),
    (
        "newer version",
        lambda d: d.__setitem__("version", 7),
        [
            "james.facestudio.json: written by a newer Face Studio (project format version 7; "
            "this version reads up to 6)"
        ],
    ),
    ("version zero", lambda d: d.__setitem__("version", 0), ["unknown project format version 0"]),
    ("version string", lambda d: d.__setitem__("version", "1"), ["version: expected an integer", '"1"']),
]


@pytest.mark.parametrize("mutate, expected", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_validation_error_names_the_field(tmp_path, saved, mutate, expected):
    _, d = saved
    mutate(d)
    with pytest.raises(ProjectError) as ei:
        load_dict(tmp_path, d)
    msg = str(ei.value)
    assert msg.startswith("james.facestudio.json: ")
    for s in expected:
        assert s in msg, f"{s!r} not in {msg!r}"


def test_several_problems_are_listed(tmp_path, saved):
    _, d = saved
    photo_dict(d)["preset"] = "frnt"
    photo_dict(d, 1, 0)["points"]["nose"] = [1, 2]
    with pytest.raises(ProjectError) as ei:
        load_dict(tmp_path, d)
    assert str(ei.value).startswith("james.facestudio.json: 2 problems:")
    assert [p for p, _ in ei.value.problems] == [
        "expressions[0].photos[0].preset",
        "expressions[1].photos[0].points.nose",
    ]


def test_slightly_outside_point_is_accepted(tmp_path, saved):
    _, d = saved
    # 0.4 of the width beyond the right border, within the 0.5 margin
    photo_dict(d)["points"]["eye_l"] = [W - 0.5 + 0.4 * W, -0.5 - 0.4 * H]
    p = load_dict(tmp_path, d)
    assert p.expressions[0].photos[0].points["eye_l"][0] == pytest.approx(W - 0.5 + 0.4 * W)


def test_schema_is_shipped_and_valid():

    assert resources.files("photomodel.project").joinpath("schema.json").is_file()
    jsonschema.Draft202012Validator.check_schema(project_schema())


def test_every_preset_is_accepted(tmp_path, saved):
    _, d = saved
    template = photo_dict(d, 1, 0)
    d["expressions"][1]["photos"] = [dict(copy.deepcopy(template), id=k, preset=k) for k in PRESET_AZIMUTH_DEG]
    assert len(load_dict(tmp_path, d).expressions[1].photos) == len(PRESET_AZIMUTH_DEG)


def test_documented_example_loads(tmp_path):
    """The example in docs/project-format.md is a valid project (keeps the docs honest)."""
    doc = (Path(__file__).resolve().parents[1] / "docs" / "project-format.md").read_text()
    example = doc.split("```json\n", 1)[1].split("```", 1)[0]
    p = load_text(tmp_path, example)
    assert p.feature_names(pose_only=True) == ["nose_tip", "eye_l_outer"]
    cam = p.expression("neutral").result.cameras["left"]
    ref = orbit_camera(90.0, 1000, 1000)  # the documented 'left' camera is the preset's camera
    np.testing.assert_allclose(cam.R, ref.R, atol=1e-15)
    np.testing.assert_allclose(cam.t, ref.t)
    assert abs(cam.f - ref.f) < 1e-6


LEAF_VALUES = {
    "pixel": [[12.0], [1, "2"], [1, 2, 3], [True, 1], "x", [[1, 2]], {}],
    "polyline": [[[1, 2]], [[1, 2], [3]], "x", [[1, 2], [True, 3]], [], [[1, 2], 5]],
    "vec3": [[1, 2], [1, 2, "3"], [1, 2, 3, 4], None, [False, 0, 0]],
}


@pytest.mark.parametrize("kind", sorted(LEAF_VALUES))
def test_fast_leaf_checks_agree_with_the_shipped_schema(saved, kind):
    """The loader checks coordinate maps in Python for speed (validate._validator); the shipped
    schema, read by a standard validator, must accept and reject exactly the same values."""

    standard = jsonschema.Draft202012Validator(project_schema())
    _, d = saved
    assert standard.is_valid(d) and _validator().is_valid(d)
    good = {"pixel": [1, 2.5], "polyline": [[1, 2], [3.5, 4]], "vec3": [0, -1.5, 2]}[kind]
    for value in [good, *LEAF_VALUES[kind]]:
        e = copy.deepcopy(d)
        if kind == "pixel":
            photo_dict(e)["points"]["eye_l"] = value
        elif kind == "polyline":
            photo_dict(e)["curves"]["brow_r"] = value
        else:
            e["expressions"][0]["result"]["points_3d"]["eye_l"] = value
        assert standard.is_valid(e) == _validator().is_valid(e) == (value is good), value


# ---------------------------------------------------------------------------------------
# an invalid project is not written
# ---------------------------------------------------------------------------------------
def test_invalid_project_is_not_written(tmp_path):
    p = sample_project(tmp_path)
    p.expressions[0].photos[0].points["nosetip"] = np.array([1.0, 2.0])
    with pytest.raises(ProjectError, match=r"points\.nosetip: no feature named 'nosetip'"):
        save_project(p)
    assert not p.path.exists() and temp_files(tmp_path) == []

    p = sample_project(tmp_path)
    p.expressions[0].photos[0].points["nose_tip"] = np.array([np.nan, 2.0])
    with pytest.raises(ProjectError, match=r"points\.nose_tip\[0\]: nan is not a finite number"):
        save_project(p)
    assert not p.path.exists()


# ---------------------------------------------------------------------------------------
# result.texture
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "mutate, expected",
    [
        (
            lambda t: t["weight_maps"].__setitem__("back", "w.png"),
            "expressions[0].result.texture.weight_maps.back: weight map for photo 'back', which is not a photo",
        ),
        (lambda t: t["exports"].__setitem__("fbx", "a.fbx"), "expressions[0].result.texture.exports"),
        (lambda t: t.pop("image"), "'image' is a required property"),
        (lambda t: t.__setitem__("size", 0), "texture.size: expected the texture size in texels"),
    ],
)
def test_texture_validation_names_the_field(tmp_path, mutate, expected):
    p = textured_project(tmp_path)
    d = project_to_dict(p, p.path)
    mutate(d["expressions"][0]["result"]["texture"])
    with pytest.raises(ProjectError) as exc:
        load_dict(tmp_path, d)
    assert expected in str(exc.value)


# ---------------------------------------------------------------------------------------
# cameras_from: an expression photographed by another expression's cameras
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "mutate, expected",
    [
        (
            lambda d: d["expressions"][1].__setitem__("cameras_from", "neutal"),
            [
                "expressions[1].cameras_from: no expression named 'neutal' to take the cameras from",
                "did you mean 'neutral'",
            ],
        ),
        (
            lambda d: d["expressions"][1].__setitem__("cameras_from", "smile"),
            ["expressions[1].cameras_from: expression 'smile' cannot take its cameras from itself"],
        ),
        (
            lambda d: (
                d["expressions"][0].__setitem__("cameras_from", "smile"),
                d["expressions"][1].__setitem__("cameras_from", "neutral"),
            ),
            [
                "expressions[0].cameras_from: cameras_from goes round in a cycle (neutral → smile → neutral)",
                "expressions[1].cameras_from: cameras_from goes round in a cycle (smile → neutral → smile)",
            ],
        ),
        (
            lambda d: d["expressions"][1].__setitem__("cameras_from", 3),
            ["expressions[1].cameras_from: expected null or the name of another expression"],
        ),
        (
            lambda d: d["expressions"][1].__setitem__("cameras_from", ""),
            ["expressions[1].cameras_from: expected a non-empty name"],
        ),
    ],
)
def test_malformed_cameras_from_names_the_field(tmp_path, saved, mutate, expected):
    _, d = saved
    mutate(d)
    with pytest.raises(ProjectError) as ei:
        load_dict(tmp_path, d)
    for s in expected:
        assert s in str(ei.value), f"{s!r} not in {str(ei.value)!r}"


def test_cameras_from_chain_without_cycle_is_valid(tmp_path, saved):
    _, d = saved
    d["expressions"].append({"name": "frown", "cameras_from": "smile", "photos": []})
    d["expressions"][1]["cameras_from"] = "neutral"
    p = load_dict(tmp_path, d)
    assert [e.cameras_from for e in p.expressions] == [None, "neutral", "smile"]


def test_invalid_cameras_from_is_not_saved(tmp_path):
    p = sample_project(tmp_path)
    p.expression("smile").cameras_from = "grin"
    with pytest.raises(ProjectError, match="no expression named 'grin'"):
        save_project(p)
    assert not p.path.exists()


# ---------------------------------------------------------------------------------------
# format version 2: version 1 read, photo camera_group
# ---------------------------------------------------------------------------------------
def test_version_1_file_loads_and_is_saved_as_the_current_version(tmp_path, saved):
    """Version 1 needs no upgrade (it has no camera groups); saving writes the current version."""
    _, d = saved
    d["version"] = 1
    p = load_dict(tmp_path, d)
    assert p == sample_project()
    assert all(ph.camera_group is None for e in p.expressions for ph in e.photos)
    assert p.camera_groups("neutral") == [0, 1]  # each photo a camera of its own
    again = json.loads(save_project(p, tmp_path / "v3.facestudio.json").read_text())
    assert again["version"] == FORMAT_VERSION and again["expressions"] == d["expressions"]
    # the committed sample project is a version-1 file and still loads
    sample = load_project(Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "james.facestudio.json")
    assert sample.camera_groups("neutral") == [0, 1, 2, 3, 4]


@pytest.mark.parametrize(
    "value, expected",
    [
        (3, "expected null or a camera group name (a non-empty string), got 3"),
        ("", 'expected null or a camera group name (a non-empty string), got ""'),
        (["video"], "expected null or a camera group name"),
        (True, "expected null or a camera group name"),
    ],
)
def test_malformed_camera_group_names_the_field(tmp_path, saved, value, expected):
    _, d = saved
    photo_dict(d, 0, 1)["camera_group"] = value
    with pytest.raises(ProjectError) as ei:
        load_dict(tmp_path, d)
    msg = str(ei.value)
    assert msg.startswith("james.facestudio.json: expressions[0].photos[1].camera_group: "), msg
    assert expected in msg, msg


def test_invalid_camera_group_is_not_saved(tmp_path):
    p = sample_project(tmp_path)
    p.expression("neutral").photos[0].camera_group = ""
    with pytest.raises(ProjectError, match=r"photos\[0\]\.camera_group: expected null or a camera group"):
        save_project(p)
    assert not p.path.exists()


# ---------------------------------------------------------------------------------------
# format version 3: click_sources (automatic clicks and their confidence)
# ---------------------------------------------------------------------------------------
def test_version_3_round_trip_of_automatic_clicks(tmp_path):
    p = sample_project(tmp_path)
    front = p.expression("neutral").photo("front")
    front.set_click("eye_l", [41.25, 12.5], source="auto", confidence=0.875)
    front.set_click("jaw_00", [30.0, 46.0], source="auto")  # a detector that gives no score
    path = save_project(p)
    d = json.loads(path.read_text())
    pd = photo_dict(d, 0, 0)
    assert d["version"] == FORMAT_VERSION
    # the clicks stay plain [u, v]; their origin sits beside them, in feature order
    assert pd["points"]["eye_l"] == [41.25, 12.5]
    assert list(pd["click_sources"]) == ["eye_l", "jaw_00"]
    assert pd["click_sources"]["eye_l"] == {"source": "auto", "confidence": 0.875}
    assert pd["click_sources"]["jaw_00"] == {"source": "auto"}
    assert "click_sources" not in photo_dict(d, 0, 1)  # the artist's clicks only: no key
    back = load_project(path)
    assert back == p
    bf = back.expression("neutral").photo("front")
    assert bf.click_source("eye_l") == "auto" and bf.click_source("nose_tip") == "user"
    assert bf.confidence == {"eye_l": 0.875} and bf.auto_clicks() == ["eye_l", "jaw_00"]


# ---------------------------------------------------------------------------------------
# format version 5: curve_sources (curves drawn by the landmark detector)
# ---------------------------------------------------------------------------------------
def test_version_5_round_trip_of_automatic_curves(tmp_path):
    p = sample_project(tmp_path)
    front = p.expression("neutral").photo("front")
    front.set_curve("lip_top", [[10.0, 40.0], [20.0, 36.5], [30.0, 40.0]], source="auto")
    path = save_project(p)
    d = json.loads(path.read_text())
    pd = photo_dict(d, 0, 0)
    assert d["version"] == FORMAT_VERSION
    assert pd["curves"]["lip_top"] == [[10.0, 40.0], [20.0, 36.5], [30.0, 40.0]]  # still a plain polyline
    assert pd["curve_sources"] == {"lip_top": "auto"}
    assert "curve_sources" not in photo_dict(d, 0, 1)  # no automatic curve: no key
    back = load_project(path)
    assert back == p
    bf = back.expression("neutral").photo("front")
    assert bf.curve_source("lip_top") == "auto" and bf.auto_curves() == ["lip_top"]
    # redrawn by the artist: theirs, and the key goes
    bf.set_curve("lip_top", [[10.0, 41.0], [30.0, 41.0]])
    assert bf.curve_source("lip_top") == "user" and bf.auto_curves() == []
    assert "curve_sources" not in photo_dict(json.loads(save_project(back).read_text()), 0, 0)
    with pytest.raises(ValueError, match="at least 2 finite points"):
        bf.set_curve("lip_top", [[1.0, 2.0]], source="auto")


def test_a_curve_source_without_its_curve_is_named(tmp_path, saved):
    path, d = saved
    photo_dict(d)["curve_sources"] = {"brow_l": "auto"}
    path.write_text(json.dumps(d))
    with pytest.raises(ProjectError, match=r"curve_sources.brow_l: .brow_l. is not drawn in this photo's curves"):
        load_project(path)


def test_version_4_file_loads_and_its_curves_are_the_users(tmp_path, saved):
    path, d = saved
    d["version"] = 4
    path.write_text(json.dumps(d))
    p = load_project(path)
    assert all(not ph.auto_curves() for e in p.expressions for ph in e.photos)
    assert json.loads(save_project(p).read_text())["version"] == FORMAT_VERSION


def test_version_2_file_loads_unchanged_and_its_clicks_are_the_users(tmp_path, saved):
    _, d = saved
    d["version"] = 2
    p = load_dict(tmp_path, d)
    assert p == sample_project()
    assert all(ph.sources == {} and ph.confidence == {} for e in p.expressions for ph in e.photos)
    assert p.expression("neutral").photo("front").click_source("nose_tip") == "user"
    again = json.loads(save_project(p, tmp_path / "v3.facestudio.json").read_text())
    assert again["version"] == FORMAT_VERSION and again["expressions"] == d["expressions"]


@pytest.mark.parametrize(
    "value, expected",
    [
        ({"eye_l": {"source": "robot"}}, 'click_sources.eye_l.source: expected "auto"'),
        ({"eye_l": {"source": "auto", "confidence": 1.5}}, "click_sources.eye_l.confidence: expected the detector's"),
        ({"eye_l": {"confidence": 0.5}}, "click_sources.eye_l"),
        ({"eye_l": "auto"}, "click_sources.eye_l"),
        ({"jaw_00": {"source": "auto"}}, "click_sources.jaw_00: 'jaw_00' has no click in this photo's points"),
    ],
)
def test_malformed_click_sources_name_the_field(tmp_path, saved, value, expected):
    _, d = saved
    photo_dict(d, 0, 1)["click_sources"] = value  # photo 'left' clicks nose_tip and eye_l
    with pytest.raises(ProjectError) as ei:
        load_dict(tmp_path, d)
    msg = str(ei.value)
    assert msg.startswith("james.facestudio.json: expressions[0].photos[1].click_sources"), msg
    assert expected in msg, msg


def test_a_deleted_click_leaves_no_source_behind(tmp_path):
    p = sample_project(tmp_path)
    front = p.expression("neutral").photo("front")
    front.set_click("eye_l", [41.0, 12.0], source="auto", confidence=0.5)
    front.points.pop("eye_l")  # deleted the old way, without remove_click
    d = json.loads(save_project(p).read_text())
    assert "click_sources" not in photo_dict(d, 0, 0)
    assert load_project(p.path) == p


# ---------------------------------------------------------------------------------------
# format version 6: people (other people's projects referred to), rig source "multilinear"
# ---------------------------------------------------------------------------------------
def test_version_5_file_loads_and_refers_to_nobody(tmp_path, saved):
    path, d = saved
    d["version"] = 5
    path.write_text(json.dumps(d))
    p = load_project(path)
    assert p.people == [] and p == sample_project()
    again = json.loads(save_project(p).read_text())
    assert again["version"] == 6 and "people" not in again  # nobody referred to: no key


def test_version_6_round_trip_keeps_the_people_relative_to_the_project(tmp_path):
    for sub in ("bob", "alice", "elsewhere/deep"):
        (tmp_path / sub).mkdir(parents=True)
    b = sample_project(tmp_path / "bob")
    alice = save_project(sample_project(tmp_path / "alice"), tmp_path / "alice" / "alice.facestudio.json")
    assert b.add_person(alice) == "../alice/alice.facestudio.json"
    assert b.add_person(tmp_path / "bob" / ".." / "alice" / "alice.facestudio.json") is None  # already there
    assert b.add_person(b.path) is None  # not oneself
    path = save_project(b)
    d = json.loads(path.read_text())
    assert d["version"] == 6 and d["people"] == ["../alice/alice.facestudio.json"]
    back = load_project(path)
    assert back.people == ["../alice/alice.facestudio.json"] and back == b
    assert back.person_path(back.people[0]) == alice
    assert load_person(back, back.people[0]).name == sample_project().name
    back.check_people()  # all there: no error
    # saved elsewhere ("save as"): the entry still reaches alice
    moved = save_project(back, tmp_path / "elsewhere" / "deep" / "bob.facestudio.json")
    assert json.loads(moved.read_text())["people"] == ["../../alice/alice.facestudio.json"]


def test_a_missing_person_is_named_with_its_path_and_nothing_is_lost(tmp_path):
    (tmp_path / "bob").mkdir()
    b = sample_project(tmp_path / "bob")
    b.add_person(tmp_path / "carol" / "carol.facestudio.json")  # never written
    path = save_project(b)
    back = load_project(path)  # the project itself opens
    with pytest.raises(ProjectError) as ei:
        load_person(back, "../carol/carol.facestudio.json")
    msg = str(ei.value)
    assert "people[0]: the referenced project ../carol/carol.facestudio.json does not exist" in msg, msg
    assert str(tmp_path / "carol" / "carol.facestudio.json") in msg, msg
    with pytest.raises(ProjectError, match=r"people\[0\]: the referenced project ../carol/carol.facestudio.json"):
        back.check_people()
    assert json.loads(save_project(back).read_text())["people"] == ["../carol/carol.facestudio.json"]


@pytest.mark.parametrize(
    "value, expected",
    [
        (["a.json"], "people[0]: expected the path of a project file (*.facestudio.json)"),
        ([""], "people[0]: expected a file path relative to the project folder"),
        (["a.facestudio.json", "a.facestudio.json"], "people: expected a list of distinct paths"),
        ("a.facestudio.json", "people: expected a list of distinct paths"),
    ],
)
def test_malformed_people_names_the_field(tmp_path, saved, value, expected):
    _, d = saved
    d["people"] = value
    with pytest.raises(ProjectError) as ei:
        load_dict(tmp_path, d)
    assert expected in str(ei.value), str(ei.value)
