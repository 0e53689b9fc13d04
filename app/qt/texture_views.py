"""Panels for the textures and the expressions: the weight maps of a texture, the expressions side by side.

* :class:`WeightMapPanel` — the extracted cylindrical texture (§5.2.2) and, one image per
  photograph, its blending weight ``g_k = F_k P_k`` in texture space (§5.2.1, the images of the
  paper's Fig. 5(c): black 0 … white 1), for the current expression; under them each photo with
  the pixels it was not allowed to give tinted red (background, clothes, below or beside the
  jaw, a hand: :func:`photomodel.landmarks.segment.face_pixels`), for a texture extracted in
  this session.
* :class:`ExpressionsView` — every expression of the project rendered by our renderer
  (:mod:`photomodel.rendering.renderer`) from one camera, next to each other, with its name and
  reprojection RMS; a click on one makes it the current expression.

Both observe the :class:`~app.studio_state.StudioModel` and hold no state of their own.
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QSize, Qt, Signal
from PySide6.QtGui import QColor, QIcon, QImage, QPixmap
from PySide6.QtWidgets import (
    QHBoxLayout,
    QLabel,
    QListView,
    QListWidget,
    QListWidgetItem,
    QScrollArea,
    QVBoxLayout,
    QWidget,
)

from app.studio_state import StudioModel
from photomodel.camera import orbit_camera
from photomodel.rendering.renderer import get_renderer

#: Side (px) of a weight-map thumbnail.
THUMB_PX = 150
#: The tint of the pixels a photo was not allowed to give, and its opacity.
LEFT_OUT_RGB, LEFT_OUT_ALPHA = (230, 40, 40), 0.55
#: Size (px) of one expression's rendering in the side-by-side view.
TILE_W, TILE_H = 240, 280
#: The side-by-side camera: azimuth and elevation (degrees), distance (mm), lens (mm, 36 mm film).
TILE_AZIMUTH_DEG, TILE_ELEVATION_DEG, TILE_DISTANCE_MM, TILE_FOCAL_MM = 20.0, 5.0, 560.0, 70.0
BACKGROUND = (0.16, 0.16, 0.18)


def masked_photo(photo: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8: ``photo`` (RGB) with the pixels outside ``mask`` ((H, W) bool: those it may
    give to the texture) tinted :data:`LEFT_OUT_RGB`."""
    out = np.asarray(photo)[..., :3].astype(np.float32).copy()
    out[~mask] = (1.0 - LEFT_OUT_ALPHA) * out[~mask] + LEFT_OUT_ALPHA * np.array(LEFT_OUT_RGB, np.float32)
    return (out + 0.5).astype(np.uint8)


def to_qimage(image: np.ndarray) -> QImage:
    """A (H, W) float in [0, 1] (grey) or (H, W, 3) uint8 RGB array as a QImage (copied)."""
    a = np.asarray(image)
    if a.ndim == 2:
        g = np.ascontiguousarray((np.clip(a, 0.0, 1.0) * 255 + 0.5).astype(np.uint8))
        h, w = g.shape
        return QImage(g.data, w, h, w, QImage.Format.Format_Grayscale8).copy()
    rgb = np.ascontiguousarray(a[..., :3].astype(np.uint8))
    h, w = rgb.shape[:2]
    return QImage(rgb.data, w, h, 3 * w, QImage.Format.Format_RGB888).copy()


