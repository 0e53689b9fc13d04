"""Tests of photomodel.project.jsontext: the readable writer and strict parsing (line and column,
NaN/Infinity literals, repeated keys), each problem named with its JSON path."""

from __future__ import annotations

import pytest
from project_samples import load_text, save_sample

from photomodel.errors import ProjectError


@pytest.fixture
def saved(tmp_path):
    """(path, dict) of a valid saved project with its photos on disk."""
    return save_sample(tmp_path)


def test_file_is_readable_json(saved):
    path, d = saved
    text = path.read_text()
    assert text.startswith('{\n  "format": "facestudio-project",\n  "version": 6,')
    assert '"nose_tip": [31.5, 20.25]' in text  # a click on one line
    assert '{"name": "nose_tip", "vertex": 10, "pose": true}' in text
    assert "NaN" not in text and "Infinity" not in text


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_non_finite_literals_rejected_with_path(tmp_path, saved, literal):
    path, _ = saved
    text = path.read_text().replace('"nose_tip": [31.5, 20.25]', f'"nose_tip": [31.5, {literal}]')
    assert literal in text
    with pytest.raises(ProjectError) as ei:
        load_text(tmp_path, text)
    assert f"expressions[0].photos[0].points.nose_tip[1]: {literal} is not a finite number" in str(ei.value)


def test_not_json_gives_line_and_column(tmp_path, saved):
    path, _ = saved
    lines = path.read_text().splitlines()
    lines[3] = lines[3].rstrip(",")  # drop the comma after "name": "james"
    with pytest.raises(ProjectError) as ei:
        load_text(tmp_path, "\n".join(lines))
    expected = "james.facestudio.json: not valid JSON: Expecting ',' delimiter (line 5, column 3)"
    assert expected in str(ei.value)


def test_duplicate_json_key_rejected(tmp_path, saved):
    path, _ = saved
    click = '"nose_tip": [31.5, 20.25]'
    text = path.read_text().replace(click, click + ', "nose_tip": [1, 2]')
    with pytest.raises(ProjectError, match=r"photos\[0\]\.points: key 'nose_tip' appears more than once"):
        load_text(tmp_path, text)
