"""Tests of photomodel.project.format: the project format (version 2, reading 1), its validation and atomic saving."""

from __future__ import annotations

import copy
import json
import os
from importlib import resources
from pathlib import Path

import cv2
import numpy as np
import pytest

from photomodel.camera import PRESET_AZIMUTH_DEG, orbit_camera
from photomodel.errors import ProjectError
from photomodel.project.format import (
    CurveDef,
    Expression,
    ExpressionResult,
    Feature,
    Photo,
    Project,
    load_project,
    new_project,
    project_schema,
    save_project,
)

W, H = 64, 48  # small photos keep the image-reading tests fast


def _camera(azimuth_deg: float):
    cam = orbit_camera(azimuth_deg, W, H)
    cam.f = 90.0  # orbit_camera's focal (50 mm → 88.88… px) is not exact at the stored 1e-6 px
    return cam


def _project(tmp_path: Path | None = None, *, with_result: bool = True) -> Project:
    """A two-expression project; click values have ≤3 decimals and result values ≤4 so that the
    file's rounding (1e-3 px, 1e-4 mm) is exact and round trips can be compared with ==."""
    features = [Feature("nose_tip", 10, True), Feature("eye_l", 20, True), Feature("jaw_00", 30, False)]
    curves = [CurveDef("brow_r", [1, 2, 3]), CurveDef("lip_top", [4, 5])]
    front = Photo("front", "photos/neutral_front.png", W, H, "front", 50.0,
                  points={"nose_tip": [31.5, 20.25], "eye_l": [40.125, 12.0], "jaw_00": [30.0, 47.0]},
                  hidden={"jaw_00"}, curves={"brow_r": [[10.0, 8.5], [14.0, 7.0], [18.25, 8.0]]})
    left = Photo("left", "photos/neutral_left.png", W, H, "left",
                 points={"nose_tip": [12.0, 22.0], "eye_l": [-3.5, 13.0]})  # slightly outside: allowed
    smile = Photo("front", "photos/smile_front.png", W, H, "three_quarter_right",
                  points={"nose_tip": [30, 21]})
    result = None
    if with_result:
        result = ExpressionResult(
            cameras={"front": _camera(0.0), "left": _camera(90.0)},
            points_3d={"nose_tip": [0.0, -1.5, 102.25], "eye_l": [33.1234, 30.0, 60.0]},
            mesh_obj="results/neutral.obj", mesh_ply="results/neutral.ply",
            report={"rms_px": 0.75, "per_view": {"front": 0.5, "left": 1.0}, "iterations": 12},
        )
    p = Project("james", features=features, curves=curves,
                expressions=[Expression("neutral", [front, left], result), Expression("smile", [smile])])
    if tmp_path is not None:
        p.path = tmp_path / "james.facestudio.json"
    return p


def _write_photos(folder: Path, project: Project) -> None:
    for e in project.expressions:
        for ph in e.photos:
            f = folder / ph.path
            f.parent.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(f), np.full((ph.height, ph.width, 3), 128, np.uint8))


@pytest.fixture
def saved(tmp_path):
    """(path, dict) of a valid saved project with its photos on disk."""
    p = _project()
    path = save_project(p, tmp_path / "james.facestudio.json")
    _write_photos(tmp_path, p)
    return path, json.loads(path.read_text())


def _load_text(tmp_path: Path, text: str) -> Project:
    f = tmp_path / "james.facestudio.json"
    f.write_text(text)
    return load_project(f)


def _load_dict(tmp_path: Path, d: dict) -> Project:
    return _load_text(tmp_path, json.dumps(d, indent=1))


# ---------------------------------------------------------------------------------------
# round trip, determinism, model helpers
# ---------------------------------------------------------------------------------------
def test_round_trip_load_save_load_equal(tmp_path, saved):
    path, _ = saved
    original = _project()
    a = load_project(path)
    assert a == original  # all values are exactly representable at the file's precision
    assert a.path == path.absolute()
    # arrays come back as arrays of the documented shapes and dtypes
    ph = a.expression("neutral").photo("front")
    assert ph.points["nose_tip"].shape == (2,) and ph.points["nose_tip"].dtype == float
    assert ph.curves["brow_r"].shape == (3, 2)
    assert a.curves[0].vertices.dtype == np.int64
    assert ph.hidden == {"jaw_00"}
    cam = a.expression("neutral").result.cameras["left"]
    np.testing.assert_array_equal(cam.R, _camera(90.0).R)  # rotation stored at full precision

    b_path = save_project(a, tmp_path / "again.facestudio.json")
    b = load_project(b_path)
    assert b == a
    # deterministic: same project → byte-identical file
    assert b_path.read_bytes() == path.read_bytes()


