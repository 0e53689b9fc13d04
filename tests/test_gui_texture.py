"""The studio's texture action, weight maps, expressions side by side and recovery autosave (pytest-qt, offscreen).

Driven as an artist would: open a copy of the sample project, fit, *Texture → Extract texture*
(a 256² texture, set through the ``texture/size`` setting, keeps this file fast), look at the
model cylindrical / view-dependent, cancel an extraction, add an expression with its photos and
fit it, compare the expressions side by side, and get a never-saved project back after a "crash";
reopen a textured project (a copy of the ``fitted_sample`` project, 1024² textures) and see its
textures at once, or a message naming a damaged texture file.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import QSettings  # noqa: E402
from PySide6.QtWidgets import QInputDialog, QMessageBox  # noqa: E402

from app.qt.main_window import MainWindow  # noqa: E402
from photomodel.project import load_project  # noqa: E402

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"


@pytest.fixture
def messages(monkeypatch):
    """Every message box shown, as (kind, title, text); questions answer ``answers['question']``."""
    shown = []
    answers = {"question": QMessageBox.StandardButton.No}

    def fake(kind):
        def box(parent, title, text, *args, **kwargs):
            shown.append((kind, title, text))
            return answers.get(kind, QMessageBox.StandardButton.Ok)

        return box

    for kind in ("critical", "warning", "information", "question"):
        monkeypatch.setattr(QMessageBox, kind, fake(kind))
    shown_answers = shown, answers
    return shown_answers


def make_window(qtbot, tmp_path, name="w"):
    w = MainWindow(
        settings=QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat),
        autosave_interval_ms=0,
        recovery_file=tmp_path / "data" / "untitled.recovery.facestudio.json",
    )
    qtbot.addWidget(w)
    w.resize(1300, 850)
    w.texture_size = 256
    return w


@pytest.fixture
def window(qtbot, tmp_path, messages):
    w = make_window(qtbot, tmp_path)
    w.show()
    qtbot.waitExposed(w)
    yield w
    w.fits.shutdown()
    w.jobs.shutdown()
    w.model.modified = False  # no unsaved-changes prompt when the test ends


def fit_now(qtbot, window):
    window.act_auto.setChecked(False)
    before = window.model.fit()
    assert window.run_fit()
    qtbot.waitUntil(lambda: not window.fits.busy, timeout=60_000)
    assert window.model.fit() is not None and window.model.fit() is not before, window.fit_label.text()


def qimage_rgb(img) -> np.ndarray:
    """(H, W, 3) uint8 of a QImage."""
    img = img.convertToFormat(img.Format.Format_RGB888)
    w, h = img.width(), img.height()
    return np.frombuffer(img.constBits(), np.uint8).reshape(h, img.bytesPerLine())[:, : 3 * w].reshape(h, w, 3)


def head_pixels(window, w=240, h=240):
    """RGB (n, 3) of the pixels the head covers in a 3D-view render (the background is uniform)."""
    a = qimage_rgb(window.view3d.render_image(w, h))
    bg = a[0, 0]
    return a[np.any(a != bg, axis=2)].astype(float)


def test_texture_action_shows_textures_and_weight_maps(qtbot, window, project_copy, messages):
    shown, _ = messages
    assert window.open_project(project_copy)
    assert not window.run_texture()  # not fitted yet: the dialog says why
    assert shown[-1][0] == "critical" and "not fitted" in shown[-1][2]
    fit_now(qtbot, window)
    grey = head_pixels(window)
    # an untextured head is grey Lambert shading: its channels are equal
    assert np.abs(grey[:, 0] - grey[:, 2]).mean() < 2.0

    assert window.run_texture()
    assert window.texture_progress is not None
    qtbot.waitUntil(lambda: not window.jobs.busy and window.model.texture() is not None, timeout=60_000)
    tex = window.model.texture()
    assert tex.job.size == 256 and tex.job.texture.image.shape == (256, 256, 3)
    assert window.texture_progress is None
    # the weight-map panel shows one image per photo
    assert window.weights_panel.image_count() == len(window.model.photos) == 5
    shown_ids = [window.weights_panel.maps.item(i).text() for i in range(5)]
    assert shown_ids == [p.id for p in window.model.photos]
    # cylindrical: the head shows skin colours (red above blue), not grey
    assert window.view3d.texture is not None and window.view3d.view_dependent is None
    cyl = head_pixels(window)
    assert (cyl[:, 0] - cyl[:, 2]).mean() > 20.0
    # view-dependent for the 3D view's camera, then untextured again
    window.set_texture_mode("view_dependent")
    assert window.view3d.view_dependent is not None and window.view3d.texture is None
    vd = head_pixels(window)
    assert (vd[:, 0] - vd[:, 2]).mean() > 20.0
    assert "view-dependent" in window.view3d.vertices()[1]
    # what the view shows is the registered fragment-shader frame (ViewDependentTexture.render's
    # default), not a plain-blend stand-in
    from app.qt.view3d import BACKGROUND

    v3 = window.view3d
    # the pairs an orbit selects are registered ahead, off the GUI thread
    qtbot.waitUntil(lambda: v3.registration_thread is not None, timeout=20000)
    v3.registration_thread.join(timeout=60)
    assert set(v3.view_dependent.orbit_pairs()) <= set(v3.view_dependent._shifts)
    shown_rgb = qimage_rgb(v3.render_image(200, 160))
    frame = v3.view_dependent.render(v3.camera(200, 160), background=BACKGROUND)
    np.testing.assert_array_equal(shown_rgb, (np.clip(frame.color, 0, 1) * 255 + 0.5).astype(np.uint8))
    window.set_texture_mode("untextured")
    assert window.view3d.texture is None and window.view3d.view_dependent is None
    window.act_tex_modes["cylindrical"].trigger()
    assert window.texture_mode == "cylindrical" and window.view3d.texture is not None

    # stored with the project like `facestudio texture`: PNGs, exports and the texture record
    assert window.save()
    stored = load_project(project_copy).expression("neutral").result.texture
    assert stored.size == 256 and set(stored.weight_maps) == {p.id for p in window.model.photos}
    for rel in [stored.image, *stored.weight_maps.values(), *stored.exports.values()]:
        assert (project_copy.parent / rel).is_file(), rel
    assert not shown[1:], shown

    # a new fit drops the texture (it belongs to the previous mesh)
    fit_now(qtbot, window)
    qtbot.waitUntil(lambda: window.model.texture() is None, timeout=60_000)
    assert window.view3d.texture is None and window.weights_panel.image_count() == 0


def test_texture_can_be_cancelled(qtbot, window, project_copy, messages):
    assert window.open_project(project_copy)
    fit_now(qtbot, window)
    assert window.run_texture()
    window.jobs.cancel()  # what the progress dialog's Cancel button does
    qtbot.waitUntil(lambda: not window.jobs.busy, timeout=60_000)
    assert window.model.texture() is None and window.texture_progress is None
    assert window.weights_panel.image_count() == 0 and window.view3d.texture is None
    assert not window.model.project.expression("neutral").result.texture


def test_add_expression_fit_it_and_see_expressions_side_by_side(qtbot, window, project_copy, messages, monkeypatch):
    shown, _ = messages
    assert window.open_project(project_copy)
    model = window.model
    fit_now(qtbot, window)
    neutral = {p.preset: p for p in model.photos}

    # Expression → New expression…, then its photos, then its clicks (here: the neutral ones)
    monkeypatch.setattr(QInputDialog, "getText", lambda *a, **k: ("again", True))
    asked = []

    def same_rig(parent, title, label, items, *a, **k):  # "Photographed with:" → the neutral's cameras
        asked.append(items)
        return items[0], True

    monkeypatch.setattr(QInputDialog, "getItem", same_rig)
    window.new_expression_dialog()
    assert model.expression_name == "again" and window.views == {}
    assert "'neutral'" in asked[0][0] and model.project.expression("again").cameras_from == "neutral"
    files = [str(project_copy.parent / "photos" / f"neutral_{p}.png") for p in neutral]
    assert window.add_photos(files) == 5
    for photo in model.photos:
        src = neutral[photo.preset]
        for name, uv in src.points.items():
            model.set_point("again", photo.id, name, uv)
        for name, line in src.curves.items():
            model.set_curve("again", photo.id, name, line)
    fit_now(qtbot, window)
    assert model.fit("again").report["rms_px"] < 2.0
    assert model.fit("again").report["cameras_from"] == "neutral"  # fitted with the rig's cameras

    window.act_side_by_side.trigger()
    view = window.expressions_view
    qtbot.waitUntil(lambda: view.isVisible())
    # one tile per expression: the sample's five (only the neutral fitted here) and the new one
    names = ["neutral", "smile", "open_mouth", "brows_raised", "frown", "again"]
    assert [t.name for t in view.tiles] == names
    fitted = [view.tiles[0], view.tiles[-1]]
    for tile in fitted:
        assert "RMS" in tile.label.text() and tile.image.pixmap() is not None
        assert not tile.image.pixmap().isNull()
    assert "not fitted" in view.tiles[1].label.text()
    # same clicks, same photos: the two meshes render alike from the shared camera
    a, b = (qimage_rgb(t.image.pixmap().toImage()).astype(float) for t in fitted)
    assert a.shape == b.shape and np.abs(a - b).mean() < 3.0  # (of 255; the fits differ by click noise only)
    # a click on a tile makes its expression current
    view.tiles[0].clicked.emit("neutral")
    assert model.expression_name == "neutral"
    assert [t.name for t in view.tiles] == names
    assert not shown, shown


def test_never_saved_project_is_recovered_at_next_start(qtbot, tmp_path, project_copy, messages):
    shown, answers = messages
    w = make_window(qtbot, tmp_path)
    assert w.model.path is None
    photos = sorted((project_copy.parent / "photos").glob("*.png"))
    assert w.add_photos([str(p) for p in photos[:2]]) == 2
    w.model.set_point("neutral", w.model.photos[0].id, "nose_tip", (500.0, 520.0))
    w.autosave()
    assert w.recovery_file.is_file()
    w.model.modified = False  # "crash"

    w2 = make_window(qtbot, tmp_path)
    answers["question"] = QMessageBox.StandardButton.Yes
    assert w2.offer_recovery()
    assert shown[-1][1] == "Recover unsaved project"
    m = w2.model
    assert m.path is None and m.modified and len(m.photos) == 2
    np.testing.assert_allclose(m.photos[0].points["nose_tip"], (500.0, 520.0))
    assert Path(m.photos[0].path).is_file()
    assert w2.save_to(tmp_path / "saved.facestudio.json")
    assert not w2.recovery_file.exists()  # it has a file now

    # declined: the recovery file is deleted, the window stays on its empty project
    w2.model.new()
    w2.add_photos([str(photos[0])])
    w2.autosave()
    assert w2.recovery_file.is_file()
    w2.model.modified = False
    w3 = make_window(qtbot, tmp_path)
    answers["question"] = QMessageBox.StandardButton.No
    assert not w3.offer_recovery() and not w3.recovery_file.exists() and w3.model.photos == []


@pytest.fixture
def textured_copy(tmp_path, fitted_sample):
    """A copy of the sample project with every expression fitted and textured (1024²)."""
    dst = tmp_path / "textured"
    shutil.copytree(fitted_sample.parent, dst, ignore=shutil.ignore_patterns("*.bak", "*.autosave"))
    return dst / fitted_sample.name


def test_opening_a_textured_project_shows_its_textures(qtbot, window, textured_copy, messages):
    shown, _ = messages
    assert window.open_project(textured_copy)
    m = window.model
    tex = m.texture()
    assert tex is not None and tex.saved and not m.modified
    stored = load_project(textured_copy).expression("neutral").result.texture
    png = cv2.cvtColor(cv2.imread(str(textured_copy.parent / stored.image)), cv2.COLOR_BGR2RGB)
    np.testing.assert_array_equal(tex.job.texture.image, png)
    # the 3D view shows the cylindrical texture (skin: red above blue), the dock the weight maps
    assert window.view3d.texture is not None and window.view3d.texture[1] is tex.job.texture.image
    assert "cylindrical texture" in window.view3d.vertices()[1]
    cyl = head_pixels(window)
    assert (cyl[:, 0] - cyl[:, 2]).mean() > 20.0
    assert window.weights_panel.image_count() == 5 and window.weights_dock.isVisibleTo(window)
    assert "neutral" in window.weights_panel.caption.text()
    assert set(m.textures) == {"neutral"}  # the others are read when shown

    # another expression: its own texture, read when it becomes current
    window.expr_combo.activated.emit(window.expr_combo.findData("smile"))
    assert m.expression_name == "smile"
    smile = m.texture("smile")
    assert smile is not None and window.view3d.texture[1] is smile.job.texture.image
    assert window.weights_panel.image_count() == 5 and "smile" in window.weights_panel.caption.text()
    assert not np.array_equal(smile.job.texture.image, tex.job.texture.image)
    m.set_expression("neutral")
    assert m.texture() is tex and window.view3d.texture[1] is tex.job.texture.image  # read once

    # view-dependent texturing reads the photos when first asked for
    assert tex.job.inputs.photos is None
    window.set_texture_mode("view_dependent")
    assert window.view3d.view_dependent is not None and len(tex.job.inputs.photos) == 5
    vd = head_pixels(window)
    assert (vd[:, 0] - vd[:, 2]).mean() > 20.0
    window.set_texture_mode("cylindrical")

    # "save as" elsewhere writes the textures it holds next to the new file
    moved = textured_copy.parent.parent / "moved" / textured_copy.name
    moved.parent.mkdir()
    assert window.save_to(moved)
    again = load_project(moved).expression("neutral").result.texture
    assert (moved.parent / again.image).is_file()
    assert again.report["cylinder"] == stored.report["cylinder"]
    assert not m.modified and not shown, shown


def test_a_damaged_texture_file_is_named_and_the_project_still_opens(qtbot, window, textured_copy, messages):
    shown, _ = messages
    folder = textured_copy.parent
    (folder / "results" / "neutral_texture.png").write_bytes(b"this is not a PNG")
    (folder / "results" / "smile_weights_left.png").unlink()
    assert window.open_project(textured_copy)
    m = window.model
    assert m.path == textured_copy and m.fit() is not None and not m.modified
    assert m.texture() is None and window.view3d.texture is None and window.weights_panel.image_count() == 0
    status = window.statusBar().currentMessage()
    assert "results/neutral_texture.png is not an image" in status and "Extract texture" in status
    # a missing weight map of another expression: named when that expression is shown
    m.set_expression("smile")
    assert (
        m.texture() is None and "results/smile_weights_left.png does not exist" in window.statusBar().currentMessage()
    )
    # the others are shown as usual, and a damaged one can be extracted again
    m.set_expression("frown")
    assert m.texture() is not None and window.view3d.texture is not None
    m.set_expression("neutral")
    assert window.run_texture()
    qtbot.waitUntil(lambda: not window.jobs.busy and window.model.texture() is not None, timeout=60_000)
    assert window.view3d.texture is not None and window.weights_panel.image_count() == 5
    assert not shown, shown