class WeightMapPanel(QWidget):
    """The current expression's texture and its weight maps, one image per photograph."""

    def __init__(self, model: StudioModel, parent=None):
        super().__init__(parent)
        self.model = model
        self.caption = QLabel()
        self.caption.setWordWrap(True)
        self.texture_label = QLabel()
        self.texture_label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.maps = QListWidget()
        self.maps.setViewMode(QListView.ViewMode.IconMode)
        self.maps.setIconSize(QSize(THUMB_PX, THUMB_PX))
        self.maps.setResizeMode(QListView.ResizeMode.Adjust)
        self.maps.setMovement(QListView.Movement.Static)
        self.maps.setSpacing(4)
        self.maps.setToolTip("blending weight of each photo in texture space (§5.2.1): white = 1, black = 0")
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        lay.addWidget(self.caption)
        lay.addWidget(self.texture_label)
        lay.addWidget(QLabel("Weight maps (one per photo):"))
        lay.addWidget(self.maps, 1)
        self.masks_caption = QLabel()
        self.masks_caption.setWordWrap(True)
        self.masks = QListWidget()
        self.masks.setViewMode(QListView.ViewMode.IconMode)
        self.masks.setIconSize(QSize(THUMB_PX, THUMB_PX))
        self.masks.setResizeMode(QListView.ResizeMode.Adjust)
        self.masks.setMovement(QListView.Movement.Static)
        self.masks.setSpacing(4)
        self.masks.setToolTip(
            "red: pixels a photo may not give to the texture (background, clothes, below or beside the jaw, a hand)"
        )
        lay.addWidget(self.masks_caption)
        lay.addWidget(self.masks, 1)
        for sig in (model.texture_changed, model.expression_changed, model.project_replaced):
            sig.connect(self.refresh)
        self.refresh()

    def image_count(self) -> int:
        """How many weight maps are shown."""
        return self.maps.count()

    def mask_count(self) -> int:
        """How many photos' masks are shown."""
        return self.masks.count()

    def refresh(self, *args) -> None:
        self.maps.clear()
        self.masks.clear()
        tex = self.model.texture()
        if tex is None:
            self.caption.setText("No texture for this expression yet: Texture → Extract texture (Ctrl+T).")
            self.texture_label.clear()
            self.masks_caption.clear()
            return
        job = tex.job
        r = job.report
        self.caption.setText(
            f"<b>{job.expression}</b>: {job.size}×{job.size} texture from "
            f"{len(job.inputs.photo_ids)} photos, {r.get('coverage', 0.0):.1%} of the surface "
            f"seen, {r.get('extract_s', 0.0):.2f} s"
        )
        side = min(260, max(120, self.width() - 16))
        self.texture_label.setPixmap(
            QPixmap.fromImage(to_qimage(job.texture.image)).scaled(
                side, side, Qt.AspectRatioMode.KeepAspectRatio, Qt.TransformationMode.SmoothTransformation
            )
        )
        for pid, w in zip(job.inputs.photo_ids, job.texture.weight_maps, strict=True):
            icon = QPixmap.fromImage(to_qimage(w)).scaled(
                THUMB_PX, THUMB_PX, Qt.AspectRatioMode.KeepAspectRatio, Qt.TransformationMode.SmoothTransformation
            )
            item = QListWidgetItem(QIcon(icon), pid)
            item.setData(Qt.ItemDataRole.UserRole, pid)
            item.setToolTip(f"{pid}: mean weight {float(w[job.texture.surface].mean()):.2f} on the surface")
            self.maps.addItem(item)
        self._show_masks(job)

    def _show_masks(self, job) -> None:
        masks, photos = getattr(job, "masks", None), job.inputs.photos
        if masks is None or photos is None:
            self.masks_caption.setText(
                "Masks (what each photo may give) are shown for a texture extracted in this session."
            )
            return
        self.masks_caption.setText("What each photo may give (red: left out):")
        for pid, photo, mask in zip(job.inputs.photo_ids, photos, masks, strict=True):
            icon = QPixmap.fromImage(to_qimage(masked_photo(photo, mask))).scaled(
                THUMB_PX, THUMB_PX, Qt.AspectRatioMode.KeepAspectRatio, Qt.TransformationMode.SmoothTransformation
            )
            item = QListWidgetItem(QIcon(icon), pid)
            item.setData(Qt.ItemDataRole.UserRole, pid)
            item.setToolTip(f"{pid}: {100.0 * float(1.0 - mask.mean()):.1f} % of the photo left out")
            self.masks.addItem(item)


