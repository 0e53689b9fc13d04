"""The curves of one photo view: the drawn curves (from the project) and the polyline being drawn.

Drawn curves are pink (the artist's) or dashed violet (drawn automatically), the active curve
wider; the polyline being drawn is previewed dashed up to the cursor. Points are image (scene)
coordinates, as everywhere in :mod:`app.qt.photo_view`.
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF, Qt
from PySide6.QtGui import QColor, QPainterPath, QPen
from PySide6.QtWidgets import QGraphicsPathItem, QGraphicsScene

from app.qt.photo_items import AUTO_COLOR, DRAWN_CURVE_COLOR


class PhotoCurves:
    """The curve items of a photo view's ``scene`` and the polyline being drawn in it."""

    def __init__(self, scene: QGraphicsScene):
        self.scene = scene
        self.items: dict[str, QGraphicsPathItem] = {}
        self.visible = True
        self.drawing: list[QPointF] | None = None  # the polyline being drawn, None when none is
        self.freehand = False  # drawn by a drag (a vertex every few pixels) rather than by clicks
        self.preview_item = QGraphicsPathItem()
        pen = QPen(DRAWN_CURVE_COLOR, 2.0, Qt.PenStyle.DashLine)
        pen.setCosmetic(True)
        self.preview_item.setPen(pen)
        self.preview_item.setZValue(12)
        scene.addItem(self.preview_item)

    # ------------------------------------------------------------------ the drawn curves
    def rebuild(self, photo, active_curve: str | None) -> None:
        """An item per curve drawn in ``photo``, ``active_curve`` highlighted."""
        for item in self.items.values():
            self.scene.removeItem(item)
        self.items = {}
        for name, line in photo.curves.items():
            self._add_item(name, line, active=name == active_curve, auto=photo.curve_source(name) == "auto")

    def _add_item(self, name: str, line, *, active: bool, auto: bool) -> None:
        path = QPainterPath(QPointF(*line[0]))
        for p in line[1:]:
            path.lineTo(QPointF(*p))
        item = QGraphicsPathItem(path)
        colour = AUTO_COLOR if auto else DRAWN_CURVE_COLOR
        if not active:
            colour = QColor(colour.red(), colour.green(), colour.blue(), 170)
        pen = QPen(colour, 2.4 if active else 1.4, Qt.PenStyle.DashLine if auto else Qt.PenStyle.SolidLine)
        pen.setCosmetic(True)
        item.setPen(pen)
        item.setZValue(8)
        item.setToolTip(f"curve {name}" + (" (drawn automatically: redraw it to correct it)" if auto else ""))
        item.setVisible(self.visible)
        self.scene.addItem(item)
        self.items[name] = item

    def set_visible(self, visible: bool) -> None:
        self.visible = visible
        for item in self.items.values():
            item.setVisible(visible)

    # ------------------------------------------------------------------ the polyline being drawn
    def add_point(self, p: QPointF, *, freehand: bool | None = None) -> None:
        """Append ``p`` (a first point starts the polyline); ``freehand``: set how it is drawn."""
        if self.drawing is None:
            self.drawing = [p]
        else:
            self.drawing.append(p)
        if freehand is not None:
            self.freehand = freehand
        self.update_preview(p)

    def remove_last_point(self) -> None:
        """Backspace: the last vertex goes; the last of all cancels the drawing."""
        self.drawing.pop()
        if not self.drawing:
            self.cancel()
        self.update_preview()

    def update_preview(self, cursor: QPointF | None = None) -> None:
        """The dashed preview: the polyline so far, up to ``cursor`` if given."""
        if not self.drawing:
            self.preview_item.setPath(QPainterPath())
            return
        path = QPainterPath(self.drawing[0])
        for p in self.drawing[1:]:
            path.lineTo(p)
        if cursor is not None:
            path.lineTo(cursor)
        self.preview_item.setPath(path)

    def take(self) -> np.ndarray | None:
        """The polyline drawn, (N, 2) px without repeated points (None if nothing was drawn); the
        drawing ends."""
        pts = self.drawing
        self.cancel()
        if not pts:
            return None
        line = np.array([[p.x(), p.y()] for p in pts])
        keep = np.concatenate([[True], np.linalg.norm(np.diff(line, axis=0), axis=1) > 1e-6])
        return line[keep]

    def cancel(self) -> None:
        self.drawing, self.freehand = None, False
        self.preview_item.setPath(QPainterPath())