def test_rounding_to_documented_precision(tmp_path):
    p = _project(tmp_path)
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


def test_file_is_readable_json(saved):
    path, d = saved
    text = path.read_text()
    assert text.startswith('{\n  "format": "facestudio-project",\n  "version": 2,')
    assert '"nose_tip": [31.5, 20.25]' in text  # a click on one line
    assert '{"name": "nose_tip", "vertex": 10, "pose": true}' in text
    assert "NaN" not in text and "Infinity" not in text


def test_report_numpy_and_nan_become_plain_json(tmp_path):
    p = _project(tmp_path)
    p.expressions[0].result.report = {"rms": np.float32(0.5), "per_point": np.array([1.0, np.nan]),
                                      "n": np.int64(3), "ok": np.bool_(True)}
    save_project(p)
    r = load_project(p.path).expressions[0].result.report
    assert r == {"rms": 0.5, "per_point": [1.0, None], "n": 3, "ok": True}


def test_new_project_save_load(tmp_path):
    p = new_project("anna")
    assert p.expressions == [] and p.generic_mesh == "builtin:template-v1"
    with pytest.raises(ProjectError, match="not been saved yet"):
        save_project(p)
    path = save_project(p, tmp_path)  # a folder → <name>.facestudio.json inside it
    assert path == tmp_path / "anna.facestudio.json"
    assert load_project(path) == p
    with pytest.raises(ProjectError, match="non-empty name"):
        new_project("  ")


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
    p = load_project(saved[0])
    p.check_photos()
    p.check_photos(read=True)


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
        p.check_photos(read=True)


# ---------------------------------------------------------------------------------------
# validation on load: each message names the file and the JSON path of the field
# ---------------------------------------------------------------------------------------
def _photo(d, e=0, i=0):
    return d["expressions"][e]["photos"][i]


