"""The studio keeps going whatever the artist does (pytest-qt, offscreen): regression tests of issue 14.

New or open while a photo tab other than the first is showing, a file nested thousands deep,
an error nobody expected (shown in a non-modal box, kept for tests), the status bar after
tracking, and redo on both of its usual keys. pytest-qt fails a test on any exception raised in
a Qt virtual or slot, so "no exception" is checked by every test here.
"""

from __future__ import annotations

import json
import sys

import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import Qt  # noqa: E402
from PySide6.QtGui import QKeySequence  # noqa: E402
from PySide6.QtWidgets import QFileDialog  # noqa: E402

from app.qt.photo_view import PhotoView  # noqa: E402
from photomodel.project.codec import project_from_dict, project_to_dict  # noqa: E402


def photo_tabs(window) -> list[str]:
    tabs = window.tabs
    return [tabs.widget(i).photo_id for i in range(tabs.count()) if isinstance(tabs.widget(i), PhotoView)]


def two_photo_project(project_copy):
    """Another project beside the sample: its neutral expression has only two photos, named
    differently, so that no photo id of the sample's tabs exists in it."""
    doc = json.loads(project_copy.read_text())
    doc["expressions"] = doc["expressions"][:1]
    photos = doc["expressions"][0]["photos"]
    keep = [p for p in photos if p["id"] in ("front", "left")]
    for p in keep:
        p["id"] = "other_" + p["id"]
    doc["expressions"][0]["photos"] = keep
    doc["expressions"][0].pop("result", None)
    doc["name"] = "other"
    other = project_copy.parent / "other.facestudio.json"
    other.write_text(json.dumps(doc))
    return other


def test_new_and_open_while_another_photo_tab_shows(qtbot, studio_window, project_copy, messages):
    w = studio_window
    assert w.open_project(project_copy)
    view = w.show_photo("three_quarter_right")
    qtbot.waitUntil(view.isVisible)
    # File → New: was a ProjectError in resizeEvent, a SystemError, then a segmentation fault
    w.act_new.trigger()
    assert w.model.project.name == "untitled" and photo_tabs(w) == [] and w.tabs.count() == 1
    assert not messages

    # open the sample, show its fourth tab, open another project whose photos are others
    assert w.open_project(project_copy)
    w.show_photo("three_quarter_left")
    other = two_photo_project(project_copy)
    assert w.open_project(other)
    assert w.model.project.name == "other" and photo_tabs(w) == ["other_front", "other_left"]
    assert not messages

    # a failed open with another tab showing keeps the project open, with all its tabs
    w.show_photo("other_left")
    bad = project_copy.parent / "bad.facestudio.json"
    bad.write_text("{ not json")
    assert not w.open_project(bad)
    assert messages[-1][0] == "critical" and "bad.facestudio.json" in messages[-1][2]
    assert w.model.project.name == "other" and photo_tabs(w) == ["other_front", "other_left"]
    assert w.current_view().photo_id == "other_left"

    # undoing the removal of the photo on screen, and redoing it, rebuild the tabs cleanly
    w.remove_current_photo()
    assert photo_tabs(w) == ["other_front"]
    w.undo_stack.undo()
    assert photo_tabs(w) == ["other_front", "other_left"]


def test_open_of_a_file_nested_thousands_deep_keeps_the_project(
    qtbot, studio_window, project_copy, messages, monkeypatch
):
    w = studio_window
    assert w.open_project(project_copy)
    w.show_photo("left")
    project = w.model.project
    deep = project_copy.parent / "deep.facestudio.json"
    deep.write_text('{"format_version": 3, "name": ' + "[" * 100_000 + "]" * 100_000 + "}")
    assert not w.open_project(deep)  # the loader's error, or a RecursionError it lets through
    kind, title, text = messages[-1]
    assert kind == "critical" and "deep.facestudio.json" in text and "Traceback" not in text
    assert w.model.project is project and len(photo_tabs(w)) == 5 and w.current_view().photo_id == "left"

    # anything else unexpected while opening: a box naming it, the project kept
    def broken(*args, **kwargs):
        raise RuntimeError("the disk said no")

    monkeypatch.setattr(w.model, "open", broken)
    assert not w.open_project(project_copy)
    assert "RuntimeError: the disk said no" in messages[-1][2] and "previous project" in messages[-1][2]
    assert w.model.project is project and len(photo_tabs(w)) == 5


