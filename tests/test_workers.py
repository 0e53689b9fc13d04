"""Fits off the GUI thread (app.qt.workers): the overlay of the photo on screen is computed by the fit's
worker and travels with its result, so the GUI thread only paints it, and a dropped result drops
its overlay too (pytest-qt, offscreen)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

import app.studio.fitting  # noqa: E402
from app.qt.workers import FitController  # noqa: E402
from app.studio.commands import SetPointCommand  # noqa: E402
from app.studio_state import StudioModel  # noqa: E402
from photomodel.modeling import wireframe as overlay_module  # noqa: E402


@pytest.fixture
def overlay_threads(monkeypatch):
    """The thread of every :func:`photomodel.modeling.wireframe.photo_overlay` call, in order."""
    calls = []
    original = overlay_module.photo_overlay

    def recorded(*args, **kwargs):
        calls.append(threading.get_ident())
        return original(*args, **kwargs)

    monkeypatch.setattr(app.studio.fitting, "photo_overlay", recorded)  # where the studio's fitting looks it up
    return calls


def _same_overlay(a, b):
    # the same inputs through the same code on two threads (two GL contexts of one driver): the
    # depth maps are identical, so the segments are too, bit for bit up to float rounding
    np.testing.assert_allclose(a.segments, b.segments, atol=1e-9)
    np.testing.assert_array_equal(a.kind, b.kind)


def test_refit_computes_the_on_screen_overlay_in_the_worker(qtbot, project_copy, overlay_threads):
    model = StudioModel()
    model.open(project_copy)
    fits = FitController(model)
    fits.overlay_photos = lambda expression: ["front", "no_such_photo"]
    with qtbot.waitSignal(fits.finished, timeout=60_000):
        assert fits.start("neutral") is not None
    fit = model.fit()
    assert set(fit.overlays) == {"front"}  # a photo without a camera is skipped
    assert overlay_threads and threading.main_thread().ident not in overlay_threads
    worker = fit.overlays["front"]
    assert len(worker.segments) > 1000 and worker.note is None

    # the GUI thread takes it from the cache; another photo is computed on demand, once
    assert model.overlay("front") is worker
    n = len(overlay_threads)
    left = model.overlay("left")
    assert left is not None and model.overlay("left") is left and len(overlay_threads) == n + 1
    assert overlay_threads[-1] == threading.main_thread().ident
    fresh = overlay_module.photo_overlay(fit.cameras["front"], fit.vertices, model.mesh.faces, model.overlay_lines)
    _same_overlay(worker, fresh)
    fits.shutdown()


def test_an_edit_during_a_refit_ends_with_the_newest_overlay(qtbot, project_copy, overlay_threads):
    """The result of an older edit is applied with its own overlay, then replaced by the refit of
    the newest edit with *its* overlay; a result for a replaced project is dropped with its overlay."""
    model = StudioModel()
    model.open(project_copy)
    fits = FitController(model)
    fits.overlay_photos = lambda expression: ["front"]
    with qtbot.waitSignal(fits.finished, timeout=60_000):
        fits.start("neutral")
    stack = model.undo_stack
    applied = []
    fits.finished.connect(lambda expression, seconds: applied.append(model.fit()))
    uv = model.photo("front").points["jaw_05"]
    stack.push(SetPointCommand(model, "neutral", "front", "jaw_05", uv + 3.0))
    fits.schedule_refit()
    qtbot.waitUntil(lambda: fits.busy, timeout=10_000)
    stack.push(SetPointCommand(model, "neutral", "front", "jaw_05", uv - 3.0))  # while it refits
    fits.schedule_refit()
    qtbot.waitUntil(
        lambda: not fits.busy and fits._pending_expression is None and not fits._timer.isActive(), timeout=60_000
    )
    fit = model.fit()
    assert len(applied) == 2 and applied[-1] is fit  # the older edit's refit, then the newest's
    assert applied[0].overlays["front"] is not fit.overlays["front"]
    # the overlay on screen is the newest fit's: the same lines as computed now from its mesh
    fresh = overlay_module.photo_overlay(fit.cameras["front"], fit.vertices, model.mesh.faces, model.overlay_lines)
    _same_overlay(fit.overlays["front"], fresh)

    # a refit whose project is replaced meanwhile: dropped, and its overlay with it
    stack.push(SetPointCommand(model, "neutral", "front", "jaw_05", uv))
    fits.start("neutral", warm=True)
    model.open(project_copy)  # cancels the running refit; its result would be for the old project
    fits.wait(60.0)
    qtbot.wait(50)  # deliver the queued signals
    assert not fits.busy and model.fit() is None  # the copy has no stored results
    fits.shutdown()


def test_window_paints_the_refit_overlay_without_computing_it(qtbot, studio_window, project_copy, overlay_threads):
    w = studio_window
    assert w.open_project(project_copy)
    view = w.show_photo("front")
    qtbot.waitUntil(lambda: view.isVisible())
    assert w.run_fit()
    qtbot.waitUntil(lambda: not w.fits.busy and w.model.fit() is not None, timeout=60_000)
    assert view.overlay_from_cache and view.overlay_item.count > 1000
    main = threading.main_thread().ident
    assert main not in overlay_threads

    # an auto-refit after a moved click: again computed in the worker, only painted here
    w.fits.last_warm_s = None
    old = w.model.fit()
    uv = w.model.photo("front").points["chin"] + 2.0
    w.undo_stack.push(SetPointCommand(w.model, "neutral", "front", "chin", uv))
    qtbot.waitUntil(lambda: w.model.fit() is not old and not w.fits.busy, timeout=60_000)
    assert main not in overlay_threads and view.overlay_from_cache
    assert view.overlay_item.count == len(w.model.fit().overlays["front"].segments)

    # another tab, not on screen during the fit: computed once when shown
    other = w.show_photo("left")
    qtbot.waitUntil(lambda: other.isVisible())
    assert overlay_threads[-1] == main and not other.overlay_from_cache and other.overlay_item.count > 500
    w.model.modified = False


def test_overlay_lines_paint_as_one_line_per_segment(qtbot):
    """The overlay's lines, drawn as one path per kind (built from a numpy buffer), are the pixels
    of drawing one QLineF per segment with the same cosmetic pens."""
    from PySide6.QtCore import QLineF, QRectF
    from PySide6.QtGui import QImage, QPainter, QPen, QTransform

    from app.qt.photo_items import OVERLAY_COLORS, LinesItem

    rng = np.random.default_rng(1)
    uv = rng.uniform(0, 200, (600, 2, 2))
    kinds = rng.integers(0, 3, 600).astype(np.uint8)
    item = LinesItem(QRectF(0, 0, 200, 200))
    item.set_lines(uv, kinds)
    assert item.count == 600

    def image(draw):
        img = QImage(250, 250, QImage.Format.Format_ARGB32_Premultiplied)
        img.fill(0)
        p = QPainter(img)
        p.setTransform(QTransform(1.1, 0, 0, 1.1, 3.3, 4.4))
        draw(p)
        p.end()
        return np.frombuffer(img.constBits(), np.uint8).reshape(250, 250, 4).copy()

    def one_per_segment(p):
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        for k in np.unique(kinds):
            pen = QPen(OVERLAY_COLORS[int(k)], 1.6 if k else 1.0)
            pen.setCosmetic(True)
            p.setPen(pen)
            p.drawLines([QLineF(*row) for row in uv[kinds == k].reshape(-1, 4).tolist()])

    drawn = image(lambda p: item.paint(p, None))
    assert drawn.any()
    np.testing.assert_array_equal(drawn, image(one_per_segment))
    item.clear()
    assert item.count == 0 and not image(lambda p: item.paint(p, None)).any()