CASES = [
    # (id, mutation of the valid dict, substrings expected in the message)
    ("short point", lambda d: _photo(d)["points"].__setitem__("nose_tip", [12.0]),
     ["james.facestudio.json: expressions[0].photos[0].points.nose_tip: "
      "expected [u, v] of two finite numbers, got [12.0]"]),
    ("string coordinate", lambda d: _photo(d)["points"].__setitem__("eye_l", [1, "2"]),
     ["expressions[0].photos[0].points.eye_l: expected [u, v]"]),
    ("three coordinates", lambda d: _photo(d, 0, 1)["points"].__setitem__("eye_l", [1, 2, 3]),
     ["expressions[0].photos[1].points.eye_l: expected [u, v]"]),
    ("missing width", lambda d: _photo(d).pop("width"),
     ["expressions[0].photos[0]: 'width' is a required property"]),
    ("misspelt field", lambda d: _photo(d).__setitem__("pionts", {}),
     ["expressions[0].photos[0]: ", "'pionts' was unexpected"]),
    ("width not integer", lambda d: _photo(d).__setitem__("width", 64.5),
     ["expressions[0].photos[0].width: expected the image width in pixels"]),
    ("negative feature vertex", lambda d: d["features"][1].__setitem__("vertex", -3),
     ["features[1].vertex: expected a generic-mesh vertex index (an integer >= 0), got -3"]),
    ("negative curve vertex", lambda d: d["curves"][0]["vertices"].__setitem__(2, -1),
     ["curves[0].vertices[2]: expected a generic-mesh vertex index"]),
    ("pose not bool", lambda d: d["features"][0].__setitem__("pose", "yes"),
     ["features[0].pose: expected true or false"]),
    ("one-point curve", lambda d: _photo(d)["curves"].__setitem__("brow_r", [[1, 2]]),
     ["expressions[0].photos[0].curves.brow_r: expected a polyline of at least two [u, v] points"]),
    ("bad result", lambda d: d["expressions"][0].__setitem__("result", 3),
     ["expressions[0].result: expected null or a result object, got 3"]),
    ("short rotation row", lambda d: d["expressions"][0]["result"]["cameras"]["front"]["rotation"][1].pop(),
     ["expressions[0].result.cameras.front.rotation: expected a 3x3 rotation matrix"]),
    ("negative focal guess", lambda d: _photo(d).__setitem__("focal_mm_guess", -50),
     ["expressions[0].photos[0].focal_mm_guess: expected null or a positive focal length"]),
    ("duplicate feature", lambda d: d["features"].append({"name": "eye_l", "vertex": 7, "pose": False}),
     ["features[3].name: feature name 'eye_l' is used twice (also at features[1])"]),
    ("duplicate curve", lambda d: d["curves"].append({"name": "brow_r", "vertices": [7, 8]}),
     ["curves[2].name: curve name 'brow_r' is used twice"]),
    ("duplicate expression", lambda d: d["expressions"][1].__setitem__("name", "neutral"),
     ["expressions[1].name: expression name 'neutral' is used twice"]),
    ("duplicate photo id", lambda d: _photo(d, 0, 1).__setitem__("id", "front"),
     ["expressions[0].photos[1].id: photo id 'front' is used twice (also at expressions[0].photos[0])"]),
    ("undefined feature", lambda d: _photo(d)["points"].__setitem__("nose_tp", [1, 2]),
     ["expressions[0].photos[0].points.nose_tp: no feature named 'nose_tp' is defined",
      "did you mean 'nose_tip'"]),
    ("undefined hidden", lambda d: _photo(d)["hidden"].append("ear_r"),
     ["expressions[0].photos[0].hidden[1]: no feature named 'ear_r'"]),
    ("undefined curve", lambda d: _photo(d)["curves"].__setitem__("brow_l", [[1, 2], [3, 4]]),
     ["expressions[0].photos[0].curves.brow_l: no curve named 'brow_l' is defined",
      "did you mean 'brow_r'"]),
    ("unknown preset", lambda d: _photo(d, 1, 0).__setitem__("preset", "frnt"),
     ["expressions[1].photos[0].preset: unknown camera preset 'frnt'; choose one of front"]),
    ("point far outside", lambda d: _photo(d)["points"].__setitem__("eye_l", [1000.0, 12.0]),
     ["expressions[0].photos[0].points.eye_l: [1000, 12] lies far outside the 64x48 photo"]),
    ("point far above", lambda d: _photo(d)["points"].__setitem__("eye_l", [0.5, -0.7 * H]),
     ["expressions[0].photos[0].points.eye_l: ", "lies far outside"]),
    ("curve point far outside", lambda d: _photo(d)["curves"]["brow_r"].__setitem__(1, [10, 200]),
     ["expressions[0].photos[0].curves.brow_r[1]: [10, 200] lies far outside"]),
    ("camera of unknown photo", lambda d: d["expressions"][0]["result"]["cameras"].__setitem__(
        "right", copy.deepcopy(d["expressions"][0]["result"]["cameras"]["front"])),
     ["expressions[0].result.cameras.right: camera for photo 'right', which is not a photo"]),
    ("camera size mismatch", lambda d: d["expressions"][0]["result"]["cameras"]["left"].__setitem__(
        "width", 640), ["expressions[0].result.cameras.left: camera image size 640x48 differs"]),
    ("not a rotation", lambda d: d["expressions"][0]["result"]["cameras"]["front"]["rotation"][0].__setitem__(
        0, 0.9), ["expressions[0].result.cameras.front.rotation: not a rotation matrix"]),
    ("3d point of unknown feature", lambda d: d["expressions"][0]["result"]["points_3d"].__setitem__(
        "chin", [0, 0, 0]), ["expressions[0].result.points_3d.chin: no feature named 'chin'"]),
    ("key with spaces", lambda d: _photo(d)["points"].__setitem__("left eye", [1, 2]),
     ['expressions[0].photos[0].points["left eye"]: no feature named']),
    ("wrong format", lambda d: d.__setitem__("format", "blender"),
     ["not a Face Studio project file", '"blender"']),
    ("newer version", lambda d: d.__setitem__("version", 3),
     ["james.facestudio.json: written by a newer Face Studio (project format version 3; "
      "this version reads up to 2)"]),
    ("version zero", lambda d: d.__setitem__("version", 0), ["unknown project format version 0"]),
    ("version string", lambda d: d.__setitem__("version", "1"), ['version: expected an integer', '"1"']),
]