def test_unexpected_errors_show_in_a_non_modal_box_and_are_kept(qtbot, studio_window, capsys):
    w = studio_window
    for n, message in enumerate(("first", "second")):
        with qtbot.waitSignal(w.unexpected_error) as signal:
            try:
                raise ValueError(message)
            except ValueError:
                w.report_unexpected(*sys.exc_info())  # what sys.excepthook gets (run_studio installs it)
        assert signal.args == [f"ValueError: {message}"]
        box = w.error_box
        assert box.isVisible() and not box.isModal() and box.windowModality() == Qt.WindowModality.NonModal
        assert f"ValueError: {message}" in box.text() and ("earlier" in box.text()) == (n == 1)
    assert w.unexpected_errors == ["ValueError: first", "ValueError: second"]
    assert "Traceback" in box.detailedText() and "Traceback" in capsys.readouterr().err
    box.close()


def test_redo_answers_ctrl_y_and_ctrl_shift_z(qtbot, studio_window, project_copy):
    w = studio_window
    keys = [k.toString() for k in w.act_redo.shortcuts()]
    assert "Ctrl+Y" in keys and "Ctrl+Shift+Z" in keys
    assert w.open_project(project_copy)
    view = w.show_photo("front")
    qtbot.waitUntil(view.isVisible)
    w.activateWindow()
    view.setFocus()
    model = w.model
    model.set_active_feature("chin")
    for shortcut in ("Ctrl+Shift+Z", "Ctrl+Y"):
        qtbot.keyClick(view, Qt.Key.Key_Delete)
        assert "chin" not in model.photo("front").points
        w.undo_stack.undo()
        assert "chin" in model.photo("front").points
        seq = QKeySequence(shortcut)[0]
        qtbot.keyClick(view, seq.key(), seq.keyboardModifiers())
        assert "chin" not in model.photo("front").points, shortcut
        w.undo_stack.undo()


def test_status_bar_says_how_tracking_ended(qtbot, studio_window, project_copy, messages, monkeypatch):
    w = studio_window
    assert w.open_project(project_copy)
    video = project_copy.parent / "video" / "james_track.mp4"
    monkeypatch.setattr(QFileDialog, "getOpenFileName", lambda *a, **k: (str(video), ""))
    w.tracking_view.limit_box.setValue(1)
    w.act_track_video.trigger()
    assert " into " in w.statusBar().currentMessage()
    qtbot.waitUntil(lambda: not w.tracking_view.jobs.busy, timeout=60_000)
    qtbot.waitUntil(lambda: " into " not in w.statusBar().currentMessage(), timeout=5_000)
    assert w.statusBar().currentMessage() == w.tracking_view.last_message != ""


def test_a_fit_of_photos_removed_meanwhile_is_not_stored(qtbot, studio_window, project_copy, messages):
    """Found by the monkey: a photo removed while its expression was being fitted left the fit's
    camera of that photo in the project, which then could not be saved."""
    w = studio_window
    assert w.open_project(project_copy)
    w.show_photo("right")
    assert w.run_fit()
    w.act_remove_photo.trigger()  # while the fit runs
    qtbot.waitUntil(lambda: not w.fits.busy, timeout=60_000)
    assert w.model.fit() is None and w.model.expression.result is None and w.fit_progress is None
    project_from_dict(project_to_dict(w.model.project, project_copy))  # still valid
    assert w.save() and not messages
    w.undo_stack.undo()  # the photo is back; a new fit is of all five
    assert w.run_fit()
    qtbot.waitUntil(lambda: not w.fits.busy, timeout=60_000)
    assert set(w.model.fit().cameras) == {p.id for p in w.model.photos}


def test_studio_command_on_a_bad_project_does_not_block_headless(
    qtbot, qapp, project_copy, monkeypatch, capsys, studio_run_loop
):
    """``QT_QPA_PLATFORM=offscreen facestudio studio deep.json``: the error is a non-modal box and a
    line on stderr (no modal box nobody could close); the window opens on an empty project."""
    from PySide6.QtWidgets import QApplication, QMessageBox

    from app.cli import main
    from app.qt.main_window import MainWindow

    monkeypatch.setattr(QMessageBox, "critical", lambda *a, **k: pytest.fail("a modal box in a headless run"))
    deep = project_copy.parent / "deep.facestudio.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    seen = {}

    def inspect_and_close():
        for w in QApplication.topLevelWidgets():
            if isinstance(w, MainWindow) and w.isVisible():
                boxes = [b for b in w.findChildren(QMessageBox) if b.isVisible()]
                seen["boxes"] = [(b.windowTitle(), b.text(), b.isModal()) for b in boxes]
                seen["photos"] = len(w.model.photos)
                for b in boxes:
                    b.close()
                w.close()

    studio_run_loop(inspect_and_close)
    assert main(["studio", str(deep)]) == 0
    assert seen["photos"] == 0 and len(seen["boxes"]) == 1
    title, text, modal = seen["boxes"][0]
    assert title == "Cannot open the project" and "deep.facestudio.json" in text and not modal
    assert "Cannot open the project" in capsys.readouterr().err
