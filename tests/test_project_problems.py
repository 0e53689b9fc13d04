"""Tests of photomodel.project.problems: how a project problem is worded."""

from __future__ import annotations

from photomodel.errors import ProjectError
from photomodel.project.problems import did_you_mean, fmt_path, listing, problems_error, short


def test_json_paths():
    assert fmt_path(("expressions", 0, "photos", 2, "points", "nose_tip")) == "expressions[0].photos[2].points.nose_tip"
    assert fmt_path(("points", "left eye")) == 'points["left eye"]'
    assert fmt_path(()) == "(top level)"


def test_values_listings_and_suggestions():
    assert short([12.0]) == "[12.0]" and short("é") == '"é"'
    assert short(list(range(100))).endswith("...") and len(short(list(range(100)))) == 80
    assert short({1, 2}) == "{1, 2}"  # not JSON: its repr
    assert listing(["a", "b"]) == "'a', 'b'" and listing([]) == "(none)"
    assert did_you_mean("nose_tp", ["nose_tip", "chin"]) == " (did you mean 'nose_tip'?)"
    assert did_you_mean("xyz", ["nose_tip"]) == ""


def test_one_error_for_several_problems():
    one = problems_error("a.json", [("features[0].name", "bad")])
    assert isinstance(one, ProjectError) and str(one) == "a.json: features[0].name: bad"
    many = problems_error("a.json", [(f"p[{i}]", "bad") for i in range(12)])
    lines = str(many).splitlines()
    assert lines[0] == "a.json: 12 problems:" and lines[1] == "  p[0]: bad" and lines[-1] == "  ... and 2 more"
    assert len(many.problems) == 12