@pytest.mark.parametrize("mutate, expected", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_validation_error_names_the_field(tmp_path, saved, mutate, expected):
    _, d = saved
    mutate(d)
    with pytest.raises(ProjectError) as ei:
        _load_dict(tmp_path, d)
    msg = str(ei.value)
    assert msg.startswith("james.facestudio.json: ")
    for s in expected:
        assert s in msg, f"{s!r} not in {msg!r}"


def test_several_problems_are_listed(tmp_path, saved):
    _, d = saved
    _photo(d)["preset"] = "frnt"
    _photo(d, 1, 0)["points"]["nose"] = [1, 2]
    with pytest.raises(ProjectError) as ei:
        _load_dict(tmp_path, d)
    assert str(ei.value).startswith("james.facestudio.json: 2 problems:")
    assert [p for p, _ in ei.value.problems] == ["expressions[0].photos[0].preset",
                                                 "expressions[1].photos[0].points.nose"]


def test_slightly_outside_point_is_accepted(tmp_path, saved):
    _, d = saved
    # 0.4 of the width beyond the right border, within the 0.5 margin
    _photo(d)["points"]["eye_l"] = [W - 0.5 + 0.4 * W, -0.5 - 0.4 * H]
    p = _load_dict(tmp_path, d)
    assert p.expressions[0].photos[0].points["eye_l"][0] == pytest.approx(W - 0.5 + 0.4 * W)


def test_optional_fields_default(tmp_path, saved):
    _, d = saved
    del d["curves"]
    for e in d["expressions"]:
        e.pop("result", None)
        for ph in e["photos"]:
            for k in ("focal_mm_guess", "points", "hidden", "curves"):
                ph.pop(k, None)
    p = _load_dict(tmp_path, d)
    ph = p.expressions[0].photos[0]
    assert p.curves == [] and ph.points == {} and ph.hidden == set() and ph.curves == {}
    assert ph.focal_mm_guess is None and p.expressions[0].result is None


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_non_finite_literals_rejected_with_path(tmp_path, saved, literal):
    path, _ = saved
    text = path.read_text().replace('"nose_tip": [31.5, 20.25]', f'"nose_tip": [31.5, {literal}]')
    assert literal in text
    with pytest.raises(ProjectError) as ei:
        _load_text(tmp_path, text)
    assert f"expressions[0].photos[0].points.nose_tip[1]: {literal} is not a finite number" in str(ei.value)


def test_not_json_gives_line_and_column(tmp_path, saved):
    path, _ = saved
    lines = path.read_text().splitlines()
    lines[3] = lines[3].rstrip(",")  # drop the comma after "name": "james"
    with pytest.raises(ProjectError) as ei:
        _load_text(tmp_path, "\n".join(lines))
    expected = "james.facestudio.json: not valid JSON: Expecting ',' delimiter (line 5, column 3)"
    assert expected in str(ei.value)


def test_duplicate_json_key_rejected(tmp_path, saved):
    path, _ = saved
    click = '"nose_tip": [31.5, 20.25]'
    text = path.read_text().replace(click, click + ', "nose_tip": [1, 2]')
    with pytest.raises(ProjectError, match=r"photos\[0\]\.points: key 'nose_tip' appears more than once"):
        _load_text(tmp_path, text)


def test_other_unreadable_files(tmp_path):
    with pytest.raises(ProjectError, match="no such project file"):
        load_project(tmp_path / "nobody.facestudio.json")
    (tmp_path / "a.facestudio.json").write_bytes(b"\xff\xfe{}")
    with pytest.raises(ProjectError, match="not a text"):
        load_project(tmp_path / "a.facestudio.json")
    with pytest.raises(ProjectError, match="not a Face Studio project file"):
        _load_text(tmp_path, "[1, 2]")


def test_schema_is_shipped_and_valid():
    import jsonschema

    assert resources.files("photomodel.project").joinpath("schema.json").is_file()
    jsonschema.Draft202012Validator.check_schema(project_schema())


def test_every_preset_is_accepted(tmp_path, saved):
    _, d = saved
    template = _photo(d, 1, 0)
    d["expressions"][1]["photos"] = [dict(copy.deepcopy(template), id=k, preset=k)
                                     for k in PRESET_AZIMUTH_DEG]
    assert len(_load_dict(tmp_path, d).expressions[1].photos) == len(PRESET_AZIMUTH_DEG)


# ---------------------------------------------------------------------------------------
# saving: validated first, atomic, keeps a backup
# ---------------------------------------------------------------------------------------
def _temp_files(folder: Path) -> list[str]:
    return sorted(f.name for f in folder.iterdir() if f.name.endswith(".tmp"))


def test_save_keeps_previous_version_as_bak(tmp_path, saved):
    path, _ = saved
    first = path.read_bytes()
    p = load_project(path)
    p.expressions[0].photos[0].points["nose_tip"] = np.array([1.0, 2.0])
    save_project(p)
    assert Path(str(path) + ".bak").read_bytes() == first
    assert load_project(path).expressions[0].photos[0].points["nose_tip"].tolist() == [1.0, 2.0]
    assert _temp_files(tmp_path) == []


@pytest.mark.parametrize("target", ["os.replace", "final os.replace", "os.fsync", "write"])
def test_failed_save_leaves_original_intact(tmp_path, saved, monkeypatch, target):
    path, _ = saved
    before = path.read_bytes()
    p = load_project(path)
    p.name = "changed"

    def boom(*args, **kwargs):
        raise OSError(28, "No space left on device")

    real_replace = os.replace

    def fail_final_replace(src, dst):
        if Path(dst) == path:  # the backup copy succeeds, the move over the project fails
            boom()
        real_replace(src, dst)

    if target == "final os.replace":
        monkeypatch.setattr(os, "replace", fail_final_replace)
    elif target == "write":
        # the disk fills half-way through writing: the first half is on disk already
        real_fdopen = os.fdopen

        class HalfWriter:
            def __init__(self, *args, **kwargs):
                self.fh = real_fdopen(*args, **kwargs)

            def __enter__(self):
                return self

            def __exit__(self, *exc):
                self.fh.close()

            def write(self, text):
                self.fh.write(text[: len(text) // 2])
                self.fh.flush()
                boom()

        monkeypatch.setattr(os, "fdopen", HalfWriter)
    else:
        monkeypatch.setattr(os, target.split(".")[1], boom)
    with pytest.raises(ProjectError) as ei:
        save_project(p)
    assert "could not save the project: No space left on device" in str(ei.value)
    monkeypatch.undo()
    assert path.read_bytes() == before
    assert load_project(path).name == "james"
    assert _temp_files(tmp_path) == []


def test_invalid_project_is_not_written(tmp_path):
    p = _project(tmp_path)
    p.expressions[0].photos[0].points["nosetip"] = np.array([1.0, 2.0])
    with pytest.raises(ProjectError, match=r"points\.nosetip: no feature named 'nosetip'"):
        save_project(p)
    assert not p.path.exists() and _temp_files(tmp_path) == []

    p = _project(tmp_path)
    p.expressions[0].photos[0].points["nose_tip"] = np.array([np.nan, 2.0])
    with pytest.raises(ProjectError, match=r"points\.nose_tip\[0\]: nan is not a finite number"):
        save_project(p)
    assert not p.path.exists()


def test_save_writes_paths_relative_to_the_project(tmp_path):
    p = _project(tmp_path)
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
    assert load_project(tmp_path / "back.facestudio.json").expressions[0].photos[0].path == \
        "photos/neutral_front.png"


def test_documented_example_loads(tmp_path):
    """The example in docs/project-format.md is a valid project (keeps the docs honest)."""
    doc = (Path(__file__).resolve().parents[1] / "docs" / "project-format.md").read_text()
    example = doc.split("```json\n", 1)[1].split("```", 1)[0]
    p = _load_text(tmp_path, example)
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
    """The loader checks coordinate maps in Python for speed (project._validator); the shipped
    schema, read by a standard validator, must accept and reject exactly the same values."""
    import jsonschema

    from photomodel.project.format import _validator

    standard = jsonschema.Draft202012Validator(project_schema())
    _, d = saved
    assert standard.is_valid(d) and _validator().is_valid(d)
    good = {"pixel": [1, 2.5], "polyline": [[1, 2], [3.5, 4]], "vec3": [0, -1.5, 2]}[kind]
    for value in [good, *LEAF_VALUES[kind]]:
        e = copy.deepcopy(d)
        if kind == "pixel":
            _photo(e)["points"]["eye_l"] = value
        elif kind == "polyline":
            _photo(e)["curves"]["brow_r"] = value
        else:
            e["expressions"][0]["result"]["points_3d"]["eye_l"] = value
        assert standard.is_valid(e) == _validator().is_valid(e) == (value is good), value


# ---------------------------------------------------------------------------------------
# result.texture (written by `facestudio texture`; optional, absent from files without one)
# ---------------------------------------------------------------------------------------
def _textured(tmp_path: Path) -> Project:
    from photomodel.project.format import TextureResult

    p = _project(tmp_path)
    p.expression("neutral").result.texture = TextureResult(
        size=512, image="results/neutral_texture.png",
        weight_maps={"left": "results/neutral_weights_left.png", "front": "results/neutral_weights_front.png"},
        exports={"obj": "results/neutral_textured.obj", "glb": "results/neutral.glb",
                 "ply": "results/neutral_colors.ply"},
        report={"coverage": 0.97, "extract_s": 0.5})
    return p


def test_texture_round_trip_and_absent_when_none(tmp_path, saved):
    path, d = saved
    assert "texture" not in d["expressions"][0]["result"]  # files without a texture are unchanged
    p = _textured(tmp_path)
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


@pytest.mark.parametrize("mutate, expected", [
    (lambda t: t["weight_maps"].__setitem__("back", "w.png"),
     "expressions[0].result.texture.weight_maps.back: weight map for photo 'back', which is not a photo"),
    (lambda t: t["exports"].__setitem__("fbx", "a.fbx"), "expressions[0].result.texture.exports"),
    (lambda t: t.pop("image"), "'image' is a required property"),
    (lambda t: t.__setitem__("size", 0), "texture.size: expected the texture size in texels"),
])
def test_texture_validation_names_the_field(tmp_path, mutate, expected):
    p = _textured(tmp_path)
    d = p.to_dict()
    mutate(d["expressions"][0]["result"]["texture"])
    with pytest.raises(ProjectError) as exc:
        _load_dict(tmp_path, d)
    assert expected in str(exc.value)


# ---------------------------------------------------------------------------------------
# cameras_from: an expression photographed by another expression's cameras
# ---------------------------------------------------------------------------------------
def test_cameras_from_round_trip_and_absent_when_none(tmp_path, saved):
    _, d = saved
    assert all("cameras_from" not in e for e in d["expressions"])  # files without it are unchanged
    p = _project(tmp_path)
    p.expression("smile").cameras_from = "neutral"
    save_project(p)
    d = json.loads(p.path.read_text())
    assert d["expressions"][1]["cameras_from"] == "neutral"
    assert list(d["expressions"][1])[:2] == ["name", "cameras_from"]  # readable: next to the name
    q = load_project(p.path)
    assert q == p and q.expression("smile").cameras_from == "neutral"
    assert q.expression("neutral").cameras_from is None
    d["expressions"][1]["cameras_from"] = None  # an explicit null is the default
    assert _load_dict(tmp_path, d).expression("smile").cameras_from is None


@pytest.mark.parametrize("mutate, expected", [
    (lambda d: d["expressions"][1].__setitem__("cameras_from", "neutal"),
     ["expressions[1].cameras_from: no expression named 'neutal' to take the cameras from",
      "did you mean 'neutral'"]),
    (lambda d: d["expressions"][1].__setitem__("cameras_from", "smile"),
     ["expressions[1].cameras_from: expression 'smile' cannot take its cameras from itself"]),
    (lambda d: (d["expressions"][0].__setitem__("cameras_from", "smile"),
                d["expressions"][1].__setitem__("cameras_from", "neutral")),
     ["expressions[0].cameras_from: cameras_from goes round in a cycle (neutral → smile → neutral)",
      "expressions[1].cameras_from: cameras_from goes round in a cycle (smile → neutral → smile)"]),
    (lambda d: d["expressions"][1].__setitem__("cameras_from", 3),
     ["expressions[1].cameras_from: expected null or the name of another expression"]),
    (lambda d: d["expressions"][1].__setitem__("cameras_from", ""),
     ["expressions[1].cameras_from: expected a non-empty name"]),
])
def test_malformed_cameras_from_names_the_field(tmp_path, saved, mutate, expected):
    _, d = saved
    mutate(d)
    with pytest.raises(ProjectError) as ei:
        _load_dict(tmp_path, d)
    for s in expected:
        assert s in str(ei.value), f"{s!r} not in {str(ei.value)!r}"


def test_cameras_from_chain_without_cycle_is_valid(tmp_path, saved):
    _, d = saved
    d["expressions"].append({"name": "frown", "cameras_from": "smile", "photos": []})
    d["expressions"][1]["cameras_from"] = "neutral"
    p = _load_dict(tmp_path, d)
    assert [e.cameras_from for e in p.expressions] == [None, "neutral", "smile"]


def test_invalid_cameras_from_is_not_saved(tmp_path):
    p = _project(tmp_path)
    p.expression("smile").cameras_from = "grin"
    with pytest.raises(ProjectError, match="no expression named 'grin'"):
        save_project(p)
    assert not p.path.exists()


# ---------------------------------------------------------------------------------------
# format version 2: photo camera_group (photos sharing one camera and lens)
# ---------------------------------------------------------------------------------------
def test_version_1_file_loads_and_is_saved_as_version_2(tmp_path, saved):
    """Version 1 needs no upgrade (it has no camera groups); saving writes version 2."""
    _, d = saved
    d["version"] = 1
    p = _load_dict(tmp_path, d)
    assert p == _project()
    assert all(ph.camera_group is None for e in p.expressions for ph in e.photos)
    assert p.camera_groups("neutral") == [0, 1]  # each photo a camera of its own
    again = json.loads(save_project(p, tmp_path / "v2.facestudio.json").read_text())
    assert again["version"] == 2 and again["expressions"] == d["expressions"]
    # the committed sample project is a version-1 file and still loads
    sample = load_project(Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "james.facestudio.json")
    assert sample.camera_groups("neutral") == [0, 1, 2, 3, 4]


def test_camera_group_round_trip_and_absent_when_none(tmp_path, saved):
    _, d = saved
    assert all("camera_group" not in ph for e in d["expressions"] for ph in e["photos"])
    p = _project(tmp_path)
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
    assert _load_dict(tmp_path, d).expression("neutral").photos[0].camera_group is None


@pytest.mark.parametrize("value, expected", [
    (3, "expected null or a camera group name (a non-empty string), got 3"),
    ("", "expected null or a camera group name (a non-empty string), got \"\""),
    (["video"], "expected null or a camera group name"),
    (True, "expected null or a camera group name"),
])
def test_malformed_camera_group_names_the_field(tmp_path, saved, value, expected):
    _, d = saved
    _photo(d, 0, 1)["camera_group"] = value
    with pytest.raises(ProjectError) as ei:
        _load_dict(tmp_path, d)
    msg = str(ei.value)
    assert msg.startswith("james.facestudio.json: expressions[0].photos[1].camera_group: "), msg
    assert expected in msg, msg


def test_invalid_camera_group_is_not_saved(tmp_path):
    p = _project(tmp_path)
    p.expression("neutral").photos[0].camera_group = ""
    with pytest.raises(ProjectError, match=r"photos\[0\]\.camera_group: expected null or a camera group"):
        save_project(p)
    assert not p.path.exists()


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
