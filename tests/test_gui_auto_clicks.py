"""Automatic clicks in the studio, driven as an artist: shown in their own colour, one dragged
(it becomes the artist's click), undo, refit (on the sample's clicks marked automatic)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import QPoint, QPointF, Qt  # noqa: E402


def widget_pos(view, uv) -> QPoint:
    return view.mapFromScene(QPointF(float(uv[0]), float(uv[1])))


def drag(qtbot, view, start: QPoint, end: QPoint) -> None:
    qtbot.mousePress(view.viewport(), Qt.MouseButton.LeftButton, pos=start)
    qtbot.mouseMove(view.viewport(), start + (end - start) / 2)
    qtbot.mouseMove(view.viewport(), end)
    qtbot.mouseRelease(view.viewport(), Qt.MouseButton.LeftButton, pos=end)


def test_auto_clicks_shown_dragged_undone_refit(qtbot, studio_window, project_copy, messages):
    assert studio_window.open_project(project_copy)
    studio_window.act_auto.setChecked(False)
    model = studio_window.model
    for p in model.photos:  # as the landmark detector leaves them: every click automatic
        for name, uv in list(p.points.items()):
            model.set_point("neutral", p.id, name, uv, source="auto", confidence=0.8)
    view = studio_window.show_photo("front")
    qtbot.waitUntil(lambda: view.isVisible())
    assert all(item.is_auto for item in view._items.values())
    assert "automatic click, confidence 0.80" in view._items["chin"].toolTip()

    # -- the artist drags the chin: it is theirs now; undo makes it automatic again
    before = model.photo("front").points["chin"].copy()
    start = widget_pos(view, before)
    drag(qtbot, view, start, start + QPoint(0, 12))
    assert model.click_source("neutral", "front", "chin") == ("user", None)
    assert not view._items["chin"].is_auto and view._items["nose_tip"].is_auto
    studio_window.undo_stack.undo()
    np.testing.assert_allclose(model.photo("front").points["chin"], before)
    assert model.click_source("neutral", "front", "chin") == ("auto", 0.8) and view._items["chin"].is_auto
    studio_window.undo_stack.redo()

    # -- refit: the dragged click is used like any other; the fit's chin is drawn as a ghost
    assert studio_window.run_fit()
    qtbot.waitUntil(lambda: not studio_window.fits.busy and model.fit() is not None, timeout=60_000)
    assert not messages, messages
    # views 45-90° apart: the most probable face under the person prior, and the panel says why
    # its RMS is the detector's; the profiles' automatic clicks are left out, each photo named
    panel = studio_window.panel
    assert "the most probable face" in panel.summary.text()
    lines = [panel.worst.item(i).text() for i in range(panel.worst.count())]
    assert {"⚠ left: left out of the fit (no camera)", "⚠ right: left out of the fit (no camera)"} <= set(lines)
    model.set_active_feature("chin")
    assert view.predicted_item.isVisible()


def test_a_neutral_fitted_to_smiles_says_so_in_the_fit_summary(qtbot, studio_window, project_copy, messages):
    # every photo's automatic mouth corners lifted a quarter of the eye distance (a smile, as the
    # detector would click it): the fit summary says the expression is not fitted and why
    assert studio_window.open_project(project_copy)
    studio_window.act_auto.setChecked(False)
    model = studio_window.model
    for p in model.photos:
        for name, uv in list(p.points.items()):
            model.set_point("neutral", p.id, name, uv, source="auto", confidence=0.8)
        if {"eye_r_outer", "eye_l_outer", "mouth_r", "mouth_l"} <= set(p.points):
            d = float(np.linalg.norm(p.points["eye_l_outer"] - p.points["eye_r_outer"]))
            for name in ("mouth_r", "mouth_l"):
                uv = p.points[name] - [0.0, 0.25 * d]
                model.set_point("neutral", p.id, name, uv, source="auto", confidence=0.8)
    assert studio_window.run_fit()
    qtbot.waitUntil(lambda: not studio_window.fits.busy and model.fit() is not None, timeout=60_000)
    assert not messages, messages
    text = studio_window.panel.summary.text()
    assert "expression not fitted: the mouth shows an expression in" in text and "not a neutral face" in text
    # on the photos whose mouth the fit can read (a three-quarter view's inner lips are not all
    # clicked in the sample), the lifted corners are the expression's, listed apart, no misclick
    shown = model.fit().report["expressive_photos"]
    assert "front" in shown
    lines = [studio_window.panel.worst.item(i).text() for i in range(studio_window.panel.worst.count())]
    assert lines[0].startswith("⚠ expression not fitted: ") and "front" in lines[0]  # first, where it is seen
    assert any(line.endswith("mouth_r  @ front  (the expression, not used)") for line in lines), lines
    assert not any(
        "mouth_" in line and "(suspect" in line and line.split("@ ")[1].split()[0] in shown for line in lines
    )
