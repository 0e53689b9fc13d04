"""The studio's model (app.studio_state) without any window: the state the GUI, scripts and tests share."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from app.studio_state import MissingPhotos, Signal, StudioModel, autosave_path, newer_autosave
from photomodel.errors import ProjectError
from photomodel.project import load_project
from photomodel.samples.synthetic import load_ground_truth

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"


@pytest.fixture
def model(project_copy):
    m = StudioModel()
    m.open(project_copy)
    return m


def test_signal_calls_in_order_and_disconnects():
    s, got = Signal(), []
    a, b = (lambda x: got.append(("a", x))), (lambda x: got.append(("b", x)))
    s.connect(a)
    s.connect(b)
    s.connect(a)  # once only
    s.emit(1)
    s.disconnect(a)
    s.emit(2)
    assert got == [("a", 1), ("b", 1), ("b", 2)]


def test_fit_snapshot_is_an_independent_copy(model):
    """The worker's snapshot equals the project and shares no click, curve or set with it."""
    snap = model.fit_snapshot()
    assert snap == model.project and snap is not model.project
    for e, f in zip(model.project.expressions, snap.expressions, strict=True):
        assert e is not f and e.result is not f.result or e.result is None
        for a, b in zip(e.photos, f.photos, strict=True):
            assert a == b and a is not b
            assert a.hidden is not b.hidden and a.sources is not b.sources and a.confidence is not b.confidence
            for k in a.points:
                assert not np.shares_memory(a.points[k], b.points[k])
            for k in a.curves:
                assert not np.shares_memory(a.curves[k], b.curves[k])
    name = next(iter(model.project.expressions[0].photos[0].points))
    before = snap.expressions[0].photos[0].points[name].copy()
    model.project.expressions[0].photos[0].points[name] += 5.0  # an edit in place after the snapshot
    np.testing.assert_array_equal(snap.expressions[0].photos[0].points[name], before)


def test_edits_emit_events_and_mark_modified(model):
    events = []
    model.points_changed.connect(lambda *a: events.append(("point", *a)))
    model.modified_changed.connect(lambda v: events.append(("modified", v)))
    old = model.set_point("neutral", "front", "chin", (10.0, 20.0))
    assert old is not None and model.modified
    assert events == [("modified", True), ("point", "neutral", "front", "chin")]
    assert model.set_hidden("neutral", "front", "chin", True) is False
    assert np.isnan(model.project.observations("neutral", ["chin"])[2, 0, 0])  # hidden: unobserved
    with pytest.raises(ProjectError, match="no feature named 'nope'"):
        model.set_point("neutral", "front", "nope", (1.0, 2.0))
    with pytest.raises(ProjectError, match="not finite"):
        model.set_point("neutral", "front", "chin", (np.nan, 2.0))
    with pytest.raises(ProjectError, match="no photo 'back'"):
        model.set_point("neutral", "back", "chin", (1.0, 2.0))


def test_catalogue_offers_each_vertex_once(tmp_path):
    m = StudioModel()  # a new project: the 13 pose features
    names = [n for n, _, _, _ in m.catalogue()]
    vertices = [v for _, v, _, _ in m.catalogue()]
    assert len(vertices) == len(set(vertices)) and len(names) == len(set(names))
    assert sum(1 for *_, in_project, pose in m.catalogue() if in_project and pose) == 13
    assert {n for n, _ in m.curve_catalogue()} == set(m.mesh.curves)


def test_fit_residuals_and_worst_clicks(model, project_copy):
    result, seconds, cold = model.compute_fit(model.fit_snapshot(), "neutral")
    assert cold and seconds > 0
    model.apply_fit("neutral", result, seconds)
    res = model.click_residuals()
    # the sample's clicks carry σ = 1 px of noise: residuals of that order, none absurd
    allres = np.array([v for d in res.values() for v in d.values()])
    assert 0.3 < np.median(allres) < 2.5 and allres.max() < 10.0
    worst = model.worst_clicks(5)
    assert [w[0] for w in worst] == sorted(allres, reverse=True)[:5]
    # a click moved by 30 px becomes the worst one
    pid, name = "front", "chin"
    model.set_point("neutral", pid, name, model.photo(pid).points[name] + 30.0)
    assert model.worst_clicks(1)[0][1:] == (pid, name) and model.worst_clicks(1)[0][0] > 30.0

    # saving writes the fitted mesh next to the project and the result into it
    model.save()
    saved = load_project(project_copy).expression("neutral").result
    assert saved.mesh_ply == "results/neutral.ply" and (project_copy.parent / saved.mesh_ply).is_file()
    truth = load_ground_truth(project_copy.parent / "ground_truth.json")
    assert set(saved.cameras) == set(truth.cameras["neutral"])


