"""One photograph in a zoomable, pannable view with its clicks, drawn curves and the fitted overlay.

Scene coordinates *are* image coordinates in the convention of :mod:`photomodel.camera`: ``u``
right, ``v`` down, pixel centres at integers (the pixmap is offset by half a pixel so that
pixel ``(i, j)`` covers ``[i − ½, i + ½] × [j − ½, j + ½]``). Map a widget position to an image
position with ``view.mapToScene`` and back with ``view.mapFromScene``.

Mouse and keys (as in Blender / photogrammetry tools):

* wheel — zoom about the cursor; middle-drag or Space + left-drag — pan; ``F`` — fit the photo.
* Points mode: left-click places the active feature (or moves its click here); left-drag on a
  marker moves it; right-click a marker — delete, hide in this photo; ``Delete`` — delete the
  active feature's click here; ``H`` — hide/show the active feature in this photo.
* Curve mode: successive left-clicks (or a left-drag, freehand) draw a polyline bound to the
  active curve; ``Enter`` or a double-click finishes it, ``Backspace`` removes the last vertex,
  ``Esc`` cancels.

Markers are coloured by their reprojection error after a fit (green < 1 px, yellow ~2 px,
red ≥ 4 px; white before any fit); hidden features are drawn hollow and grey. Automatic clicks
(placed by the landmark detector, ``"source": "auto"`` in the file) are drawn as violet diamonds
until the artist drags them (then they are the artist's clicks, round; undo makes them automatic
again). Once a fit exists,
the active feature's *predicted* position — the fitted mesh's vertex of that feature projected
with this photo's fitted camera (:meth:`~app.studio_state.StudioModel.predicted_uv`) — is drawn as a
dashed cyan ghost cross: where to click a feature not clicked here yet, or how far a click is
from the current fit.
"""

from __future__ import annotations

import math
import time

import numpy as np
from PySide6.QtCore import QLineF, QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QBrush, QColor, QFont, QImage, QPainter, QPainterPath, QPen, QPixmap, QTransform
from PySide6.QtWidgets import (
    QGraphicsItem,
    QGraphicsPathItem,
    QGraphicsPixmapItem,
    QGraphicsScene,
    QGraphicsView,
    QMenu,
)

from app.qt.commands import SetCurveCommand, SetHiddenCommand, SetPointCommand
from app.studio_state import StudioModel
from photomodel.errors import FaceStudioError
from photomodel.photos.reading import read_photo

#: A press closer than this (screen px) to a marker grabs it.
HIT_RADIUS_PX = 9.0
#: Freehand curve drawing adds a vertex every this many screen pixels.
FREEHAND_STEP_PX = 4.0
MARKER_RADIUS_PX = 5.0
ZOOM_STEP = 1.2
MIN_SCALE, MAX_SCALE = 0.02, 64.0

POINTS, CURVE = "points", "curve"

OVERLAY_COLORS = {0: QColor(0, 200, 255, 150), 1: QColor(255, 170, 0, 200), 2: QColor(255, 235, 0, 230)}
DRAWN_CURVE_COLOR = QColor(255, 60, 200)
#: Automatic clicks (the landmark detector's) are violet diamonds.
AUTO_COLOR = QColor(190, 110, 255)
#: The ghost marker of the active feature's predicted position (the current fit projected).
PREDICTED_COLOR = QColor(0, 230, 255)


def residual_color(px: float | None) -> QColor:
    """Marker colour for a reprojection error in pixels (None: not fitted yet)."""
    if px is None or not math.isfinite(px):
        return QColor(255, 255, 255)
    # green (0 px) → yellow (2 px) → red (4 px and more)
    x = min(max(px / 4.0, 0.0), 1.0)
    if x < 0.5:
        return QColor(int(510 * x), 220, 40)
    return QColor(255, int(220 * (1.0 - x) * 2), 40)