class _Tile(QWidget):
    clicked = Signal(str)

    def __init__(self, name: str, image: QImage | None, caption: str, current: bool):
        super().__init__()
        self.name = name
        self.image = QLabel()
        self.image.setFixedSize(TILE_W, TILE_H)
        self.image.setAlignment(Qt.AlignmentFlag.AlignCenter)
        if image is not None:
            self.image.setPixmap(QPixmap.fromImage(image))
        else:
            self.image.setText("not fitted yet")
            self.image.setStyleSheet("background: #29292e; color: #bbb;")
        self.label = QLabel(caption)
        self.label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(2, 2, 2, 2)
        lay.addWidget(self.image)
        lay.addWidget(self.label)
        lay.addStretch(1)
        if current:
            self.setStyleSheet("QLabel { font-weight: bold; }")
        self.setToolTip(f"click: make {name!r} the current expression")

    def mouseReleaseEvent(self, event):
        if event.button() == Qt.MouseButton.LeftButton:
            self.clicked.emit(self.name)


class ExpressionsView(QWidget):
    """Every expression's fitted mesh from the same camera, side by side, with its name and RMS.

    The camera looks at the centre of the first fitted mesh (all expressions share the head
    frame of their own fits), so that the meshes line up and their differences show.
    """

    def __init__(self, model: StudioModel, parent=None):
        super().__init__(parent)
        self.model = model
        self.tiles: list[_Tile] = []
        self._dirty = True
        self.row = QWidget()
        self.row_layout = QHBoxLayout(self.row)
        self.row_layout.setContentsMargins(4, 4, 4, 4)
        self.row_layout.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setWidget(self.row)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(scroll)
        for sig in (model.fit_changed, model.expression_changed, model.project_replaced, model.photos_changed):
            sig.connect(self.invalidate)

    def sizeHint(self) -> QSize:
        return QSize(3 * (TILE_W + 12), TILE_H + 50)

    def invalidate(self, *args) -> None:
        self._dirty = True
        if self.isVisible():
            self.refresh()

    def showEvent(self, event):
        if self._dirty:
            self.refresh()
        super().showEvent(event)

    def camera(self, vertices: np.ndarray):
        target = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
        return orbit_camera(
            TILE_AZIMUTH_DEG,
            TILE_W,
            TILE_H,
            distance_mm=TILE_DISTANCE_MM,
            focal_mm=TILE_FOCAL_MM,
            elevation_deg=TILE_ELEVATION_DEG,
            target=target,
        )

    def render(self, vertices: np.ndarray, camera) -> QImage:

        out = get_renderer().render(camera, vertices, self.model.mesh.faces, shading="lambert", background=BACKGROUND)
        return to_qimage((np.clip(out.color[..., :3], 0, 1) * 255 + 0.5).astype(np.uint8))

    def refresh(self) -> None:
        """Re-render every expression (a few tens of ms each)."""
        for t in self.tiles:
            self.row_layout.removeWidget(t)
            t.hide()
            t.deleteLater()
        self.tiles = []
        fits = [(e.name, self.model.fit(e.name)) for e in self.model.project.expressions]
        first = next((f.vertices for _, f in fits if f is not None and f.vertices is not None), None)
        cam = None if first is None else self.camera(first)
        for i, (name, fit) in enumerate(fits):
            image, caption = None, f"{name} — not fitted"
            if fit is not None and fit.vertices is not None:
                try:
                    image = self.render(fit.vertices, cam)
                except Exception as exc:  # no OpenGL: say so in the tile
                    image = QImage(TILE_W, TILE_H, QImage.Format.Format_RGB888)
                    image.fill(QColor(60, 40, 40))
                    caption = f"{name}: cannot render ({exc})"
                else:
                    rms = fit.report.get("rms_px")
                    caption = name if rms is None else f"{name} — RMS {rms:.2f} px"
            tile = _Tile(name, image, caption, name == self.model.expression_name)
            tile.clicked.connect(self._pick)
            self.row_layout.insertWidget(i, tile)
            self.tiles.append(tile)
        self._dirty = False

    def _pick(self, name: str) -> None:
        if name != self.model.expression_name:
            self.model.set_expression(name)
