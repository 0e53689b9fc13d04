"""The fit's checklist in the studio, driven as an artist: what is still to click, unflag a pose
feature, leave one out of a photo, undo; the next feature in the 3D view; the fit's prediction
drawn as a ghost marker on the photo."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import QPointF, Qt  # noqa: E402


def _without(project_file, feature: str, keep: str) -> None:
    """Delete ``feature``'s clicks from every neutral photo but ``keep``."""
    data = json.loads(project_file.read_text())
    for photo in data["expressions"][0]["photos"]:
        if photo["id"] != keep:
            photo["points"].pop(feature, None)
    project_file.write_text(json.dumps(data))


def _todo(panel) -> list:
    return [panel.todo.item(i).data(Qt.ItemDataRole.UserRole) for i in range(panel.todo.count())]


def _action(menu, text: str):
    return next(a for a in menu.actions() if a.text() == text)


def test_checklist_unflag_leave_out_undo(qtbot, studio_window, project_copy):
    _without(project_copy, "chin", keep="front")
    assert studio_window.open_project(project_copy)
    studio_window.act_auto.setChecked(False)
    model, panel, stack = studio_window.model, studio_window.panel, studio_window.undo_stack
    # the checklist names the under-clicked pose feature; a click on it makes it active
    assert _todo(panel) == [("feature", "chin")]
    assert "clicked only in 'front'" in panel.todo.item(0).toolTip()
    panel.todo.itemClicked.emit(panel.todo.item(0))
    assert model.active_feature == "chin"
    # the 3D view rings it as the next feature to click
    studio_window.view3d.repaint()
    assert studio_window.view3d.next_feature == "chin"

    # -- the views cannot see it twice: unflag it from the feature list's menu, then undo
    menu = panel.feature_menu("chin")
    _action(menu, "Unflag chin as a pose feature").trigger()
    assert not model.project.feature("chin").pose
    assert _todo(panel) == [None]  # "every pose feature is clicked in 2+ photos"
    assert panel.feature_item("chin").parent().text(0).startswith("Other features")
    stack.undo()
    assert model.project.feature("chin").pose and _todo(panel) == [("feature", "chin")]

    # -- leave a pose feature out of one photo (hidden there), then undo
    menu = panel.feature_menu("nose_tip")
    sub = next(a.menu() for a in menu.actions() if a.menu() is not None)
    front = _action(sub, "front")
    assert not front.isChecked()
    front.trigger()
    assert "nose_tip" in model.photo("front").hidden
    assert panel.feature_menu("nose_tip") is not None
    stack.undo()
    assert "nose_tip" not in model.photo("front").hidden
    assert stack.undo_text == ""  # nothing else was pushed


def test_predicted_marker_after_a_fit(qtbot, studio_window, project_copy, messages):
    assert studio_window.open_project(project_copy)
    studio_window.act_auto.setChecked(False)
    model = studio_window.model
    model.set_active_feature("nose_tip")
    view = studio_window.show_photo("front")
    qtbot.waitUntil(lambda: view.isVisible())
    assert not view.predicted_item.isVisible()  # no cameras yet
    assert studio_window.run_fit()
    qtbot.waitUntil(lambda: not studio_window.fits.busy and model.fit() is not None, timeout=60_000)
    assert not messages, messages
    # the fitted nose tip projected into the front photo lies on its click (σ = 1 px sample clicks)
    item = view.predicted_item
    assert item.isVisible() and item.name == "nose_tip"
    uv = np.array([item.pos().x(), item.pos().y()])
    assert np.linalg.norm(uv - model.photo("front").points["nose_tip"]) < 4.0
    # a feature not clicked in this photo is predicted too: where to click it
    model.set_active_feature("eye_l_outer")
    right = studio_window.show_photo("right")
    qtbot.waitUntil(lambda: right.isVisible())
    assert right.predicted_item.isVisible() and right.predicted_item.name == "eye_l_outer"


def test_one_photo_checklist_and_fit(qtbot, studio_window, project_copy, messages):
    """An artist with one photo: the checklist asks for clicks in that photo only, Fit works (the
    camera placed against the generic head), and the fitted features land on the clicks."""
    data = json.loads(project_copy.read_text())
    expr = data["expressions"][0]
    expr["photos"] = [p for p in expr["photos"] if p["id"] == "three_quarter_left"]
    data["expressions"] = [expr]
    photo = expr["photos"][0]
    kept = dict(list(photo["points"].items())[:5])  # five clicks: one short of a camera
    rest = {k: v for k, v in photo["points"].items() if k not in kept}
    photo["points"] = kept
    project_copy.write_text(json.dumps(data))
    assert studio_window.open_project(project_copy)
    studio_window.act_auto.setChecked(False)
    model, panel = studio_window.model, studio_window.panel
    assert ("photo", "three_quarter_left") in _todo(panel)
    assert "5/6 clicks" in "\n".join(panel.todo.item(i).text() for i in range(panel.todo.count()))
    # the artist clicks ten more features where the sample's clicks put them
    view = studio_window.show_photo("three_quarter_left")
    qtbot.waitUntil(lambda: view.isVisible())
    more = dict(list(rest.items())[:10])
    for name, uv in more.items():
        model.set_active_feature(name)
        pos = view.mapFromScene(QPointF(float(uv[0]), float(uv[1])))
        qtbot.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=pos)
        assert name in model.photo("three_quarter_left").points
    panel.refresh_checklist()
    # the photo has its clicks; left: the pose features this view hides (far side), which the
    # fit does without
    assert all(kind == "feature" for kind, _ in _todo(panel))
    assert studio_window.run_fit()
    qtbot.waitUntil(lambda: not studio_window.fits.busy and model.fit() is not None, timeout=60_000)
    assert not messages, messages
    assert "one photo" in model.fit().report["camera_solve"]["start"]
    # a clicked feature's fitted position lands on its click (one view: the clicks are met)
    name, uv = next(iter(more.items()))
    model.set_active_feature(name)
    item = view.predicted_item
    qtbot.waitUntil(lambda: item.isVisible() and item.name == name)
    assert np.linalg.norm([item.pos().x() - uv[0], item.pos().y() - uv[1]]) < 2.0


def test_a_profile_left_out_of_the_fit_is_named_in_the_panel(qtbot, studio_window, project_copy, messages):
    # the detector's clicks in a profile (fit._without_profile_detections) are not fitted while
    # other photos place the cameras: the panel names the photo and why, and activating the line
    # shows that photo, where the artist drags them
    data = json.loads(project_copy.read_text())
    left = next(p for p in data["expressions"][0]["photos"] if p["id"] == "left")
    left["click_sources"] = {n: {"source": "auto", "confidence": 0.9} for n in left["points"]}
    data["version"] = max(data.get("version", 1), 3)
    project_copy.write_text(json.dumps(data))
    assert studio_window.open_project(project_copy)
    studio_window.act_auto.setChecked(False)
    model, panel = studio_window.model, studio_window.panel
    assert studio_window.run_fit()
    qtbot.waitUntil(lambda: not studio_window.fits.busy and model.fit() is not None, timeout=60_000)
    assert not messages, messages
    assert "left" not in model.fit().cameras
    lines = [panel.worst.item(i) for i in range(panel.worst.count())]
    named = [it for it in lines if it.text().startswith("⚠ left: left out of the fit")]
    assert len(named) == 1 and "a profile" in named[0].toolTip()
    panel.worst.itemActivated.emit(named[0])
    qtbot.waitUntil(lambda: getattr(studio_window.current_view(), "photo_id", None) == "left")