def load_photo_image(path, width: int, height: int) -> tuple[QImage, str | None, float]:
    """The photo as a QImage at its working resolution, through the modeling core's one reader
    (:func:`photomodel.photos.reading.read_photo`: EXIF orientation applied — a phone's
    portrait photo stands up, as its clicks were placed —, a truncated file refused, a very
    large one reduced), the reason it cannot be shown (``None`` when it can) and its scale
    (working pixels per original pixel). Unreadable: a grey placeholder of the stored size
    naming the reason, scale 1."""
    try:
        photo = read_photo(path)
    except FaceStudioError as exc:
        reason = str(exc)
    else:
        a = np.ascontiguousarray(photo.image)
        image = QImage(a.data, a.shape[1], a.shape[0], 3 * a.shape[1], QImage.Format.Format_RGB888).copy()
        return image, None, photo.scale
    ph = QImage(max(width, 1), max(height, 1), QImage.Format.Format_RGB32)
    ph.fill(QColor(90, 90, 90))
    p = QPainter(ph)
    p.setPen(QColor(230, 230, 230))
    f = QFont()
    f.setPixelSize(max(12, width // 40))
    p.setFont(f)
    p.drawText(ph.rect(), Qt.AlignmentFlag.AlignCenter | Qt.TextFlag.TextWordWrap, f"photo not shown\n{reason}")
    p.end()
    return ph, reason, 1.0


class PointItem(QGraphicsItem):
    """A click marker: constant size on screen, coloured by its reprojection error."""

    def __init__(self, name: str, uv, pose: bool):
        super().__init__()
        self.name = name
        self.pose = pose
        self.residual: float | None = None
        self.active = False
        self.hidden = False
        self.auto: float | None | bool = False  # False: the artist's click; else the detector's confidence
        self.setFlag(QGraphicsItem.GraphicsItemFlag.ItemIgnoresTransformations, True)
        # a repaint blits ~150 cached markers (~5 ms) instead of drawing them again (~25 ms)
        self.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
        self.setZValue(10)
        self.setPos(QPointF(float(uv[0]), float(uv[1])))
        self.setAcceptHoverEvents(True)
        self._update_tip()

    def _update_tip(self):
        r = "not fitted" if self.residual is None else f"{self.residual:.2f} px from the fit"
        extra = ", pose feature" if self.pose else ""
        hid = " (hidden in this photo)" if self.hidden else ""
        auto = ""
        if self.is_auto:
            conf = "" if self.auto is True else f", confidence {self.auto:.2f}"
            auto = f" — automatic click{conf}; drag it to correct it"
        self.setToolTip(f"{self.name}{hid}: {r}{extra}{auto}")

    @property
    def is_auto(self) -> bool:
        return self.auto is not False

    def set_auto(self, auto: bool, confidence: float | None = None) -> None:
        """Mark the click as the detector's (with its confidence) or the artist's."""
        value = (True if confidence is None else float(confidence)) if auto else False
        if value != self.auto:
            self.auto = value
            self._update_tip()
            self.update()

    def _look(self):
        color = residual_color(self.residual).rgb()
        label = f"{self.residual:.1f}" if (self.active and self.residual is not None) else None
        return color, label, self.active, self.hidden

    def set_state(self, residual: float | None = None, active: bool | None = None, hidden: bool | None = None):
        before = self._look()
        self.residual = residual
        if active is not None and active != self.active:
            self.prepareGeometryChange()  # the label widens the bounding box
            self.active = active
            self.setZValue(11 if active else 10)
        if hidden is not None:
            self.hidden = hidden
        self._update_tip()
        if self._look() != before:  # repaint (and re-cache) only markers that look different
            self.update()

    def boundingRect(self) -> QRectF:
        r = MARKER_RADIUS_PX + 4
        return QRectF(-r, -r, 2 * r + (200 if self.active else 0), 2 * r)

    def paint(self, painter: QPainter, option, widget=None):
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        r = MARKER_RADIUS_PX + (1.5 if self.active else 0.0)
        color = QColor(150, 150, 150) if self.hidden else residual_color(self.residual)
        painter.setBrush(Qt.BrushStyle.NoBrush)
        style = Qt.PenStyle.DashLine if self.hidden else Qt.PenStyle.SolidLine
        if self.is_auto:  # the detector's click: a violet diamond around the residual-coloured dot
            d = r + 1.5
            diamond = [QPointF(0, -d), QPointF(d, 0), QPointF(0, d), QPointF(-d, 0), QPointF(0, -d)]
            painter.setPen(QPen(QColor(0, 0, 0, 200), 3.0))
            painter.drawPolyline(diamond)
            painter.setPen(QPen(AUTO_COLOR, 1.8, style))
            painter.drawPolyline(diamond)
        else:
            painter.setPen(QPen(QColor(0, 0, 0, 200), 3.0))
            painter.drawEllipse(QPointF(0, 0), r, r)
            painter.setPen(QPen(color, 1.6, style))
            painter.drawEllipse(QPointF(0, 0), r, r)
        if not self.hidden:  # a dot at the exact position
            painter.setPen(Qt.PenStyle.NoPen)
            painter.setBrush(QBrush(color))
            painter.drawEllipse(QPointF(0, 0), 1.3, 1.3)
        if self.pose and not self.hidden:  # pose features get a tick above
            painter.setPen(QPen(color, 1.4))
            painter.drawLine(QPointF(0, -r - 3), QPointF(0, -r))
        if self.active:
            painter.setBrush(Qt.BrushStyle.NoBrush)
            painter.setPen(QPen(QColor(255, 255, 255), 2.0))
            painter.drawEllipse(QPointF(0, 0), r + 3, r + 3)
            f = painter.font()
            f.setPixelSize(12)
            f.setBold(True)
            painter.setFont(f)
            text = self.name if self.residual is None else f"{self.name}  {self.residual:.1f} px"
            painter.setPen(QColor(0, 0, 0, 220))
            painter.drawText(QPointF(r + 7, 5), text)
            painter.setPen(QColor(255, 255, 255))
            painter.drawText(QPointF(r + 6, 4), text)


class PredictedItem(QGraphicsItem):
    """The ghost marker: where the current fit puts the active feature in this photo."""

    def __init__(self):
        super().__init__()
        self.name = ""
        self.setFlag(QGraphicsItem.GraphicsItemFlag.ItemIgnoresTransformations, True)
        self.setZValue(9)  # under the clicks: a click on it lands on the photo, not on the ghost
        self.setVisible(False)

    def show_at(self, name: str, uv) -> None:
        self.name = name
        self.setPos(QPointF(float(uv[0]), float(uv[1])))
        self.setToolTip(f"{name}: where the current fit puts it")
        self.setVisible(True)
        self.update()

    def boundingRect(self) -> QRectF:
        r = MARKER_RADIUS_PX + 8
        return QRectF(-r, -r, 2 * r + 160, 2 * r)

    def paint(self, painter: QPainter, option, widget=None):
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        r = MARKER_RADIUS_PX + 3
        for color, width in ((QColor(0, 0, 0, 160), 3.0), (PREDICTED_COLOR, 1.4)):
            painter.setPen(QPen(color, width, Qt.PenStyle.DashLine))
            painter.setBrush(Qt.BrushStyle.NoBrush)
            painter.drawEllipse(QPointF(0, 0), r, r)
            painter.drawLine(QPointF(-r - 4, 0), QPointF(-r + 3, 0))
            painter.drawLine(QPointF(r - 3, 0), QPointF(r + 4, 0))
            painter.drawLine(QPointF(0, -r - 4), QPointF(0, -r + 3))
            painter.drawLine(QPointF(0, r - 3), QPointF(0, r + 4))
        f = painter.font()
        f.setPixelSize(11)
        painter.setFont(f)
        painter.setPen(PREDICTED_COLOR)
        painter.drawText(QPointF(r + 6, r + 10), f"{self.name} (fit)")


class LinesItem(QGraphicsItem):
    """Line segments in scene coordinates drawn with cosmetic (screen-width) pens, by kind."""

    def __init__(self, rect: QRectF):
        super().__init__()
        self._rect = QRectF(rect)
        self._lines: dict[int, list[QLineF]] = {}
        self.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)  # redrawn on zoom, not on every repaint
        self.setZValue(5)

    def set_lines(self, uv: np.ndarray, kinds: np.ndarray) -> None:
        """``uv`` (M, 2, 2) px endpoints; ``kinds`` (M,) int (keys of :data:`OVERLAY_COLORS`)."""
        self.prepareGeometryChange()
        self._lines = {}
        for k in np.unique(kinds):
            seg = uv[kinds == k].reshape(-1, 4).tolist()
            self._lines[int(k)] = [QLineF(a, b, c, d) for a, b, c, d in seg]
        if len(uv):
            lo, hi = uv.reshape(-1, 2).min(axis=0), uv.reshape(-1, 2).max(axis=0)
            self._rect = QRectF(QPointF(*lo), QPointF(*hi)).adjusted(-2, -2, 2, 2)
        self.update()

    def clear(self) -> None:
        self.prepareGeometryChange()
        self._lines = {}
        self.update()

    @property
    def count(self) -> int:
        return sum(len(v) for v in self._lines.values())

    def boundingRect(self) -> QRectF:
        return self._rect

    def paint(self, painter: QPainter, option, widget=None):
        painter.setRenderHint(QPainter.RenderHint.Antialiasing)
        for kind, lines in self._lines.items():
            pen = QPen(OVERLAY_COLORS.get(kind, QColor(0, 200, 255)), 1.6 if kind else 1.0)
            pen.setCosmetic(True)
            painter.setPen(pen)
            painter.drawLines(lines)


class PhotoView(QGraphicsView):
    """One photo of the current expression, editable with the mouse (see the module docstring).

    Parameters
    ----------
    model : StudioModel
    undo_stack : QUndoStack, where edits are pushed.
    expression, photo_id : which photo.
    """

    status_message = Signal(str)
    mode_changed = Signal(str)

    def __init__(self, model: StudioModel, undo_stack, expression: str, photo_id: str, parent=None):
        super().__init__(parent)
        self.model, self.undo_stack = model, undo_stack
        self.expression, self.photo_id = expression, photo_id
        self.mode = POINTS
        self.show_overlay = True
        self.show_curves = True
        self.user_zoomed = False
        self.overlay_stale = True
        self.overlay_time_s: float | None = None
        self.overlay_compute_s: float | None = None
        self.overlay_from_cache = False
        self._items: dict[str, PointItem] = {}
        self._curve_items: dict[str, QGraphicsPathItem] = {}
        self._drag: dict | None = None
        self._pan: QPointF | None = None
        self._space = False
        self._drawing: list[QPointF] | None = None
        self._freehand = False
        self.detached = False  # set by detach(): the model may no longer hold this photo

        self.setScene(QGraphicsScene(self))
        # ~200 items: a linear scan beats keeping a BSP index up to date after every refit
        self.scene().setItemIndexMethod(QGraphicsScene.ItemIndexMethod.NoIndex)
        self.setRenderHints(QPainter.RenderHint.Antialiasing | QPainter.RenderHint.SmoothPixmapTransform)
        self.setTransformationAnchor(QGraphicsView.ViewportAnchor.AnchorUnderMouse)
        self.setResizeAnchor(QGraphicsView.ViewportAnchor.AnchorViewCenter)
        self.setDragMode(QGraphicsView.DragMode.NoDrag)
        self.setViewportUpdateMode(QGraphicsView.ViewportUpdateMode.SmartViewportUpdate)
        self.setBackgroundBrush(QColor(45, 45, 48))
        self.setMouseTracking(True)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        # pan with the middle button / Space as in Blender; scroll bars would only take room
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.setVerticalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)

        photo = self.photo
        # kept: a view being torn down still fits its photo without asking the model (whose
        # project may already be another one, see detach)
        self.photo_size = (photo.width, photo.height)
        image, self.missing, scale = load_photo_image(model.project.photo_path(photo), photo.width, photo.height)
        self.pixmap_item = QGraphicsPixmapItem(QPixmap.fromImage(image))
        # the original photo's pixel centres at integer scene coordinates: working pixel i spans
        # [i, i + 1] in the item and [i / s − ½, (i + 1) / s − ½] in the scene
        self.pixmap_item.setTransform(QTransform(1.0 / scale, 0.0, 0.0, 1.0 / scale, -0.5, -0.5))
        self.pixmap_item.setTransformationMode(Qt.TransformationMode.SmoothTransformation)
        self.pixmap_item.setShapeMode(QGraphicsPixmapItem.ShapeMode.BoundingRectShape)
        self.scene().addItem(self.pixmap_item)
        rect = QRectF(-0.5, -0.5, photo.width, photo.height)
        self.scene().setSceneRect(rect.adjusted(-photo.width, -photo.height, photo.width, photo.height))
        self.overlay_item = LinesItem(rect)
        self.scene().addItem(self.overlay_item)
        self.preview_item = QGraphicsPathItem()
        pen = QPen(DRAWN_CURVE_COLOR, 2.0, Qt.PenStyle.DashLine)
        pen.setCosmetic(True)
        self.preview_item.setPen(pen)
        self.preview_item.setZValue(12)
        self.scene().addItem(self.preview_item)
        self.predicted_item = PredictedItem()
        self.scene().addItem(self.predicted_item)

        self._connect()
        self.rebuild_points()
        self.rebuild_curves()
        self.update_predicted()

    # ------------------------------------------------------------------ model observation
    def _connect(self):
        m = self.model
        m.points_changed.connect(self._on_points_changed)
        m.curves_changed.connect(self._on_curves_changed)
        m.fit_changed.connect(self._on_fit_changed)
        m.active_feature_changed.connect(self._on_active_feature)
        m.active_curve_changed.connect(self._on_active_curve)
        m.features_changed.connect(self.rebuild_points)

    def detach(self):
        """Stop observing the model (before the view is deleted).

        From now on the view never looks its photo up again: the model may already hold another
        project (File → New, Open) and Qt may still show or resize the view while it is removed
        from its tab.
        """
        self.detached = True
        m = self.model
        m.points_changed.disconnect(self._on_points_changed)
        m.curves_changed.disconnect(self._on_curves_changed)
        m.fit_changed.disconnect(self._on_fit_changed)
        m.active_feature_changed.disconnect(self._on_active_feature)
        m.active_curve_changed.disconnect(self._on_active_curve)
        m.features_changed.disconnect(self.rebuild_points)

    @property
    def photo(self):
        return self.model.photo(self.photo_id, self.expression)

    @property
    def markers(self) -> dict[str, PointItem]:
        """The click markers on the photo, by feature name."""
        return self._items

    def _residuals(self) -> dict[str, float]:
        return self.model.click_residuals(self.expression).get(self.photo_id, {})

    def rebuild_points(self):
        for item in self._items.values():
            self.scene().removeItem(item)
        self._items = {}
        photo = self.photo
        pose = {f.name for f in self.model.project.features if f.pose}
        res = self._residuals()
        for name, uv in photo.points.items():
            item = PointItem(name, uv, name in pose)
            item.set_auto(photo.click_source(name) == "auto", photo.confidence.get(name))
            item.set_state(res.get(name), active=name == self.model.active_feature, hidden=name in photo.hidden)
            self.scene().addItem(item)
            self._items[name] = item

    def _on_points_changed(self, expression, photo_id, feature):
        if expression != self.expression:
            return
        if photo_id != self.photo_id:
            return
        photo = self.photo
        item = self._items.get(feature)
        uv = photo.points.get(feature)
        if uv is None:
            if item is not None:
                self.scene().removeItem(item)
                del self._items[feature]
        else:
            if item is None:
                pose = any(f.name == feature and f.pose for f in self.model.project.features)
                item = PointItem(feature, uv, pose)
                self.scene().addItem(item)
                self._items[feature] = item
            item.setPos(QPointF(float(uv[0]), float(uv[1])))
            item.set_auto(photo.click_source(feature) == "auto", photo.confidence.get(feature))
            item.set_state(
                self._residuals().get(feature),
                active=feature == self.model.active_feature,
                hidden=feature in photo.hidden,
            )

    def _on_fit_changed(self, expression):
        if expression != self.expression:
            return
        res = self._residuals()
        for name, item in self._items.items():
            item.set_state(res.get(name))
        self.overlay_stale = True
        if self.isVisible():
            self.update_overlay()
        self.update_predicted()

    def update_predicted(self, *_) -> None:
        """Show the ghost marker of the active feature where the current fit puts it (or hide it)."""
        name = self.model.active_feature
        uv = None if name is None else self.model.predicted_uv(self.photo_id, name, self.expression)
        if uv is None or not np.all(np.isfinite(uv)):
            self.predicted_item.setVisible(False)
        else:
            self.predicted_item.show_at(name, uv)

    def _on_active_feature(self, name):
        self.update_predicted()
        for n, item in self._items.items():
            if item.active != (n == name):
                item.set_state(item.residual, active=n == name)

    def _on_active_curve(self, name):
        self.rebuild_curves()

    # ------------------------------------------------------------------ curves
    def rebuild_curves(self):
        for item in self._curve_items.values():
            self.scene().removeItem(item)
        self._curve_items = {}
        for name, line in self.photo.curves.items():
            self._add_curve_item(name, line)

    def _add_curve_item(self, name, line):
        path = QPainterPath(QPointF(*line[0]))
        for p in line[1:]:
            path.lineTo(QPointF(*p))
        item = QGraphicsPathItem(path)
        active = name == self.model.active_curve
        auto = self.photo.curve_source(name) == "auto"
        colour = AUTO_COLOR if auto else DRAWN_CURVE_COLOR
        if not active:
            colour = QColor(colour.red(), colour.green(), colour.blue(), 170)
        pen = QPen(colour, 2.4 if active else 1.4, Qt.PenStyle.DashLine if auto else Qt.PenStyle.SolidLine)
        pen.setCosmetic(True)
        item.setPen(pen)
        item.setZValue(8)
        item.setToolTip(f"curve {name}" + (" (drawn automatically: redraw it to correct it)" if auto else ""))
        item.setVisible(self.show_curves)
        self.scene().addItem(item)
        self._curve_items[name] = item

    def _on_curves_changed(self, expression, photo_id, curve):
        if expression == self.expression and photo_id == self.photo_id:
            self.rebuild_curves()

    def set_curves_visible(self, visible: bool):
        self.show_curves = visible
        for item in self._curve_items.values():
            item.setVisible(visible)

    # ------------------------------------------------------------------ overlay
    def set_overlay_visible(self, visible: bool):
        self.show_overlay = visible
        self.overlay_item.setVisible(visible)
        if visible and self.overlay_stale:
            self.update_overlay()

    def update_overlay(self) -> None:
        """Draw the fitted mesh's lines with the fitted camera of this photo (hidden lines removed).

        The lines come from the fit's overlay cache, filled by the fit's worker for the photo on
        screen (:class:`app.qt.workers.FitTask`), so after a refit this only paints; a photo that
        was not on screen then has its overlay computed here once (:meth:`StudioModel.overlay`).
        """

        self.overlay_stale = False
        fit = self.model.fit(self.expression)
        if fit is None or not self.show_overlay:
            self.overlay_item.clear()
            self.overlay_stale = fit is not None and not self.show_overlay
            return
        t0 = time.perf_counter()
        cached = self.photo_id in fit.overlays
        overlay = self.model.overlay(self.photo_id, self.expression)
        if overlay is None:
            self.overlay_item.clear()
            return
        if overlay.note is not None:
            self.status_message.emit(overlay.note)
        self.overlay_item.set_lines(overlay.segments, overlay.kind)
        # for benchmarks/bench_gui.py: GUI-thread time of this update, time computing the lines
        # (in the fit's worker when they came from the cache right after a refit)
        self.overlay_time_s = time.perf_counter() - t0
        self.overlay_compute_s = overlay.elapsed_s
        self.overlay_from_cache = cached

    def showEvent(self, event):
        super().showEvent(event)
        if not self.user_zoomed:
            self.fit_photo()
        if self.overlay_stale and not self.detached:
            self.update_overlay()

    def resizeEvent(self, event):
        super().resizeEvent(event)
        if not self.user_zoomed:
            self.fit_photo()

    # ------------------------------------------------------------------ zoom and pan
    @property
    def scale_factor(self) -> float:
        """Screen pixels per image pixel."""
        return float(self.transform().m11())

    def fit_photo(self):
        width, height = self.photo_size
        self.fitInView(QRectF(-0.5, -0.5, width, height), Qt.AspectRatioMode.KeepAspectRatio)

    def zoom(self, factor: float, anchor: QPointF | None = None):
        s = self.scale_factor
        factor = min(max(factor, MIN_SCALE / s), MAX_SCALE / s)
        if anchor is not None:
            old = self.mapToScene(anchor.toPoint())
        self.scale(factor, factor)
        if anchor is not None:  # keep the image point under the cursor where it was
            new = self.mapToScene(anchor.toPoint())
            d = new - old
            self.translate(d.x(), d.y())
        self.user_zoomed = True

    def center_on_image(self, u: float, v: float, scale: float | None = None):
        """Show image position (u, v) in the middle, optionally at ``scale`` screen px per image px."""
        if scale is not None:
            self.resetTransform()
            self.scale(scale, scale)
            self.user_zoomed = True
        self.centerOn(QPointF(u, v))

    def wheelEvent(self, event):
        steps = event.angleDelta().y() / 120.0
        if steps:
            self.setTransformationAnchor(QGraphicsView.ViewportAnchor.AnchorUnderMouse)
            self.zoom(ZOOM_STEP**steps)
        event.accept()

    # ------------------------------------------------------------------ mouse
    def image_pos(self, widget_pos) -> np.ndarray:
        """(2,) image position (px) under a viewport position."""
        p = self.mapToScene(widget_pos.toPoint() if isinstance(widget_pos, QPointF) else widget_pos)
        return np.array([p.x(), p.y()])

    def point_at(self, widget_pos) -> str | None:
        """The clicked feature whose marker is within :data:`HIT_RADIUS_PX` of a viewport position."""
        best, best_d = None, HIT_RADIUS_PX
        for name, item in self._items.items():
            q = self.mapFromScene(item.pos())
            d = math.hypot(q.x() - widget_pos.x(), q.y() - widget_pos.y())
            if d <= best_d:
                best, best_d = name, d
        return best

    def set_mode(self, mode: str):
        if mode not in (POINTS, CURVE):
            raise ValueError(f"unknown mode {mode!r}")
        if mode != self.mode:
            self.cancel_curve()
            self.mode = mode
            self.viewport().setCursor(Qt.CursorShape.CrossCursor if mode == CURVE else Qt.CursorShape.ArrowCursor)
            self.mode_changed.emit(mode)

    def mousePressEvent(self, event):
        pos = event.position()
        button = event.button()
        if button == Qt.MouseButton.MiddleButton or (button == Qt.MouseButton.LeftButton and self._space):
            self._pan = pos
            self.viewport().setCursor(Qt.CursorShape.ClosedHandCursor)
            event.accept()
            return
        if button == Qt.MouseButton.RightButton:
            self._context_menu(pos, event.globalPosition().toPoint())
            event.accept()
            return
        if button != Qt.MouseButton.LeftButton:
            return super().mousePressEvent(event)
        event.accept()
        if self.mode == CURVE:
            self._curve_press(pos)
            return
        name = self.point_at(pos)
        uv = self.image_pos(pos)
        if name is not None:  # grab an existing marker
            if name != self.model.active_feature:
                self._set_active(name)
            item = self._items[name]
            self._drag = {
                "name": name,
                "old": self.photo.points[name].copy(),
                "item": item,
                "offset": np.array([item.pos().x(), item.pos().y()]) - uv,
                "moved": False,
            }
            return
        feature = self.model.active_feature
        if feature is None:
            self.status_message.emit("pick a feature in the list first (or click one in the 3D view)")
            return
        self._place(feature, uv)

    def _place(self, feature: str, uv) -> None:
        """Place (or move here) the click of ``feature``; one undoable command."""
        try:
            cmd = SetPointCommand(self.model, self.expression, self.photo_id, feature, uv)
            self.undo_stack.push(cmd)
        except (FaceStudioError, KeyError) as exc:
            self.status_message.emit(str(exc))
            return
        item = self._items.get(feature)
        if item is not None:  # keep dragging the new marker while the button is held
            self._drag = {
                "name": feature,
                "old": np.asarray(uv, float).copy(),
                "item": item,
                "offset": np.zeros(2),
                "moved": False,
            }

    def _set_active(self, name):
        try:
            self.model.set_active_feature(name)
        except FaceStudioError as exc:
            self.status_message.emit(str(exc))

    def mouseMoveEvent(self, event):
        pos = event.position()
        if self._pan is not None:
            d = pos - self._pan
            self._pan = pos
            self.horizontalScrollBar().setValue(self.horizontalScrollBar().value() - int(round(d.x())))
            self.verticalScrollBar().setValue(self.verticalScrollBar().value() - int(round(d.y())))
            event.accept()
            return
        if self._drag is not None:
            uv = self.image_pos(pos) + self._drag["offset"]
            self._drag["item"].setPos(QPointF(*uv))
            self._drag["moved"] = True
            event.accept()
            return
        if self._drawing is not None:
            if self._freehand and event.buttons() & Qt.MouseButton.LeftButton:
                last = self.mapFromScene(self._drawing[-1])
                if math.hypot(pos.x() - last.x(), pos.y() - last.y()) >= FREEHAND_STEP_PX:
                    self._drawing.append(self.mapToScene(pos.toPoint()))
            self._update_preview(self.mapToScene(pos.toPoint()))
            event.accept()
            return
        uv = self.image_pos(pos)
        self.status_message.emit(f"{self.photo_id}: ({uv[0]:.1f}, {uv[1]:.1f}) px, zoom {self.scale_factor:.2f}×")
        super().mouseMoveEvent(event)

    def mouseReleaseEvent(self, event):
        if self._pan is not None and event.button() in (Qt.MouseButton.MiddleButton, Qt.MouseButton.LeftButton):
            self._pan = None
            self.viewport().setCursor(Qt.CursorShape.CrossCursor if self.mode == CURVE else Qt.CursorShape.ArrowCursor)
            event.accept()
            return
        if self._drag is not None and event.button() == Qt.MouseButton.LeftButton:
            drag, self._drag = self._drag, None
            item = drag["item"]
            new = np.array([item.pos().x(), item.pos().y()])
            if drag["moved"] and not np.allclose(new, drag["old"]):
                try:
                    self.undo_stack.push(
                        SetPointCommand(
                            self.model, self.expression, self.photo_id, drag["name"], new, old_uv=drag["old"]
                        )
                    )
                except FaceStudioError as exc:
                    self.status_message.emit(str(exc))
                    item.setPos(QPointF(*drag["old"]))
            else:
                item.setPos(QPointF(*drag["old"]))
            event.accept()
            return
        if self._drawing is not None and event.button() == Qt.MouseButton.LeftButton:
            if self._freehand and len(self._drawing) > 2:
                self.finish_curve()  # a drag draws a whole curve at once
            self._freehand = False
            event.accept()
            return
        super().mouseReleaseEvent(event)

    def mouseDoubleClickEvent(self, event):
        if self.mode == CURVE and self._drawing is not None:
            self.finish_curve()
            event.accept()
            return
        super().mouseDoubleClickEvent(event)

    # ------------------------------------------------------------------ curve drawing
    def _curve_press(self, pos):
        if self.model.active_curve is None:
            self.status_message.emit("pick a curve in the list first")
            return
        p = self.mapToScene(pos.toPoint())
        if self._drawing is None:
            self._drawing = [p]
            self._freehand = True
            self.status_message.emit(
                f"drawing {self.model.active_curve}: click more points, Enter to finish, Esc to cancel"
            )
        else:
            self._drawing.append(p)
            self._freehand = False
        self._update_preview(p)

    def add_curve_point(self, u: float, v: float) -> None:
        """Append an image point to the curve being drawn (as a click in curve mode does)."""
        p = QPointF(u, v)
        if self._drawing is None:
            self._drawing = [p]
        else:
            self._drawing.append(p)
        self._update_preview(p)

    def _update_preview(self, cursor: QPointF | None = None):
        if not self._drawing:
            self.preview_item.setPath(QPainterPath())
            return
        path = QPainterPath(self._drawing[0])
        for p in self._drawing[1:]:
            path.lineTo(p)
        if cursor is not None:
            path.lineTo(cursor)
        self.preview_item.setPath(path)

    def finish_curve(self) -> bool:
        """Bind the drawn polyline to the active curve (one undoable command)."""
        pts, self._drawing, self._freehand = self._drawing, None, False
        self.preview_item.setPath(QPainterPath())
        if not pts:
            return False
        line = np.array([[p.x(), p.y()] for p in pts])
        keep = np.concatenate([[True], np.linalg.norm(np.diff(line, axis=0), axis=1) > 1e-6])
        line = line[keep]
        curve = self.model.active_curve
        if curve is None or len(line) < 2:
            self.status_message.emit("a curve needs at least two points")
            return False
        try:
            self.undo_stack.push(SetCurveCommand(self.model, self.expression, self.photo_id, curve, line))
        except (FaceStudioError, KeyError) as exc:
            self.status_message.emit(str(exc))
            return False
        self.status_message.emit(f"curve {curve}: {len(line)} points in {self.photo_id}")
        return True

    def cancel_curve(self):
        self._drawing, self._freehand = None, False
        self.preview_item.setPath(QPainterPath())

    # ------------------------------------------------------------------ keys and menus
    def keyPressEvent(self, event):
        key = event.key()
        if key == Qt.Key.Key_Space and not event.isAutoRepeat():
            self._space = True
            self.viewport().setCursor(Qt.CursorShape.OpenHandCursor)
        elif key in (Qt.Key.Key_Return, Qt.Key.Key_Enter) and self._drawing is not None:
            self.finish_curve()
        elif key == Qt.Key.Key_Escape and self._drawing is not None:
            self.cancel_curve()
        elif key == Qt.Key.Key_Backspace and self._drawing is not None:
            self._drawing.pop()
            if not self._drawing:
                self.cancel_curve()
            self._update_preview()
        elif key in (Qt.Key.Key_Delete, Qt.Key.Key_Backspace):
            self.delete_active_click()
        elif key == Qt.Key.Key_H:
            self.toggle_active_hidden()
        elif key == Qt.Key.Key_F:
            self.user_zoomed = False
            self.fit_photo()
        else:
            super().keyPressEvent(event)
            return
        event.accept()

    def keyReleaseEvent(self, event):
        if event.key() == Qt.Key.Key_Space and not event.isAutoRepeat():
            self._space = False
            self.viewport().setCursor(Qt.CursorShape.CrossCursor if self.mode == CURVE else Qt.CursorShape.ArrowCursor)
            event.accept()
            return
        super().keyReleaseEvent(event)

    def delete_active_click(self):
        name = self.model.active_feature
        if name is not None and name in self.photo.points:
            self.undo_stack.push(SetPointCommand(self.model, self.expression, self.photo_id, name, None))

    def toggle_active_hidden(self):
        name = self.model.active_feature
        if name is None:
            return
        if not self.model.has_feature(name):
            self.status_message.emit(f"{name} is not used in the project yet; click it somewhere first")
            return
        hidden = name in self.photo.hidden
        self.undo_stack.push(SetHiddenCommand(self.model, self.expression, self.photo_id, name, not hidden))

    def _context_menu(self, pos, global_pos):
        menu = QMenu(self)
        name = self.point_at(pos)
        photo = self.photo
        if name is not None:
            self._set_active(name)
            menu.addAction(
                f"Delete {name} here",
                lambda: self.undo_stack.push(SetPointCommand(self.model, self.expression, self.photo_id, name, None)),
            )
            hidden = name in photo.hidden
            menu.addAction(
                f"{'Show' if hidden else 'Hide'} {name} in this photo",
                lambda: self.undo_stack.push(
                    SetHiddenCommand(self.model, self.expression, self.photo_id, name, not hidden)
                ),
            )
        else:
            act = self.model.active_feature
            if act is not None and self.model.has_feature(act):
                hidden = act in photo.hidden
                menu.addAction(f"{'Show' if hidden else 'Hide'} {act} in this photo", self.toggle_active_hidden)
            for curve in list(photo.curves):
                menu.addAction(
                    f"Delete curve {curve} here",
                    lambda c=curve: self.undo_stack.push(
                        SetCurveCommand(self.model, self.expression, self.photo_id, c, None)
                    ),
                )
        menu.addSeparator()
        menu.addAction("Fit photo to window (F)", lambda: (setattr(self, "user_zoomed", False), self.fit_photo()))
        if not menu.isEmpty():
            menu.popup(global_pos)
        self._menu = menu  # tests read it
