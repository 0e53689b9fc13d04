"""The studio's *Tracking → Clone from another project…* (pytest-qt, offscreen), driven like an artist:
browse to project A, pick its tracking results and a method, clone (and cancel a clone), then scrub
A's frames | B rendered side by side; B's results open in the tracking view and A joins B's people.

Two small projects: B the fitted sample (the window's), A a copy of it in a sibling folder holding the
session's tracked run of the sample video (``straight``, 6 frames). A few seconds on the 2-core machine.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import Qt  # noqa: E402
from PySide6.QtWidgets import QFileDialog  # noqa: E402
from studio_window import close_studio, open_studio  # noqa: E402

from photomodel.project import load_project  # noqa: E402
from tracking.blendshape_face import CONTROL_REGIONS  # noqa: E402
from tracking.track_result import load_track_results  # noqa: E402


@pytest.fixture
def window(qtbot, tmp_path, errors, fitted_project_copy):
    w = open_studio(qtbot, tmp_path, fitted_project_copy)
    yield w
    dlg = w.tracking_menu.clone_dialog_widget
    if dlg is not None:
        dlg.jobs.shutdown()
    close_studio(w)


@pytest.fixture
def alice(tmp_path, fitted_sample, straight):
    """Project A: the fitted sample in ``alice/alice.facestudio.json`` with a tracked performance in
    ``results/track_james_track`` (a copy of the session's tracked run)."""
    folder = tmp_path / "alice"
    shutil.copytree(fitted_sample.parent, folder)
    (folder / fitted_sample.name).rename(folder / "alice.facestudio.json")
    shutil.copytree(straight.out_dir, folder / "results" / "track_james_track")
    return folder / "alice.facestudio.json"


def test_clone_from_another_project_side_by_side(qtbot, window, errors, alice, fitted_project_copy, monkeypatch):
    monkeypatch.setattr(QFileDialog, "getOpenFileName", lambda *a, **k: (str(alice), ""))
    dlg = window.tracking_menu.clone_dialog(modal=False)
    qtbot.waitExposed(dlg)
    assert not dlg.clone_button.isEnabled()  # nothing chosen yet
    qtbot.mouseClick(dlg.browse_button, Qt.MouseButton.LeftButton)
    assert dlg.source == alice
    assert [dlg.track_combo.itemText(i) for i in range(dlg.track_combo.count())] == ["track_james_track"]
    assert dlg.clone_button.isEnabled()
    dlg.method_combo.setCurrentText("displacement")
    out = fitted_project_copy.parent / "results" / "track_james_track_from_alice"

    # a clone cancelled at once writes nothing
    assert dlg.start()
    dlg.jobs.cancel()
    qtbot.waitUntil(lambda: not dlg.jobs.busy, timeout=30_000)
    assert "cancelled" in dlg.last_message and not out.exists() and dlg.result is None

    qtbot.mouseClick(dlg.clone_button, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: not dlg.jobs.busy, timeout=60_000)
    assert not errors, errors
    assert dlg.result is not None and dlg.result.out_dir == out
    doc = load_track_results(out)
    assert doc["cloned_from"]["method"] == "displacement" and doc["project"] == str(fitted_project_copy)
    # the same face on both sides: the displacement copy gives A's weights back (least squares of an exact blend)
    a = load_track_results(alice.parent / "results" / "track_james_track")
    assert len(doc["frames"]) == len(a["frames"]) == 6
    for ra, rb in zip(a["frames"], doc["frames"], strict=True):
        for region in CONTROL_REGIONS[1:]:
            got = np.array(list(rb["weights"][region].values()))
            want = np.array([ra["weights"][region][n] for n in rb["weights"][region]])
            np.testing.assert_allclose(got, want, atol=1e-4)
    # B's results open in the tracking view, as its own would
    view = window.tracking_view
    assert window.tracking_dock.isVisible() and view.out_dir == out and view.frame_count == 6
    # A joins B's people (the project is modified until saved)
    assert window.model.project.people == ["../alice/alice.facestudio.json"] and window.model.modified

    # side by side: A's frame | B rendered at its pose and expression, on black
    h, w = doc["video"]["height"], doc["video"]["width"]
    first = dlg.image.copy()
    assert first.shape == (h, 2 * w, 3)
    np.testing.assert_allclose(first[:, :w], view.review.footage_frame(0), atol=1e-6)
    right = first[:, w:]
    face = right.max(axis=2) > 0.02
    assert 0.05 < face.mean() < 0.9, face.mean()  # the face drawn, the background black
    assert right[0, 0].max() == 0.0
    dlg.grab().save("/tmp/clone_dialog.png")

    # scrubbing: the slider (or ←/→) moves both halves, and the tracking view follows
    dlg.slider.setValue(5)
    assert view.current_frame == 5 and dlg.index_label.text() == "frame 5 / 5"
    assert np.abs(dlg.image - first).mean() > 1e-3
    dlg.setFocus()
    qtbot.keyClick(dlg, Qt.Key.Key_Left)
    assert dlg.slider.value() == 4 and view.current_frame == 4

    # saved, B refers to A in its file
    assert window.save()
    assert load_project(fitted_project_copy).people == ["../alice/alice.facestudio.json"]
    dlg.close()


def test_clone_needs_a_saved_project(qtbot, window, errors):
    window.model.new("unsaved")
    assert window.tracking_menu.clone_dialog(modal=False) is None
    assert errors and "save the project first" in errors[-1][1]