def test_save_as_elsewhere_keeps_photos_resolvable(model, tmp_path):
    target = tmp_path / "elsewhere" / "copy.facestudio.json"
    model.save(target)
    assert model.path == target and not model.modified
    model.project.check_photos()  # the in-memory paths follow the file
    again = StudioModel()
    again.open(target)
    assert again.photo("front").points.keys() == model.photo("front").points.keys()


def test_autosave_recovery_and_bad_files(model, project_copy, tmp_path):
    assert model.autosave() is None  # nothing changed
    model.set_point("neutral", "front", "chin", (400.0, 800.0))
    written = model.autosave()
    assert written == autosave_path(project_copy) and newer_autosave(project_copy) == written
    assert json.loads(project_copy.read_text())["expressions"][0]["photos"][2]["points"]["chin"] != [400.0, 800.0]
    assert not written.with_name(written.name + ".bak").exists()

    other = StudioModel()
    other.open(project_copy, recover=True)
    np.testing.assert_allclose(other.photo("front").points["chin"], (400.0, 800.0))
    assert other.modified and other.path == project_copy.absolute()

    before = model.project
    bad = tmp_path / "bad.facestudio.json"
    bad.write_text("[1, 2")
    with pytest.raises(ProjectError, match="bad.facestudio.json"):
        model.open(bad)
    moved = tmp_path / "moved.facestudio.json"
    shutil.copy(project_copy, moved)
    with pytest.raises(MissingPhotos, match="neutral_front.png"):
        model.open(moved)
    assert model.project is before


def test_photo_from_file(model, tmp_path):
    photo = model.photo_from_file(SAMPLE / "photos" / "neutral_front.png")
    assert (photo.width, photo.height) == (1000, 1000) and photo.id == "neutral_front"
    junk = tmp_path / "junk.jpg"
    junk.write_bytes(b"\x00" * 10)
    with pytest.raises(ProjectError, match="junk.jpg"):
        model.photo_from_file(junk)
    with pytest.raises(ProjectError, match="no such file"):
        model.photo_from_file(tmp_path / "absent.png")


def test_set_photo_camera_group(model):
    events = []
    model.photo_changed.connect(lambda *a: events.append(a))
    assert model.set_photo_camera_group("neutral", "front", "video") is None
    assert model.photo("front", "neutral").camera_group == "video" and model.modified
    assert events == [("neutral", "front")]
    assert model.set_photo_camera_group("neutral", "front", None) == "video"
    for bad in ("", 3):
        with pytest.raises(ProjectError, match="camera group is a non-empty name"):
            model.set_photo_camera_group("neutral", "front", bad)
    with pytest.raises(ProjectError, match="no photo 'back'"):
        model.set_photo_camera_group("neutral", "back", "video")


def test_pose_flag_checklist_next_feature_and_prediction(model):
    events = []
    model.features_changed.connect(lambda: events.append("features"))
    assert model.checklist() == [] and model.next_feature() is None
    for p in model.photos:
        if p.id != "front":
            model.set_point("neutral", p.id, "mouth_l", None)
    assert [it.feature for it in model.checklist()] == ["mouth_l"] and model.next_feature() == "mouth_l"
    assert model.set_feature_pose("mouth_l", False) is True and events == ["features"]
    assert model.checklist() == [] and model.modified
    with pytest.raises(ProjectError, match="no feature named 'nope'"):
        model.set_feature_pose("nope", True)
    # the prediction: the fitted mesh's feature vertex through the photo's fitted camera
    assert model.predicted_uv("front", "nose_tip") is None  # no cameras yet
    result, seconds, _ = model.compute_fit(model.fit_snapshot(), "neutral")
    model.apply_fit("neutral", result, seconds)
    uv = model.predicted_uv("front", "nose_tip")
    cam = model.fit().cameras["front"]
    np.testing.assert_allclose(uv, cam.project(result.vertices[[model.project.feature("nose_tip").vertex]])[0])
    assert np.linalg.norm(uv - model.photo("front").points["nose_tip"]) < 4.0  # σ = 1 px clicks
