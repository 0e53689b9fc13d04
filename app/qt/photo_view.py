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

The markers, the predicted ghost and the mesh's lines are painted by :mod:`app.qt.photo_items`
(colours by reprojection error, automatic clicks as violet diamonds); the drawn curves and the one
being drawn are kept by :mod:`app.qt.photo_curves`. Once a fit exists, the active feature's
*predicted* position (:meth:`~app.studio_state.StudioModel.predicted_uv`) is drawn as a dashed cyan
ghost cross: where to click a feature not clicked here yet, or how far a click is from the fit.
"""

from __future__ import annotations

import math
import time

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QPainter, QPixmap, QTransform
from PySide6.QtWidgets import QGraphicsPixmapItem, QGraphicsScene, QGraphicsView, QMenu

from app.qt.photo_curves import PhotoCurves
from app.qt.photo_items import LinesItem, PointItem, PredictedItem, load_photo_image
from app.studio.commands import SetCurveCommand, SetHiddenCommand, SetPointCommand
from app.studio_state import StudioModel
from photomodel.errors import FaceStudioError

#: A press closer than this (screen px) to a marker grabs it.
HIT_RADIUS_PX = 9.0
#: Freehand curve drawing adds a vertex every this many screen pixels.
FREEHAND_STEP_PX = 4.0
ZOOM_STEP = 1.2
MIN_SCALE, MAX_SCALE = 0.02, 64.0

POINTS, CURVE = "points", "curve"


class PhotoView(QGraphicsView):
    """One photo of the current expression, editable with the mouse (see the module docstring).

    Parameters
    ----------
    model : StudioModel
    undo_stack : app.studio.undo.UndoStack, where edits are pushed (the model's).
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
        self.user_zoomed = False
        self.overlay_stale = True
        self.overlay_time_s: float | None = None
        self.overlay_compute_s: float | None = None
        self.overlay_from_cache = False
        self._items: dict[str, PointItem] = {}
        self._drag: dict | None = None
        self._pan: QPointF | None = None
        self._space = False
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
        self.curves = PhotoCurves(self.scene())  # the drawn curves and the one being drawn
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
        self.curves.rebuild(self.photo, self.model.active_curve)

    def _on_curves_changed(self, expression, photo_id, curve):
        if expression == self.expression and photo_id == self.photo_id:
            self.rebuild_curves()

    def set_curves_visible(self, visible: bool):
        self.curves.set_visible(visible)

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
        drawing = self.curves.drawing
        if drawing is not None:
            if self.curves.freehand and event.buttons() & Qt.MouseButton.LeftButton:
                last = self.mapFromScene(drawing[-1])
                if math.hypot(pos.x() - last.x(), pos.y() - last.y()) >= FREEHAND_STEP_PX:
                    drawing.append(self.mapToScene(pos.toPoint()))
            self.curves.update_preview(self.mapToScene(pos.toPoint()))
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
        if self.curves.drawing is not None and event.button() == Qt.MouseButton.LeftButton:
            if self.curves.freehand and len(self.curves.drawing) > 2:
                self.finish_curve()  # a drag draws a whole curve at once
            self.curves.freehand = False
            event.accept()
            return
        super().mouseReleaseEvent(event)

    def mouseDoubleClickEvent(self, event):
        if self.mode == CURVE and self.curves.drawing is not None:
            self.finish_curve()
            event.accept()
            return
        super().mouseDoubleClickEvent(event)

    # ------------------------------------------------------------------ curve drawing
    def _curve_press(self, pos):
        if self.model.active_curve is None:
            self.status_message.emit("pick a curve in the list first")
            return
        first = self.curves.drawing is None
        self.curves.add_point(self.mapToScene(pos.toPoint()), freehand=first)
        if first:
            self.status_message.emit(
                f"drawing {self.model.active_curve}: click more points, Enter to finish, Esc to cancel"
            )

    def add_curve_point(self, u: float, v: float) -> None:
        """Append an image point to the curve being drawn (as a click in curve mode does)."""
        self.curves.add_point(QPointF(u, v))

    def finish_curve(self) -> bool:
        """Bind the drawn polyline to the active curve (one undoable command)."""
        line = self.curves.take()
        if line is None:
            return False
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
        self.curves.cancel()

    # ------------------------------------------------------------------ keys and menus
    def keyPressEvent(self, event):
        key = event.key()
        if key == Qt.Key.Key_Space and not event.isAutoRepeat():
            self._space = True
            self.viewport().setCursor(Qt.CursorShape.OpenHandCursor)
        elif key in (Qt.Key.Key_Return, Qt.Key.Key_Enter) and self.curves.drawing is not None:
            self.finish_curve()
        elif key == Qt.Key.Key_Escape and self.curves.drawing is not None:
            self.cancel_curve()
        elif key == Qt.Key.Key_Backspace and self.curves.drawing is not None:
            self.curves.remove_last_point()
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
