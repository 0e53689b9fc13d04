"""The ``facestudio`` command as a user runs it: on a copy of the sample project."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from app.cli import main
from photomodel.errors import FaceStudioError
from photomodel.exchange.mesh import read_mesh
from photomodel.project import load_project, save_project
from tracking.first_pose import read_pose_spec

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"


def test_fit_writes_results_into_the_project(project_copy, capsys):
    assert main(["fit", str(project_copy), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    # every expression, the neutral first: the other four reuse its cameras
    assert [e["name"] for e in out["expressions"]] == ["neutral", "smile", "open_mouth", "brows_raised", "frown"]
    expr = out["expressions"][0]
    assert {v["photo"] for v in expr["views"]} == {
        "right",
        "three_quarter_right",
        "front",
        "three_quarter_left",
        "left",
    }
    assert expr["rms_px"] < 3.0
    project = load_project(project_copy)
    result = project.expression("neutral").result
    assert set(result.cameras) == {v["photo"] for v in expr["views"]}
    vertices, faces = read_mesh(project.resolve(result.mesh_obj))
    v2, _ = read_mesh(project.resolve(result.mesh_ply))
    assert vertices.shape[0] > 5000 and faces.shape[1] == 3
    np.testing.assert_allclose(vertices, v2, atol=1e-4)
    # every clicked feature has a 3D point, and the clicks are untouched
    assert "nose_tip" in result.points_3d
    original = load_project(SAMPLE / "james.facestudio.json")
    assert (
        project.expression("neutral").photos[0].points.keys() == original.expression("neutral").photos[0].points.keys()
    )
    # the stored result reprojects at the RMS the report prints (cameras and points as saved,
    # every click of a feature with a 3D point; 1e-3 px: the file rounds cameras and points)
    for e in out["expressions"]:
        res = project.expression(e["name"]).result
        names = list(res.points_3d)
        obs = project.observations(e["name"], names)
        X = np.array([res.points_3d[n] for n in names])
        ids = [p.id for p in project.expression(e["name"]).photos]
        err = np.stack([res.cameras[i].project(X) for i in ids]) - obs
        ok = np.isfinite(err[..., 0])
        assert abs(np.sqrt((err[ok] ** 2).sum() / ok.sum()) - e["rms_px"]) < 1e-3
        assert e["suspect_clicks"] == []  # the sample's clicks carry 1 px noise and no wrong click


def test_fit_prints_a_table(project_copy, capsys):
    assert main(["fit", str(project_copy), "--dry-run", "--expression", "neutral"]) == 0
    out = capsys.readouterr().out
    assert "reprojection RMS" in out and "worst points" in out and "front" in out
    assert load_project(project_copy).expression("neutral").result is None  # dry run wrote nothing


def test_malformed_project_is_reported_and_left_alone(tmp_path, capsys):
    bad = tmp_path / "bad.facestudio.json"
    text = (SAMPLE / "james.facestudio.json").read_text().replace('"pose": true', '"pose": "yes"', 1)
    bad.write_text(text)
    assert main(["fit", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.facestudio.json" in err and "pose" in err
    assert bad.read_text() == text


def test_missing_project_file(tmp_path, capsys):
    assert main(["fit", str(tmp_path / "nope.facestudio.json")]) == 2
    assert "nope.facestudio.json" in capsys.readouterr().err


def test_missing_photo_is_named_but_the_fit_uses_the_clicks(project_copy, capsys):
    (project_copy.parent / "photos" / "neutral_left.png").unlink()
    assert main(["fit", str(project_copy), "--dry-run", "--expression", "neutral"]) == 0
    assert "neutral_left.png" in capsys.readouterr().err


def test_too_few_clicks_is_a_clear_error(project_copy, capsys):
    project = json.loads(project_copy.read_text())
    for photo in project["expressions"][0]["photos"]:
        photo["points"] = dict(list(photo["points"].items())[:3])
    project_copy.write_text(json.dumps(project))
    before = project_copy.read_text()
    assert main(["fit", str(project_copy)]) == 2
    assert "error" in capsys.readouterr().err
    assert project_copy.read_text() == before


def test_fit_all_fits_a_cameras_source_first(project_copy, capsys):
    """Expressions that reuse another's cameras (cameras_from) are fitted after it, whatever the
    file's order; the report says where the cameras came from."""
    project = json.loads(project_copy.read_text())
    by_name = {e["name"]: e for e in project["expressions"]}
    project["expressions"] = [by_name["smile"], by_name["neutral"]]  # the source last in the file
    project_copy.write_text(json.dumps(project))
    assert main(["fit", str(project_copy), "--json", "--dry-run"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [e["name"] for e in out["expressions"]] == ["neutral", "smile"]
    neutral, smile = out["expressions"]
    assert smile["cameras_from"] == "neutral" and neutral["cameras_from"] is None
    assert smile["cameras"] == neutral["cameras"]  # the very same cameras
    assert smile["rms_px"] < 1.5  # measured 1.14 px: the click noise


def test_fit_of_an_expression_whose_source_is_unfitted_is_a_clear_error(project_copy, capsys):
    before = project_copy.read_text()
    assert main(["fit", str(project_copy), "--expression", "smile"]) == 2
    err = capsys.readouterr().err
    assert "takes its cameras from expression 'neutral', which is not fitted yet: fit 'neutral' first" in err
    assert project_copy.read_text() == before
    # once the neutral is fitted (and saved), the smile is fitted with its cameras
    assert main(["fit", str(project_copy), "--expression", "neutral"]) == 0
    capsys.readouterr()
    assert main(["fit", str(project_copy), "--expression", "smile"]) == 0
    assert "cameras of expression 'neutral' (same rig), kept fixed" in capsys.readouterr().out
    project = load_project(project_copy)
    smile, neutral = project.expression("smile").result, project.expression("neutral").result
    assert smile.report["cameras_from"] == "neutral" and smile.mesh_obj == "results/smile.obj"
    np.testing.assert_array_equal(smile.cameras["front"].R, neutral.cameras["front"].R)


def test_fit_json_error_lists_every_missing_click(project_copy, capsys):
    data = json.loads(project_copy.read_text())
    for photo in data["expressions"][0]["photos"]:
        photo["points"] = {}
    project_copy.write_text(json.dumps(data))
    assert main(["fit", str(project_copy), "--json", "--expression", "neutral"]) == 2
    captured = capsys.readouterr()
    err = json.loads(captured.out)["error"]  # one JSON object, the error in it
    assert err["type"] == "MissingClicks" and err["expression"] == "neutral"
    pose = [f["name"] for f in data["features"] if f["pose"]]
    assert [c["feature"] for c in err["checklist"] if c["feature"]] == pose
    assert all(name in captured.err for name in pose)  # the plain message lists them all too


def test_the_fit_summary_says_one_reason_for_many_features_once():
    from app.cli.fit import grouped_reasons as _grouped_reasons

    why = "automatic click(s) unsure (confidence < 0.5) and 0 sure; the generic mesh places it"
    reasons = ["photo 'right': no click (no face found?), left out of the fit"]
    reasons += [f"jaw_{i:02d}: {3 + i % 2} {why}" for i in range(5)]
    reasons += ["nose_tip: clicked in 1 photo(s)", "chin: clicked in 1 photo(s)"]
    out = _grouped_reasons(reasons)
    assert out[0] == reasons[0]
    assert out[1] == f"5 features for one reason (jaw_00, jaw_01, jaw_02, jaw_03, jaw_04), e.g. jaw_00: 3 {why}"
    assert out[2:] == ["nose_tip: clicked in 1 photo(s)", "chin: clicked in 1 photo(s)"]  # two: as they are


def test_fit_checks_photo_sizes_at_load_and_names_what_changed(project_copy, capsys):
    """Issue 35: a photo replaced by one of another size (its clicks are in the old one's pixels)
    is an error naming it and both sizes before any work, not a fit and a false "the photo
    changed since the fit" from texture later."""
    photo = project_copy.parent / "photos" / "neutral_front.png"
    cv2.imwrite(str(photo), np.zeros((1, 1, 3), np.uint8))
    before = project_copy.read_bytes()
    assert main(["fit", str(project_copy), "--expression", "neutral", "--no-refine"]) == 2
    err = capsys.readouterr().err
    assert "neutral_front.png is now 1x1 pixels" in err and "'front'" in err and "Traceback" not in err, err
    assert project_copy.read_bytes() == before


def test_fit_table_columns_hold_a_long_photo_name(project_copy, capsys):
    project = load_project(project_copy)
    long_id = "front_taken_on_holiday_in_the_mountains_2024"
    project.expression("neutral").photo("front").id = long_id
    save_project(project, project_copy)
    assert main(["fit", str(project_copy), "--expression", "neutral", "--no-refine", "--dry-run"]) == 0
    out = capsys.readouterr().out.splitlines()
    header = next(i for i, line in enumerate(out) if "RMS px" in line and "focal mm" in line)
    rows = out[header : header + 6]
    assert any(long_id in r for r in rows)
    ends = {len(r.rstrip()) for r in rows}  # the last column (focal mm) ends at one place on every row
    assert len(ends) == 1, rows


def test_version_and_sample_data_help(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and capsys.readouterr().out.startswith("facestudio ")
    with pytest.raises(SystemExit):
        main(["sample-data", "--help"])
    assert "SHA-256" in capsys.readouterr().out


def test_first_pose_hint_suits_track_many():
    """track-many has no --first-pose: the hint names the file beside the video, and the flag as `track`'s."""
    with pytest.raises(FaceStudioError) as err:
        read_pose_spec(Path("/nonexistent/clip.first_pose.json"))
    assert "`facestudio track` also takes one as --first-pose" in str(err.value)
