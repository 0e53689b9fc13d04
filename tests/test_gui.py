"""The studio driven as an artist drives it (pytest-qt, offscreen): click, drag, undo, fit, save, reopen.

Mouse events go to the photo view's viewport at the widget position that the view's transform
maps the wanted image position to (``view.mapFromScene``), so these tests exercise the same
coordinate mapping a user's clicks go through. Ground truth is the sample project's
``ground_truth.json`` (the photos are renderings of a scan from known cameras).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

import subprocess
import sys

from PySide6.QtCore import QPoint, QPointF, QSettings, Qt  # noqa: E402
from PySide6.QtWidgets import QMessageBox  # noqa: E402

from app.cli import main
from app.qt.main_window import MainWindow, guess_preset  # noqa: E402
from app.studio_state import autosave_path  # noqa: E402
from photomodel.alignment import align_to_truth, camera_errors  # noqa: E402
from photomodel.project import load_project  # noqa: E402
from photomodel.samples.synthetic import load_ground_truth  # noqa: E402

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"


def widget_pos(view, uv) -> QPoint:
    """The viewport position that shows image position ``uv``."""
    return view.mapFromScene(QPointF(float(uv[0]), float(uv[1])))


def test_artist_session_click_drag_undo_fit_save_reopen(qtbot, studio_window, project_copy, messages):
    truth = load_ground_truth(project_copy.parent / "ground_truth.json")
    assert studio_window.open_project(project_copy)
    model = studio_window.model
    studio_window.act_auto.setChecked(False)  # the explicit fit below is the one under test
    view = studio_window.show_photo("front")
    qtbot.waitUntil(lambda: view.isVisible())
    scale = view.scale_factor
    # a click lands within ~half a screen pixel of the wanted image position (integer widget
    # coordinates), i.e. 0.5/scale image px per axis
    tol = 0.75 / scale + 1e-6

    # -- pick a feature in the list, delete its click, click it again at its true position
    item = studio_window.panel.feature_item("nose_tip")
    studio_window.panel.features.setCurrentItem(item)
    assert model.active_feature == "nose_tip"
    qtbot.keyClick(view, Qt.Key.Key_Delete)
    assert "nose_tip" not in model.photo("front").points
    true_uv = truth.clean_points["neutral"]["front"]["nose_tip"]
    qtbot.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=widget_pos(view, true_uv))
    clicked = model.photo("front").points["nose_tip"]
    assert np.abs(clicked - true_uv).max() < tol, (clicked, true_uv)
    # H hides it in this photo (kept, but not observed), undo shows it again
    qtbot.keyClick(view, Qt.Key.Key_H)
    assert "nose_tip" in model.photo("front").hidden and view._items["nose_tip"].hidden
    studio_window.undo_stack.undo()
    assert "nose_tip" not in model.photo("front").hidden

    # -- drag the chin's marker 30 screen px to the right, then undo / redo
    before = model.photo("front").points["chin"].copy()
    start = widget_pos(view, before)
    end = start + QPoint(30, 0)
    qtbot.mousePress(view.viewport(), Qt.MouseButton.LeftButton, pos=start)
    qtbot.mouseMove(view.viewport(), start + QPoint(10, 0))
    qtbot.mouseMove(view.viewport(), end)
    qtbot.mouseRelease(view.viewport(), Qt.MouseButton.LeftButton, pos=end)
    after = model.photo("front").points["chin"]
    assert model.active_feature == "chin"
    assert after[0] - before[0] == pytest.approx(30 / scale, abs=tol)
    assert after[1] == pytest.approx(before[1], abs=tol)
    studio_window.undo_stack.undo()
    np.testing.assert_allclose(model.photo("front").points["chin"], before)
    assert view._items["chin"].pos().x() == pytest.approx(before[0])  # the marker went back too
    studio_window.undo_stack.redo()
    np.testing.assert_allclose(model.photo("front").points["chin"], after)
    studio_window.undo_stack.undo()

    # -- fit in the worker; the window keeps processing events meanwhile
    assert studio_window.run_fit()
    qtbot.waitUntil(lambda: not studio_window.fits.busy and model.fit() is not None, timeout=60_000)
    assert not messages, messages
    fit = model.fit()
    result = fit.result
    cams, _ = align_to_truth(result.cameras, result.points_3d, truth.true_points(result.feature_names))
    err = camera_errors(cams, [truth.cameras["neutral"][pid] for pid in result.photo_ids])
    # same bound and reason as tests/test_fit.py: σ = 1 px clicks, the profile views see 5–6 pose features
    assert err["rot_err_deg"].max() < 2.5, err
    assert "px" in studio_window.tabs.tabText(studio_window.tabs.currentIndex())  # per-view RMS in the tab title
    assert view.overlay_item.count > 1000  # the fitted wireframe is drawn over the photo
    assert studio_window.panel.worst.count() > 0

    # -- the worst click is one click away
    first = studio_window.panel.worst.item(0)
    pid, name = first.data(Qt.ItemDataRole.UserRole)
    studio_window.panel.worst.itemClicked.emit(first)
    assert studio_window.current_view().photo_id == pid and model.active_feature == name

    # -- auto-refit: a drag after a fast fit refits by itself
    studio_window.act_auto.setChecked(True)
    studio_window.fits.last_warm_s = None
    view = studio_window.show_photo("front")
    model.set_active_feature("chin")
    old_fit = model.fit()
    p = widget_pos(view, model.photo("front").points["chin"])
    qtbot.mousePress(view.viewport(), Qt.MouseButton.LeftButton, pos=p)
    qtbot.mouseMove(view.viewport(), p + QPoint(0, 4))
    qtbot.mouseRelease(view.viewport(), Qt.MouseButton.LeftButton, pos=p + QPoint(0, 4))
    qtbot.waitUntil(lambda: model.fit() is not old_fit and not studio_window.fits.busy, timeout=60_000)

    # -- save, reopen, compare the clicks
    clicks = {p.id: {k: v.copy() for k, v in p.points.items()} for p in model.photos}
    assert studio_window.save()
    assert not model.modified and not studio_window.isWindowModified()
    saved = json.loads(project_copy.read_text())
    assert saved["expressions"][0]["result"]["mesh_obj"] == "results/neutral.obj"
    assert (project_copy.parent / "results" / "neutral.ply").is_file()
    assert studio_window.open_project(project_copy)
    for p in studio_window.model.photos:
        assert p.points.keys() == clicks[p.id].keys()
        for k, uv in p.points.items():
            np.testing.assert_allclose(uv, clicks[p.id][k], atol=1e-3)  # stored to 1e-3 px
    assert studio_window.model.fit().vertices is not None  # the fitted mesh came back from results/
    assert str(project_copy.absolute()) in studio_window.recent_files()


def test_bad_files_leave_the_open_project_untouched(studio_window, project_copy, tmp_path, messages):
    assert studio_window.open_project(project_copy)
    model = studio_window.model
    project, path = model.project, model.path

    # malformed: a click with one coordinate
    bad = json.loads(project_copy.read_text())
    bad["expressions"][0]["photos"][2]["points"]["nose_tip"] = [12.0]
    bad_path = project_copy.parent / "bad.facestudio.json"
    bad_path.write_text(json.dumps(bad))
    assert not studio_window.open_project(bad_path)
    kind, title, text = messages[-1]
    assert kind == "critical" and "expressions[0].photos[2].points.nose_tip" in text and "Traceback" not in text
    assert model.project is project and model.path == path

    # not JSON at all
    bad_path.write_text("{ this is not json")
    assert not studio_window.open_project(bad_path)
    assert "bad.facestudio.json" in messages[-1][2] and model.project is project

    # a missing photo: the question names it; answering No keeps the current project
    other = tmp_path / "moved"
    other.mkdir()
    shutil.copy(project_copy, other / "james.facestudio.json")
    assert not studio_window.open_project(other / "james.facestudio.json")
    kind, title, text = messages[-1]
    assert kind == "question" and "photos/neutral_front.png" in text
    assert model.project is project and model.path == path

    # answering Yes opens it with placeholders
    messages.answers["question"] = QMessageBox.StandardButton.Yes
    assert studio_window.open_project(other / "james.facestudio.json")
    assert studio_window.views["front"].missing is not None

    # an unreadable photo file is named
    assert studio_window.open_project(project_copy)
    junk = tmp_path / "notes.png"
    junk.write_text("not an image")
    n = len(studio_window.model.photos)
    assert studio_window.add_photos([str(junk)]) == 0
    assert messages[-1][0] == "critical" and "notes.png" in messages[-1][2]
    assert len(studio_window.model.photos) == n


def test_add_photos_and_draw_a_curve(qtbot, studio_window, project_copy):
    studio_window.new_project()
    assert studio_window.model.photos == []
    photos = sorted((project_copy.parent / "photos").glob("*.png"))
    assert studio_window.add_photos([str(p) for p in photos]) == len(photos)
    model = studio_window.model
    assert {p.preset for p in model.photos} == {guess_preset(p.name) for p in photos}
    front = next(p for p in model.photos if p.preset == "front")
    assert (front.width, front.height) == (1000, 1000)  # read from the file

    view = studio_window.show_photo(front.id)
    qtbot.waitUntil(lambda: view.isVisible())

    # a generic-mesh feature the project does not use yet is added by its first click
    new_name = next(n for n, _, in_project, _ in model.catalogue() if not in_project)
    model.set_active_feature(new_name)
    qtbot.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=widget_pos(view, (500.0, 300.0)))
    assert model.has_feature(new_name) and new_name in model.photo(front.id).points
    studio_window.undo_stack.undo()
    assert not model.has_feature(new_name) and new_name not in model.photo(front.id).points

    model.set_active_curve("brow_l")
    studio_window.set_mode("curve")
    pts = [(560.0, 330.0), (600.0, 318.0), (650.0, 322.0), (690.0, 340.0)]
    for uv in pts:
        qtbot.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=widget_pos(view, uv))
    qtbot.keyClick(view, Qt.Key.Key_Return)
    line = model.photo(front.id).curves["brow_l"]
    assert line.shape == (4, 2)
    np.testing.assert_allclose(line, pts, atol=1.0 / view.scale_factor + 1e-6)
    studio_window.undo_stack.undo()
    assert "brow_l" not in model.photo(front.id).curves

    # Escape abandons a curve being drawn
    qtbot.mouseClick(view.viewport(), Qt.MouseButton.LeftButton, pos=widget_pos(view, pts[0]))
    qtbot.keyClick(view, Qt.Key.Key_Escape)
    qtbot.keyClick(view, Qt.Key.Key_Return)
    assert "brow_l" not in model.photo(front.id).curves

    studio_window.undo_stack.undo()  # the photos go again
    assert model.photos == []


def test_autosave_is_offered_for_recovery(qtbot, tmp_path, project_copy, messages):
    settings = QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat)
    w = MainWindow(settings=settings, autosave_interval_ms=0)
    qtbot.addWidget(w)
    assert w.open_project(project_copy)
    w.model.set_point("neutral", "front", "chin", (400.0, 800.0))
    w.autosave()
    assert autosave_path(project_copy).is_file()
    assert load_project(project_copy).expression("neutral").photo("front").points["chin"][0] != 400.0
    w.model.modified = False  # "crash": close without saving

    w2 = MainWindow(settings=settings, autosave_interval_ms=0)
    qtbot.addWidget(w2)
    messages.answers["question"] = QMessageBox.StandardButton.Yes
    assert w2.open_project(project_copy)
    assert messages[-1][1] == "Recover autosave"
    np.testing.assert_allclose(w2.model.photo("front").points["chin"], (400.0, 800.0))
    assert w2.model.modified and w2.model.path == project_copy.absolute()
    assert w2.save()
    assert not autosave_path(project_copy).exists()
    w2.model.modified = False


def _crashed_instance_lock(path: Path) -> None:
    """Leave ``<path>.lock`` as a studio that crashed leaves it: taken by a process that then died."""

    code = (
        "import os, sys; from PySide6.QtCore import QLockFile; "
        "l = QLockFile(sys.argv[1]); l.setStaleLockTime(0); assert l.tryLock(0); os._exit(0)"
    )
    subprocess.run([sys.executable, "-c", code, str(path) + ".lock"], check=True, timeout=60)
    assert Path(str(path) + ".lock").is_file()


def test_two_instances_keep_their_own_recovery_files(qtbot, tmp_path, project_copy, messages):
    """Two studios at once autosave untitled projects to files of their own; one starting later
    offers neither (both run) but does offer the file of an instance that crashed."""
    folder = tmp_path / "data"

    def window():
        w = MainWindow(
            settings=QSettings(str(tmp_path / "s.ini"), QSettings.Format.IniFormat),
            autosave_interval_ms=0,
            recovery_folder=folder,
        )
        qtbot.addWidget(w)
        return w

    photos = sorted((project_copy.parent / "photos").glob("*.png"))
    a, b = window(), window()
    assert a.recovery_file != b.recovery_file and a.recovery_file.parent == b.recovery_file.parent == folder
    a.add_photos([str(photos[0])])
    a.model.set_point("neutral", a.model.photos[0].id, "nose_tip", (500.0, 520.0))
    b.add_photos([str(p) for p in photos[:3]])
    a.autosave(), b.autosave()
    b.autosave()  # unchanged: not written again
    assert len(load_project(a.recovery_file).expression("neutral").photos) == 1
    assert len(load_project(b.recovery_file).expression("neutral").photos) == 3

    # a third studio starting now offers nothing: both files belong to running instances
    c = window()
    assert not c.offer_recovery() and messages == [] and c.model.photos == []
    # b saves its project: its recovery file goes, a's stays
    assert b.save_to(tmp_path / "b.facestudio.json")
    assert not b.recovery_file.exists() and a.recovery_file.is_file()

    # an instance crashed with a's project in its recovery file: its lock names a dead process
    dead = folder / "untitled-1-deadbeef.recovery.facestudio.json"
    shutil.copy(a.recovery_file, dead)
    _crashed_instance_lock(dead)
    d = window()
    messages.answers["question"] = QMessageBox.StandardButton.Yes
    assert d.offer_recovery()
    assert len(messages) == 1 and messages[0][1] == "Recover unsaved project" and str(dead) in messages[0][2]
    np.testing.assert_allclose(d.model.photos[0].points["nose_tip"], (500.0, 520.0))
    assert d.model.path is None and d.model.modified
    # d adopted the file (and holds its lock): a later start does not offer it while d runs
    assert d.recovery_file == dead
    assert not window().offer_recovery() and len(messages) == 1
    d.model.set_point("neutral", d.model.photos[0].id, "nose_tip", (510.0, 520.0))
    d.autosave()
    assert load_project(dead).expression("neutral").photos[0].points["nose_tip"][0] == 510.0
    np.testing.assert_allclose(
        load_project(a.recovery_file).expression("neutral").photos[0].points["nose_tip"], (500.0, 520.0)
    )  # a's own file untouched
    # closing a (its project discarded) removes its file and lock only
    messages.answers["question"] = QMessageBox.StandardButton.Discard
    assert a.close()
    assert not a.recovery_file.exists() and not Path(str(a.recovery_file) + ".lock").exists()
    assert dead.is_file() and Path(str(dead) + ".lock").is_file()
    d.model.modified = False


def test_fit_can_be_cancelled(qtbot, studio_window, project_copy):
    assert studio_window.open_project(project_copy)
    assert studio_window.run_fit()
    studio_window.fits.cancel()  # what the progress dialog's Cancel button does
    qtbot.waitUntil(lambda: not studio_window.fits.busy, timeout=60_000)
    assert studio_window.model.fit() is None and studio_window.fit_label.text() == "fit cancelled"
    assert studio_window.fit_progress is None


def test_3d_view_picks_a_feature(qtbot, studio_window, project_copy):
    assert studio_window.open_project(project_copy)
    v3 = studio_window.view3d
    qtbot.waitUntil(lambda: v3.isVisible())
    v3.view_from(0.0, 0.0)
    v3.render_image()
    assert v3.last_render_s is not None
    vertex = studio_window.model.mesh.features["nose_tip"]
    cam = v3.camera(v3.width(), v3.height())
    u, v = cam.project(studio_window.model.mesh.vertices[[vertex]])[0]
    qtbot.mouseClick(v3, Qt.MouseButton.LeftButton, pos=QPoint(int(round(u)), int(round(v))))
    assert studio_window.model.active_feature == "nose_tip"


def test_studio_command_opens_the_project(qtbot, qapp, project_copy, messages, studio_run_loop):
    """``facestudio studio PROJECT`` (also ``python -m app PROJECT``) opens a window on the project."""

    from PySide6.QtWidgets import QApplication

    seen = {}

    def inspect_and_close():
        for w in QApplication.topLevelWidgets():
            if isinstance(w, MainWindow) and w.isVisible():
                seen["path"] = w.model.path
                seen["photos"] = [p.id for p in w.model.photos]
                w.close()

    studio_run_loop(inspect_and_close)
    assert main(["studio", str(project_copy)]) == 0
    assert seen["path"] == project_copy.absolute() and len(seen["photos"]) == 5


def test_camera_group_field_is_an_undoable_photo_edit(qtbot, studio_window, project_copy):
    """The toolbar's Camera group field names the current photo's camera (Photo.camera_group):
    Enter applies it, switching photos applies what was typed to the photo it was typed for,
    each change is one undo step, and it is saved with the project."""
    assert studio_window.open_project(project_copy)
    model, edit, undo = studio_window.model, studio_window.camera_group_edit, studio_window.undo_stack
    view = studio_window.show_photo("front")
    qtbot.waitUntil(lambda: view.isVisible())
    assert edit.isEnabled() and edit.text() == ""
    qtbot.keyClicks(edit, "  video ")
    qtbot.keyClick(edit, Qt.Key.Key_Return)
    assert model.photo("front").camera_group == "video" and edit.text() == "video"
    assert undo.undo_text == "Set camera group of front to video"
    # typed for 'left', then the tab changes before Enter: it still goes to 'left'
    studio_window.show_photo("left")
    assert edit.text() == ""
    qtbot.keyClicks(edit, "video")
    studio_window.show_photo("front")
    qtbot.waitUntil(lambda: model.photo("left").camera_group == "video")  # once the tab change is done
    assert edit.text() == "video" and undo.undo_text == "Set camera group of left to video"
    assert model.project.camera_groups("neutral") == [0, 1, 2, 3, 2]  # right, ¾ right, front, ¾ left, left
    # emptying the field clears the group
    studio_window.show_photo("left")
    edit.selectAll()
    qtbot.keyClick(edit, Qt.Key.Key_Delete)
    qtbot.keyClick(edit, Qt.Key.Key_Return)
    assert model.photo("left").camera_group is None
    undo.undo()
    assert model.photo("left").camera_group == "video" and edit.text() == "video"
    undo.undo()
    assert model.photo("left").camera_group is None and edit.text() == ""
    undo.redo()
    assert studio_window.save()
    reopened = load_project(project_copy)
    assert [p.camera_group for p in reopened.expression("neutral").photos] == [None, None, "video", None, "video"]
