"""The *Edit* tab of the studio's tracking view (pytest-qt, offscreen; app/qt/edit_panel.py, issue 16).

The tracked results are the session's ``straight`` run (6 frames of the sample video, conftest),
copied so that the export's ``edits.json`` does not change it.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")


from app.qt.tracking_view import TrackingView  # noqa: E402
from app.studio_state import StudioModel  # noqa: E402
from tracking.edit import load_edits  # noqa: E402
from tracking.track_result import load_track_results, state_of  # noqa: E402

SHOT = Path(__file__).resolve().parents[1] / "docs" / "img" / "edit_view.png"


@pytest.fixture
def view(qtbot, tmp_path, errors, straight):
    out = tmp_path / "track"
    shutil.copytree(straight.out_dir, out)
    v = TrackingView(StudioModel())
    qtbot.addWidget(v)
    v.resize(1300, 760)
    v.show()
    qtbot.waitExposed(v)
    assert v.load_results(out), errors
    yield v
    v.edit_panel.jobs.shutdown()
    v.jobs.shutdown()


def test_scale_undo_scrub_export(qtbot, view, errors, tmp_path):
    panel = view.edit_panel
    view.plot_tabs.setCurrentWidget(panel)  # builds the session, draws the curve and frame 0
    assert panel.session is not None and not errors, errors
    n = view.frame_count
    assert n == 6
    panel.region_box.setCurrentText("mouth")
    panel.expression_box.setCurrentText("smile")
    # the tracked smile of the mouth, straight from the stored track
    stored = np.array([r["weights"]["mouth"]["smile"] for r in load_track_results(view.out_dir)["frames"]])
    before, after = panel.curve()
    np.testing.assert_allclose(before, stored, atol=1e-9)
    np.testing.assert_allclose(after, before, atol=1e-12)

    # a drag across the curve picks the span; the factor box scales it (no ramp: exactly f × w)
    plot = panel.plot
    y = plot.height() // 2
    from PySide6.QtCore import QPoint, Qt

    qtbot.mousePress(plot, Qt.MouseButton.LeftButton, pos=QPoint(round(plot.to_x(2)), y))
    qtbot.mouseMove(plot, QPoint(round(plot.to_x(5)), y))
    qtbot.mouseRelease(plot, Qt.MouseButton.LeftButton, pos=QPoint(round(plot.to_x(5)), y))
    assert panel.span == (2, 5)
    panel.ramp_box.setValue(0)
    panel.factor_box.setValue(1.5)
    qtbot.mouseClick(panel.scale_button, Qt.MouseButton.LeftButton)
    assert not errors, errors
    _, after = panel.curve()
    np.testing.assert_allclose(after[2:], 1.5 * stored[2:], atol=1e-6)
    np.testing.assert_allclose(after[:2], stored[:2], atol=1e-9)
    np.testing.assert_allclose(plot.edited, after)  # what is drawn

    # scrub to an edited frame: edited beside the original, different inside the face only
    panel.set_frame(4)
    original, edited = panel.original, panel.edited
    np.testing.assert_array_equal(original, view.review.footage_frame(4))
    diff = np.abs(edited - original).max(axis=2)
    assert diff.max() > 0.02
    fitter = panel.session.fitter
    st = state_of(view.review.records[4])
    model = fitter.model
    uv = fitter.camera(st).project(model.blend_geometry(model.vertex_weights(model.region_weights(st.alpha))))
    import cv2

    face = np.zeros(diff.shape, np.uint8)
    cv2.fillConvexPoly(face, cv2.convexHull(np.round(uv).astype(np.int32)), 1)
    near = cv2.dilate(face, np.ones((31, 31), np.uint8)).astype(bool)  # the flow fades out over 12 px
    assert (diff[~near] == 0).all()
    assert (diff[face.astype(bool)] > 0.01).sum() > 50
    panel.set_frame(0)
    np.testing.assert_array_equal(panel.edited, panel.original)  # outside the span: the footage itself
    panel.set_frame(4)

    if os.environ.get("FACESTUDIO_SCREENSHOTS"):  # docs/img/edit_view.png on request (not in a plain run)
        SHOT.parent.mkdir(parents=True, exist_ok=True)
        view.grab().save(str(SHOT))

    # undo restores the tracked curve, redo brings the edit back
    assert panel.undo_button.isEnabled()
    qtbot.mouseClick(panel.undo_button, Qt.MouseButton.LeftButton)
    np.testing.assert_allclose(panel.curve()[1], stored, atol=1e-9)
    np.testing.assert_array_equal(panel.edited, panel.original)
    assert panel.redo()
    np.testing.assert_allclose(panel.curve()[1][2:], 1.5 * stored[2:], atol=1e-6)

    # replace, then export in the worker
    assert panel.apply_replace(1)
    assert [e["op"] for e in panel.session.edits] == ["scale", "replace"]
    assert not panel.apply_replace(99) or panel.frame_box.value() == 5  # clamped by the spin box
    out = tmp_path / "frames"
    assert panel.export(out)
    qtbot.waitUntil(lambda: not panel.jobs.busy, timeout=120_000)
    assert not errors, errors
    assert "exported" in panel.last_message
    assert len(list(out.glob("frame_*.png"))) == n
    assert [e["op"] for e in load_edits(view.out_dir)["edits"]][:2] == ["scale", "replace"]
