"""The fit's checklist: every missing or under-clicked pose feature and photo at once."""

from __future__ import annotations

from pathlib import Path

import pytest

from photomodel.errors import FitError, MissingClicks
from photomodel.modeling.checklist import click_checklist, require_clicks
from photomodel.modeling.fit import FitOptions, fit_expression
from photomodel.project import load_project

PROJECT = Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "james.facestudio.json"


def test_the_sample_lacks_nothing():
    assert click_checklist(load_project(PROJECT), "neutral") == []


def test_no_clicks_lists_every_pose_feature_and_photo(mesh):
    project = load_project(PROJECT)
    for p in project.expression("neutral").photos:
        p.points = {}
    with pytest.raises(MissingClicks) as info:
        fit_expression(project, "neutral", mesh)
    err = info.value
    assert isinstance(err, FitError)  # callers that catch FitError still do
    pose = project.feature_names(pose_only=True)
    assert [it["feature"] for it in err.checklist if it["feature"]] == pose  # all 13, not the first
    assert [it["photo"] for it in err.checklist if it["photo"]] == [p.id for p in project.expression("neutral").photos]
    assert all(it["photos_clicked"] == 0 and it["needed"] in (2, 4) for it in err.checklist)
    msg = str(err)
    assert all(name in msg for name in pose) and "0 of 13 pose feature(s)" in msg
    # with no click anywhere (no face found in any photo), the message says where to click
    assert "no photo has a click yet" in msg and f"facestudio studio {project.path}" in msg


def test_under_clicked_and_hidden_features_say_where(mesh):
    project = load_project(PROJECT)
    photos = project.expression("neutral").photos
    for p in photos[1:]:  # eye_r_outer clicked in 'right' only
        p.points.pop("eye_r_outer", None)
    photos[2].hidden.add("nose_tip")  # nose_tip hidden in 'front'
    for p in photos:
        if p.id not in ("front", "left"):
            p.points.pop("nose_tip", None)
    items = {it.feature: it for it in click_checklist(project, "neutral")}
    assert set(items) == {"eye_r_outer", "nose_tip"}
    eye = items["eye_r_outer"]
    assert (eye.photos_clicked, eye.needed, eye.clicked_in) == (1, 2, ["right"])
    assert "'front'" in eye.hint and "unflag" in eye.hint
    nose = items["nose_tip"]
    assert (nose.clicked_in, nose.hidden_in) == (["left"], ["front"]) and "hidden in 'front'" in nose.hint
    # the robust fit goes on without them (reported as dropped); the paper's pose recovery stops
    assert len(require_clicks(project, "neutral")) == 2
    result = fit_expression(project, "neutral", mesh, FitOptions(refine=False))
    assert any("eye_r_outer" in d for d in result.report["dropped"])
    with pytest.raises(MissingClicks, match="eye_r_outer.*\n.*nose_tip"):
        fit_expression(project, "neutral", mesh, FitOptions(bundle_all=False, refine=False))


def test_unflagged_feature_leaves_the_checklist():
    project = load_project(PROJECT)
    for p in project.expression("neutral").photos:
        p.points.pop("chin", None)
    assert [it.feature for it in click_checklist(project, "neutral")] == ["chin"]
    project.feature("chin").pose = False
    assert click_checklist(project, "neutral") == []
